"""``polyenvs list``: every environment with its spaces (one robot's) and a line; with ``--policies``, every
environment's hand baselines and the parameters each may have tuned (``polyenvs tune``).

An environment whose optional extra is not installed (the beasts without ``mujoco``) is listed with the line that
installs it instead of its spaces; a superseded id (kept registered for the results made with it) with its newer
version.
"""

from __future__ import annotations

import argparse
import json

__all__ = ["add_parser", "run"]

#: The fields of a ``--json`` row (the spaces are ``null`` and ``missing`` says why where an extra is missing).
FIELDS = ("id", "action_space", "observation_space", "description", "superseded_by", "missing")


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "list", help="every environment (Gymnasium id or PettingZoo module) with its spaces (one robot's) and a line"
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.add_argument(
        "--policies",
        action="store_true",
        help="list each environment's hand baselines and their tunable parameters (start [range] unit) instead",
    )
    p.set_defaults(func=run)
    return p


def _policies() -> list[dict]:
    """Per environment: its hand baselines, the paper's marked, each with its tunable parameters."""
    import dataclasses

    from baselines import paper_policy
    from baselines.factory import tunable_parameters
    from baselines.table import hand_baselines
    from polyenvs.registry import REGISTRY

    return [
        {
            "id": entry.id,
            "paper": paper_policy(entry.id),
            "baselines": {
                name: [dataclasses.asdict(p) for p in tunable_parameters(name, entry.id)]
                for name in hand_baselines(entry.id).names
            },
        }
        for entry in REGISTRY
    ]


def _print_policies(rows: list[dict]) -> None:
    for row in rows:
        print(row["id"])
        for name, tunables in row["baselines"].items():
            paper = " (paper)" if name == row["paper"] else ""
            params = "; ".join(f"{p['name']} = {p['start']:g} [{p['low']:g}, {p['high']:g}] {p['unit']}".rstrip()
                               for p in tunables)  # fmt: skip
            print(f"  {name}{paper}: {params or 'nothing to tune'}")


def run(args: argparse.Namespace) -> int:
    import polyenvs
    from polyenvs.registry import REGISTRY

    if args.policies:
        rows = _policies()
        if args.json:
            print(json.dumps(rows, indent=1))
        else:
            _print_policies(rows)
        return 0
    rows = [_row(entry) for entry in REGISTRY]
    if args.json:
        print(json.dumps([dict(zip(FIELDS, r, strict=True)) for r in rows], indent=1))
        return 0
    width = max(len(r[0]) for r in rows)
    for env_id, act, obs, desc, newer, missing in rows:
        spaces = missing or f"action {act}  observation {obs}"
        superseded = f" (superseded by {newer})" if newer else ""
        print(f"{env_id:<{width}}  {spaces}{superseded}\n{'':<{width}}  {desc}")
    print(f"\n{len(rows)} environments (polyenvs {polyenvs.__version__})")
    return 0


def _row(entry) -> tuple:
    """``FIELDS`` of one registry row: its spaces from a copy built here, or why it cannot be built."""
    from gymnasium.error import DependencyNotInstalled

    from polyenvs.evaluation.rollout import agent_spaces, make_env

    try:
        env = make_env(entry.id)
    except DependencyNotInstalled as exc:  # its message names the extra to install
        return entry.id, None, None, entry.description, entry.superseded_by, str(exc)
    observation_space, action_space = agent_spaces(env)  # a parallel env's: one robot's
    env.close()
    return (entry.id, _describe_space(action_space), _describe_space(observation_space), entry.description,
            entry.superseded_by, None)  # fmt: skip


def _describe_space(space) -> str:
    """A one-line summary: ``Discrete(3)``, or ``Box(22,) float32 in [-1, 1]`` instead of every bound."""
    import numpy as np
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        return f"Box{space.shape} {space.dtype} in [{np.min(space.low):g}, {np.max(space.high):g}]"
    return str(space)
