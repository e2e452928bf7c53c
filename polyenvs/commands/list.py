"""``polyenvs list``: every environment with its spaces (one robot's) and a line."""

from __future__ import annotations

import argparse
import json

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "list", help="every environment (Gymnasium id or PettingZoo module) with its spaces (one robot's) and a line"
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    import polyenvs
    from polyenvs.registry import REGISTRY
    from polyenvs.rollout import agent_spaces, make_env

    rows = []
    for entry in REGISTRY:
        env = make_env(entry.id)
        observation_space, action_space = agent_spaces(env)  # a parallel env's: one robot's
        rows.append((entry.id, _describe_space(action_space), _describe_space(observation_space), entry.description))
        env.close()
    if args.json:
        print(
            json.dumps(
                [dict(zip(("id", "action_space", "observation_space", "description"), r, strict=True)) for r in rows],
                indent=1,
            )
        )
        return 0
    width = max(len(r[0]) for r in rows)
    for env_id, act, obs, desc in rows:
        print(f"{env_id:<{width}}  action {act}  observation {obs}\n{'':<{width}}  {desc}")
    print(f"\n{len(rows)} environments (polyenvs {polyenvs.__version__})")
    return 0


def _describe_space(space) -> str:
    """A one-line summary: ``Discrete(3)``, or ``Box(22,) float32 in [-1, 1]`` instead of every bound."""
    import numpy as np
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        return f"Box{space.shape} {space.dtype} in [{np.min(space.low):g}, {np.max(space.high):g}]"
    return str(space)
