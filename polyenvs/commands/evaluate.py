"""``polyenvs evaluate``: run a policy on fixed seeds and print its returns and task metrics (or one JSON document)."""

from __future__ import annotations

import argparse
import json

from polyenvs.commands.flags import ProgressBar, add_episode_flags, episode_flags

__all__ = ["add_parser", "describe_policy", "format_value", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("evaluate", help="run a policy on fixed seeds and print its returns and task metrics")
    p.add_argument(
        "env_id", help="a Gymnasium id (polyenvs/BuckybotGoal-v0) or a PettingZoo module (polyenvs.swarm.corridor_v0)"
    )
    p.add_argument(
        "--policy",
        default="paper",
        help="'random', a hand baseline's name, 'paper' (default), or a trained model: a training directory "
        "(model.zip, vecnormalize.pkl, run.json) or a .zip",
    )
    add_episode_flags(p)
    p.add_argument("--json", action="store_true", help="print one JSON document (progress, if any, goes to stderr)")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from polyenvs.evaluation.episodes import evaluate

    episodes, seed, env_kwargs, policy_kwargs = episode_flags(args)
    bar = ProgressBar("episodes")
    bar.start(episodes, label=args.policy, draw=False)  # drawn once the inputs passed their checks
    try:
        doc = evaluate(
            args.env_id,
            args.policy,
            episodes=episodes,
            seed=seed,
            env_kwargs=env_kwargs,
            policy_kwargs=policy_kwargs,
            on_episode=lambda _: bar.advance(),
        )
    finally:
        bar.close()
    if args.json:
        print(json.dumps(doc, indent=1))
        return 0
    metric_names = list(doc["episodes"][0]["metrics"])
    header = ["seed", "return", "length", *metric_names]
    rows = [
        [ep["seed"], ep["return"], ep["length"], *(ep["metrics"][m] for m in metric_names)] for ep in doc["episodes"]
    ]
    summary = doc["summary"]
    rows.append(["mean", *(summary[h] for h in header[1:])])
    seeds = doc["seeds"]
    print(doc["env_id"])
    print(f"policy: {describe_policy(doc['env_id'], doc['policy'], doc['policy_description'])}")
    print(f"episodes: {len(seeds)} on seeds {seeds[0]}..{seeds[-1]}" if len(seeds) > 1 else f"seed: {seeds[0]}")
    if doc["env_kwargs"]:
        print(f"environment: {', '.join(f'{k}={format_value(v)}' for k, v in doc['env_kwargs'].items())}")
    print()
    print("\n".join(format_table(header, rows)))
    return 0


def format_value(value) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def describe_policy(env_id: str, policy: str, description: dict) -> str:
    """``wall_follower (d_star_cm=50, x_s_cm=20, ...)``; ``paper = goal_seeker (clearance_cm=40)`` for the alias;
    ``ppo model runs/ppo_wall (training_seed=0, timesteps=250000, normalize=true)`` for a trained model."""
    from baselines import paper_policy

    name, hidden = policy, {"name"}
    paper = paper_policy(env_id) if policy == "paper" else None
    if paper:
        name = f"paper = {paper}"
    if "algo" in description and "path" in description:
        name, hidden = f"{description['algo']} model {description['path']}", {"name", "algo", "path", "sha256"}
    params = ", ".join(f"{k}={format_value(v)}" for k, v in description.items() if k not in hidden)
    return f"{name} ({params})" if params else name


def format_table(header: list[str], rows: list[list]) -> list[str]:
    """Right-aligned columns, each as wide as its widest cell."""

    def cell(v) -> str:
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    cells = [header] + [[cell(v) for v in row] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    return ["  ".join(f"{c:>{w}}" for c, w in zip(r, widths, strict=True)) for r in cells]
