"""A local process pool for independent jobs: what ``polyenvs sweep`` and ``polyenvs leaderboard`` run on.

:func:`run_local` runs ``work(job)`` for every job on ``workers`` spawned processes (each with one torch thread, so
N workers use N cores) and hands each result to ``on_result`` in the parent as it finishes, in finishing order;
a worker that dies hands its exception to ``on_error``. Ctrl-C (or an exception from either callback) cancels
what has not started and waits for what has. ``work`` and the jobs must pickle (a module-level function, plain
data): the workers are spawned, not forked, since the parent has torch and numba loaded.
"""

from __future__ import annotations

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


def run_local(
    work: Callable[[Any], Any],
    jobs: Iterable[Any],
    workers: int,
    on_result: Callable[[Any, Any], None],
    on_error: Callable[[Any, BaseException], None],
) -> None:
    """``work(job)`` for every job on a pool of ``min(workers, len(jobs))`` processes; ``on_result(job, result)``
    or ``on_error(job, exception)`` (the worker raised or died) in the parent as each finishes."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    jobs = list(jobs)
    if not jobs:
        return
    context = multiprocessing.get_context("spawn")  # the parent has torch and numba loaded: fork is not safe
    pool = ProcessPoolExecutor(
        max_workers=max(1, min(workers, len(jobs))), mp_context=context, initializer=single_threaded_torch
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
