"""``polyenvs collect``: a policy's seeded episodes written as a Minari dataset (needs ``polyenvs[collect]``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from polyenvs.commands.flags import ProgressBar, add_episode_flags, add_progress_flag, episode_flags
from polyenvs.commands.leaderboard import REFERENCE_RESULTS_DIR

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "collect",
        help="write a policy's episodes as a Minari dataset (needs polyenvs[collect])",
        description="Run a policy on seeds SEED, SEED+1, ... and write its episodes as one Minari dataset into DIR, "
        "a Minari datasets root holding only it: DIR/polyenvs/ENV/POLICY-v0/data/ (nothing goes to ~/.minari). "
        "Load it with MINARI_DATASETS_PATH=DIR and minari.load_dataset('polyenvs/ENV/POLICY-v0') (printed at the "
        "end), or give DIR to polyenvs train --bc-from. The dataset holds the environment's spec "
        "(recover_environment), each episode's seed, the policy's name (algorithm_name), polyenvs' version and git "
        "commit (code_permalink), and ref_min_score / ref_max_score: the mean return of random and of the paper's "
        f"algorithm, from the committed results in {REFERENCE_RESULTS_DIR}/ where they exist for these keywords, "
        "else evaluated on 10 episodes. A PettingZoo swarm gives a per-robot dataset: each robot's trajectory is an "
        "episode (options {'robot': NAME}), the spec is polyenvs.evaluation.datasets.RobotView (the swarm as that "
        "robot sees it, its teammates driven by the same policy). DIR is written under a temporary name beside it and "
        "renamed into place when done (the next run removes what a killed one left there).",
    )
    p.add_argument(
        "env_id", help="a Gymnasium id (polyenvs/BuckybotGoal-v0) or a PettingZoo module (polyenvs.swarm.corridor_v0)"
    )
    p.add_argument(
        "--policy",
        default="paper",
        help="'random', a hand baseline's name, 'paper' (default), or a trained model: a training directory or a .zip",
    )
    add_episode_flags(p)
    p.add_argument("--out", required=True, metavar="DIR", help="the directory to write (must not exist or be empty)")
    p.add_argument("--overwrite", action="store_true", help="replace DIR if it exists")
    add_progress_flag(p)
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from polyenvs.evaluation.datasets import CollectRequest, check_out_dir, collect

    episodes, seed, env_kwargs, policy_kwargs = episode_flags(args)
    out = Path(args.out)
    check_out_dir(out, args.overwrite, "--out")
    bar = ProgressBar("episodes", enabled=args.progress)
    request = CollectRequest(
        args.env_id,
        args.policy,
        episodes=episodes,
        seed=seed,
        out_dir=out,
        env_kwargs=env_kwargs,
        policy_kwargs=policy_kwargs,
        overwrite=args.overwrite,
        results_dir=REFERENCE_RESULTS_DIR if REFERENCE_RESULTS_DIR.is_dir() else None,
        on_episode=bar.advance,
    )
    bar.start(episodes, label=args.policy, draw=False)  # drawn once the inputs passed their checks
    try:
        identifier = collect(request)
    finally:
        bar.close()
    print(f"wrote {identifier} ({episodes} episodes) to {out}")
    print(
        f"load it: MINARI_DATASETS_PATH={out.absolute()} python -c \"import minari; minari.load_dataset('{identifier}')\""
    )
    return 0
