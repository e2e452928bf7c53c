"""``polyenvs tune``: search a hand baseline's tunable parameters on the training layouts (needs polyenvs[tune]).

``polyenvs tune ENV --policy NAME --trials N --seed S --out DIR [--episodes N] [--sampler tpe|cmaes]
[--storage URL] [--env-kwargs JSON] [--max-mean METRIC=LIMIT ...]``; the study is :mod:`polyenvs.training.tune`'s, its output directory a policy
(:mod:`baselines.tuned`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from polyenvs.commands.flags import float_flag, int_flag, parse_json_object
from polyenvs.errors import InputError
from polyenvs.files import check_writable_directory
from polyenvs.limits import MAX_EPISODES, MAX_SEED, MAX_TRIALS

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "tune",
        help="tune a hand baseline's parameters on the training layouts (Optuna; needs polyenvs[tune])",
        description="Search the parameters a hand baseline declares tunable (polyenvs list --policies) for the best "
        "task score over a fixed set of episodes on the training layouts, with Optuna (TPE or CMA-ES, median "
        "pruning). The first trial is the baseline as it ships. DIR/tuned.json (rewritten after every trial) holds "
        "the best parameters, the study's history, the command, the wall clock and the versions; DIR is then a "
        "policy for evaluate, record, collect, leaderboard and train --residual. The study is stored in "
        "DIR/study.db (or --storage, an Optuna storage URL several workers share); run the same command again to "
        "go on with an interrupted study.",
    )
    p.add_argument("env_id", help="a Gymnasium id or a PettingZoo module (polyenvs list)")
    p.add_argument("--policy", default="paper", help="the hand baseline to tune: paper (default) or its name")
    p.add_argument("--trials", required=True, help=f"trials in the study, 1 to {MAX_TRIALS}")
    p.add_argument("--seed", default="0", help=f"tuning seed, 0 to {MAX_SEED}: the sampler and the episodes")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--episodes", default=None, help=f"training episodes per trial, 1 to {MAX_EPISODES} (default 20)")
    p.add_argument("--sampler", default="tpe", help="tpe (default) or cmaes")
    p.add_argument("--storage", default=None, help="an Optuna storage URL (default: sqlite in DIR)")
    p.add_argument("--env-kwargs", default="{}", help="JSON object of environment keyword arguments")
    p.add_argument(
        "--max-mean",
        action="append",
        default=[],
        metavar="METRIC=LIMIT",
        help="keep an episode metric's mean over a trial's episodes at most LIMIT (a number, or 'first': the first "
        "trial's, the baseline as it ships), e.g. mean_power_w=first; repeatable; TPE only",
    )
    p.set_defaults(func=run)
    return p


def _limit(text: str) -> tuple[str, float | str]:
    """``(metric, limit)`` of a ``--max-mean METRIC=LIMIT``."""
    from polyenvs.training.tune import FIRST

    metric, sep, limit = text.partition("=")
    if not sep or not metric:
        raise InputError(f"--max-mean must be METRIC=LIMIT, got {text!r}")
    return metric, FIRST if limit == FIRST else float_flag(f"--max-mean {metric}", limit, -1e300, 1e300)


def run(args: argparse.Namespace) -> int:
    from polyenvs.training.tune import DEFAULT_EPISODES, TuneRequest, check_request, tune

    out = Path(args.out)
    episodes = int_flag("--episodes", args.episodes, 1, MAX_EPISODES)
    request = TuneRequest(
        env_id=args.env_id,
        policy=args.policy,
        trials=int_flag("--trials", args.trials, 1, MAX_TRIALS) or 1,
        seed=int_flag("--seed", args.seed, 0, MAX_SEED) or 0,
        out=out,
        episodes=DEFAULT_EPISODES if episodes is None else episodes,
        sampler=args.sampler,
        storage=args.storage,
        env_kwargs=parse_json_object(args.env_kwargs, "--env-kwargs"),
        limits=dict(_limit(text) for text in args.max_mean),
    )
    check_writable_directory(out, "--out")
    check_request(request)
    doc = tune(request)
    params = ", ".join(f"{k} = {v:.4g} (paper {doc['paper_params'][k]:.4g})" for k, v in doc["params"].items())
    best = doc["best"] or {}
    print(f"{doc['env_id']} {doc['policy']}: best of {doc['finished_trials']} trials, score {best.get('score')}: "
          f"{params}; wall clock {doc['wall_clock_s']:.0f} s; {out}")  # fmt: skip
    return 0
