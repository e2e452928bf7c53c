"""``polyenvs sweep``: its flags, checked before any job, and the summary it prints.

The jobs, and how they run, are :mod:`polyenvs.training.sweep`'s.

``polyenvs sweep --envs ID... --algos ALGO... --seeds S... [--timesteps N] [--config-dir DIR] [--backend local|ray]
[--address ADDR] [--jobs N] [--out DIR] [--episodes N]``
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from polyenvs.commands.flags import int_flag
from polyenvs.limits import MAX_EPISODES, MAX_JOBS, MAX_SEED, MAX_TIMESTEPS
from polyenvs.pool import backend_description, check_backend
from polyenvs.training import DEFAULT_CHECKPOINT_EVERY, sweep

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``sweep`` subcommand to an ``argparse`` subparsers object; ``args.func`` is :func:`run`."""
    p = subparsers.add_parser(
        "sweep",
        help="train and evaluate every (environment, algorithm, seed) in parallel (needs polyenvs[train])",
        description="Train every (environment, algorithm, seed) and evaluate it on the leaderboard's seeds, as "
        "independent jobs on a local process pool (--jobs workers) or on Ray (--backend ray; needs "
        "polyenvs[distributed]). Writes OUT/agents/<env>/<algo>/seed<N>/ (as benchmarks/agents) and "
        "OUT/results/<env>__agent__<algo>__seed<N>.json; a re-run skips finished jobs and resumes interrupted ones "
        "(from their last checkpoint, or from the start if they saved none). On a Ray cluster OUT must be on a "
        "file system every node shares.",
    )
    p.add_argument("--envs", nargs="+", required=True, metavar="ID", help="environment ids (polyenvs list)")
    p.add_argument("--algos", nargs="+", required=True, metavar="ALGO", help="algorithms (ppo, maskable_ppo, ...)")
    p.add_argument("--seeds", nargs="+", required=True, metavar="S", help=f"training seeds, 0 to {MAX_SEED}")
    p.add_argument(
        "--timesteps", default=None, help=f"training steps per job, 1 to {MAX_TIMESTEPS:,} (default: the config's)"
    )
    p.add_argument(
        "--config-dir",
        default=None,
        help="directory of <algo>.yml configs (default: the configs shipped with polyenvs)",
    )
    p.add_argument("--backend", default="local", help="local (a process pool, default) or ray")
    p.add_argument(
        "--address", default=None, help="with --backend ray: a running cluster's address (ray://... or auto)"
    )
    p.add_argument(
        "--jobs", default=None, help=f"parallel jobs, 1 to {MAX_JOBS} (default: the CPU count; a local Ray's CPUs)"
    )
    p.add_argument(
        "--out", default=str(sweep.DEFAULT_SWEEP_DIR), help=f"output directory (default {sweep.DEFAULT_SWEEP_DIR})"
    )
    p.add_argument(
        "--checkpoint-every",
        default=str(DEFAULT_CHECKPOINT_EVERY),
        help="save each job's model every this many timesteps, so that a re-run after a kill resumes from there; "
        f"0: only at the end and on Ctrl-C (default {DEFAULT_CHECKPOINT_EVERY})",
    )
    p.add_argument("--episodes", default="10", help=f"evaluation episodes per job, 1 to {MAX_EPISODES} (default 10)")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``polyenvs sweep`` for parsed ``args``: 0 when every job finished, 1 if any failed, 130 after Ctrl-C."""
    seeds = [int_flag("--seeds", s, 0, MAX_SEED) for s in args.seeds]
    timesteps = int_flag("--timesteps", args.timesteps, 1, MAX_TIMESTEPS)
    episodes = int_flag("--episodes", args.episodes, 1, MAX_EPISODES)
    checkpoint_every = int_flag("--checkpoint-every", args.checkpoint_every, 0, MAX_TIMESTEPS)
    workers = (
        int_flag("--jobs", args.jobs, 1, MAX_JOBS) if args.jobs is not None else min(os.cpu_count() or 1, MAX_JOBS)
    )
    check_backend(args.backend, args.address)
    jobs = sweep.plan_jobs(
        args.envs,
        args.algos,
        seeds,
        out=Path(args.out),
        config_dir=Path(args.config_dir) if args.config_dir is not None else None,
        timesteps=timesteps,
        episodes=episodes,
        checkpoint_every=checkpoint_every,
    )
    busy = min(workers, len(jobs)) if args.backend == "local" else workers  # a local Ray instance has --jobs CPUs
    print(f"{len(jobs)} job{'s' if len(jobs) != 1 else ''} on {backend_description(args.backend, busy, args.address)}")
    from polyenvs.training.train import interrupted_note

    for job in jobs:
        note = interrupted_note(job.out_dir)
        if note is not None:
            print(f"{job.name}: {note}")
    results: list[dict] = []
    start = time.monotonic()
    try:
        results = sweep.run_sweep(jobs, backend=args.backend, workers=workers, address=args.address)
    except KeyboardInterrupt:
        print(
            "polyenvs sweep: interrupted; finished jobs are kept (a re-run skips them); a run stopped mid-training "
            "keeps its partial model (run.json: completed false), which a re-run resumes",
            file=sys.stderr,
        )
        return 130
    print()
    for line in sweep.summary_table(results):
        print(line)
    failed = [r for r in results if "error" in r]
    print(f"{len(results) - len(failed)} of {len(jobs)} jobs finished in {time.monotonic() - start:.1f} s; "
          f"agents in {Path(args.out) / 'agents'}, results in {Path(args.out) / 'results'}")  # fmt: skip
    if failed:
        print(f"polyenvs sweep: {len(failed)} job{'s' if len(failed) != 1 else ''} failed:", file=sys.stderr)
        for r in failed:
            print(f"  {sweep.describe_result(r)}", file=sys.stderr)
        return 1
    return 0
