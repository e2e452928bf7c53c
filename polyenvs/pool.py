"""A local process pool for independent jobs: what ``polyenvs sweep`` and ``polyenvs leaderboard`` run on.

:func:`run_local` runs ``work(job)`` for every job on ``workers`` spawned processes (each with one torch thread, so
N workers use N cores) and hands each result to ``on_result`` in the parent as it finishes, in finishing order;
a worker that dies hands its exception to ``on_error``. Ctrl-C (or an exception from either callback) cancels
what has not started and waits for what has; a worker whose parent is killed outright (kill -9) exits with it.
``work`` and the jobs must pickle (a module-level function, plain data): the workers are spawned, not forked, since
the parent has torch and numba loaded.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from collections.abc import Callable, Iterable
from typing import Any

__all__ = ["run_local", "single_threaded_torch"]


def single_threaded_torch() -> None:
    """One torch thread in this process (if torch is installed): parallel workers must not each take every core, and
    a trained policy's actions must not depend on the machine's core count (see ``baselines.trained``)."""
    try:
        import torch
    except ImportError:  # the environments and the hand baselines need no torch
        return
    torch.set_num_threads(1)


def _start_worker() -> None:
    """A pool worker's initializer: one torch thread, and a watch that ends the worker when its parent dies.

    Killed outright (kill -9 of the parent alone, not its group), the parent can no longer stop its workers, and an
    idle one waits on its queue for ever, holding its memory (458 MB with torch loaded): the watch waits on the pipe
    that links a spawned process to its parent, which the kernel closes when the parent dies, and exits then.
    """
    single_threaded_torch()
    parent = multiprocessing.parent_process()
    if parent is None:  # not a spawned worker (called in the parent itself)
        return

    def exit_when_orphaned() -> None:
        parent.join()  # returns once the parent's end of the pipe is closed: it died
        os._exit(1)  # at once: nothing is left to report to, and a job's files are written atomically

    threading.Thread(target=exit_when_orphaned, name="exit-when-orphaned", daemon=True).start()


def run_local(
    work: Callable[[Any], Any],
    jobs: Iterable[Any],
    workers: int,
    on_result: Callable[[Any, Any], None],
    on_error: Callable[[Any, BaseException], None],
) -> None:
    """``work(job)`` for every job on a pool of ``min(workers, len(jobs))`` processes; ``on_result(job, result)``
    or ``on_error(job, exception)`` (the worker raised or died) in the parent as each finishes."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    jobs = list(jobs)
    if not jobs:
        return
    context = multiprocessing.get_context("spawn")  # the parent has torch and numba loaded: fork is not safe
    pool = ProcessPoolExecutor(
        max_workers=max(1, min(workers, len(jobs))), mp_context=context, initializer=_start_worker
    )
    futures = {pool.submit(work, job): job for job in jobs}
    try:
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                job = futures[future]
                try:
                    result = future.result()
                except Exception as exc:  # the job raised, or its worker died (killed, out of memory)
                    on_error(job, exc)
                else:
                    on_result(job, result)
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
