"""Independent jobs on a local process pool or on Ray: what ``polyenvs sweep`` and ``polyenvs leaderboard`` run on.

:func:`run_jobs` runs ``work(job)`` for every job on a backend: ``"local"`` (:func:`run_local`, ``workers`` spawned
processes) or ``"ray"`` (:func:`run_ray`, a Ray task of one CPU per job, on a local Ray instance of ``workers`` CPUs
or, with ``address``, on a running cluster, whose CPUs decide how many run at once). On either, every worker has one
torch thread (N workers use N cores, and a trained policy's actions do not depend on the core count), and each
result is handed to ``on_result(job, result)`` in the parent as it finishes, in finishing order; a job that raises,
or whose worker dies, hands its exception to ``on_error(job, exception)``. Ctrl-C (or an exception from either
callback) cancels what has not started: the local pool waits for what has, Ray stops it. A local worker whose parent
is killed outright (kill -9) exits with it; Ray ends a killed driver's tasks itself.

``work`` and the jobs must pickle (a module-level function, plain data): the local workers are spawned, not forked,
since the parent has torch and numba loaded, and Ray ships both to its workers. A job runs in the parent's working
directory on either; on a cluster every node needs polyenvs installed and the files the jobs read at the same
paths, and whatever ``work`` writes goes to the file system of the node that ran it.
:func:`check_backend` checks a command's ``--backend`` and ``--address`` before any work.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from collections.abc import Callable, Iterable
from typing import Any

from polyenvs.core.extras import install_hint
from polyenvs.errors import InputError

__all__ = [
    "BACKENDS",
    "RAY_HINT",
    "backend_description",
    "check_backend",
    "import_ray",
    "one_line",
    "run_jobs",
    "run_local",
    "run_ray",
    "single_threaded_torch",
]

BACKENDS = ("local", "ray")
RAY_HINT = f"the ray backend needs Ray: {install_hint('distributed')}"


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


def one_line(exc: BaseException) -> str:
    """``exc`` as one line, its type first: how a failed job is reported."""
    message = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {message}" if message else type(exc).__name__


def import_ray():
    """The ``ray`` module, or an :class:`InputError` saying how to install it."""
    try:
        import ray
    except ImportError:
        raise InputError(RAY_HINT) from None
    return ray


def check_backend(backend: str, address: str | None) -> None:
    """A command's ``--backend`` and ``--address``, before any work: an :class:`InputError` (one line naming the
    flag) for an unknown backend, an address without the ray backend, or the ray backend without Ray installed."""
    if backend not in BACKENDS:
        raise InputError(f"--backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    if address is not None and backend != "ray":
        raise InputError("--address joins a Ray cluster: it needs --backend ray")
    if backend == "ray":
        import_ray()


def backend_description(backend: str, workers: int, address: str | None = None) -> str:
    """Where :func:`run_jobs` runs, for a command's first line: ``"Ray (a local instance, 2 CPUs)"``, ``"Ray
    (auto)"`` or ``"2 local workers"``."""
    if backend == "ray":
        return f"Ray ({address or f'a local instance, {workers} CPUs'})"
    return f"{workers} local worker{'s' if workers != 1 else ''}"


def run_jobs(
    work: Callable[[Any], Any],
    jobs: Iterable[Any],
    workers: int,
    on_result: Callable[[Any, Any], None],
    on_error: Callable[[Any, BaseException], None],
    *,
    backend: str = "local",
    address: str | None = None,
) -> None:
    """``work(job)`` for every job on ``backend`` (:data:`BACKENDS`): :func:`run_local`, or :func:`run_ray` with
    ``address``; the same callbacks, the same results."""
    check_backend(backend, address)
    if backend == "ray":
        run_ray(work, jobs, workers, on_result, on_error, address=address)
    else:
        run_local(work, jobs, workers, on_result, on_error)


def _as_a_local_worker(work: Callable[[Any], Any], job: Any, directory: str) -> Any:
    """``work(job)`` in a Ray worker as in a local one: one torch thread (a Ray worker runs no initializer of ours),
    in the parent's working directory (where a cluster's node started it otherwise), so that relative paths in a
    job (the leaderboard's agents) mean the same on every node that has the same files at the same place."""
    single_threaded_torch()
    os.chdir(directory)
    return work(job)


def run_ray(
    work: Callable[[Any], Any],
    jobs: Iterable[Any],
    workers: int,
    on_result: Callable[[Any, Any], None],
    on_error: Callable[[Any, BaseException], None],
    address: str | None = None,
) -> None:
    """:func:`run_local`'s contract on Ray: a task of one CPU per job, not retried, run in this process's working
    directory, on the Ray this process has joined already, else on a local instance of ``workers`` CPUs (shut down at the end) or, with ``address``, on
    that running cluster (left on; an address it cannot join is an :class:`InputError` naming ``--address``)."""
    jobs = list(jobs)
    if not jobs:
        return
    ray = import_ray()
    started = not ray.is_initialized()
    if started:
        _start_ray(ray, workers, address)
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(_as_a_local_worker)
        refs = {task.remote(work, job, os.getcwd()): job for job in jobs}
        pending = list(refs)
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    try:
                        result = ray.get(ref)
                    except (
                        Exception
                    ) as exc:  # the job raised (a RayTaskError that is also its error), or its worker died
                        on_error(refs[ref], exc)
                    else:
                        on_result(refs[ref], result)
        except BaseException:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise
    finally:
        if started:
            ray.shutdown()


def _start_ray(ray, workers: int, address: str | None) -> None:
    """Join the cluster at ``address``, or start a local instance of ``workers`` CPUs."""
    if address is None:
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        return
    try:
        ray.init(address=address, log_to_driver=False)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise InputError(f"--address {address}: cannot join the Ray cluster: {one_line(exc)}") from None
