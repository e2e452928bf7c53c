"""The ``polyenvs`` command line: list environments, evaluate policies, build the leaderboard, record episodes.

Expected failures (unknown id or policy, bad JSON or keyword arguments) print one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

__all__ = ["main"]


class CliError(Exception):
    """An error the user can fix: printed as one line, no traceback."""


def _json_arg(text: str, name: str) -> dict:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CliError(f"{name} is not valid JSON: {exc.msg} (got {text!r})") from None
    if not isinstance(value, dict):
        raise CliError(f"{name} must be a JSON object, got {text!r}")
    return value


def _describe_space(space) -> str:
    """A one-line summary: ``Discrete(3)``, or ``Box(22,) float32 in [-1, 1]`` instead of every bound."""
    import numpy as np
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        return f"Box{space.shape} {space.dtype} in [{np.min(space.low):g}, {np.max(space.high):g}]"
    return str(space)


def _cmd_list(args) -> int:
    import gymnasium as gym

    import polyenvs
    from polyenvs.registry import REGISTRY

    rows = []
    for entry in REGISTRY:
        env = gym.make(entry.id)
        rows.append(
            (entry.id, _describe_space(env.action_space), _describe_space(env.observation_space), entry.description)
        )
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


def _cmd_evaluate(args) -> int:
    from polyenvs.evaluation import evaluate

    doc = evaluate(
        args.env_id,
        args.policy,
        episodes=args.episodes,
        seed=args.seed,
        env_kwargs=_json_arg(args.env_kwargs, "--env-kwargs"),
        policy_kwargs=_json_arg(args.policy_kwargs, "--policy-kwargs"),
    )
    if args.json:
        print(json.dumps(doc, indent=1))
        return 0
    metric_names = list(doc["episodes"][0]["metrics"])
    header = ["seed", "return", "length", *metric_names]
    print(f"{doc['env_id']}  policy {doc['policy']}  {doc['policy_description']}")
    print("  ".join(f"{h:>14}" for h in header))
    for ep in doc["episodes"]:
        values = [ep["seed"], ep["return"], ep["length"], *(ep["metrics"][m] for m in metric_names)]
        print("  ".join(f"{v:>14.4g}" if isinstance(v, float) else f"{v:>14}" for v in values))
    summary = doc["summary"]
    print("  ".join([f"{'mean':>14}"] + [f"{summary[h]:>14.4g}" for h in header[1:]]))
    return 0


def _cmd_leaderboard(args) -> int:
    from polyenvs.leaderboard import run_leaderboard, write_leaderboard
    from polyenvs.registry import ENV_IDS

    env_ids = [e for e in ENV_IDS if args.only is None or args.only in e]
    if not env_ids:
        raise CliError(f"no environment id contains {args.only!r}")
    episodes = args.episodes if args.episodes is not None else (5 if args.quick else 50)
    docs = run_leaderboard(
        env_ids, episodes, Path(args.results_dir), redo=args.redo, progress=lambda m: print(m, file=sys.stderr)
    )
    text = write_leaderboard(docs, Path(args.output), quick=episodes < 50)
    print(text)
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


def _cmd_record(args) -> int:
    import gymnasium as gym
    import numpy as np

    import polyenvs  # noqa: F401
    from baselines import make_policy

    try:
        import imageio.v2 as imageio
    except ImportError:
        raise CliError('recording needs imageio: pip install "polyenvs[render]"') from None
    env_id = args.env_id.split(":", 1)[-1]
    if env_id not in gym.registry:
        raise CliError(f"unknown environment id {env_id!r}; run 'polyenvs list' for the ids")
    try:
        env = gym.make(env_id, render_mode="rgb_array", **_json_arg(args.env_kwargs, "--env-kwargs"))
    except TypeError as exc:
        raise CliError(f"bad environment keyword arguments for {env_id}: {exc}") from None
    policy = make_policy(args.policy, env_id, env.observation_space, env.action_space, seed=args.seed)
    obs, _ = env.reset(seed=args.seed)
    frames, state, start = [env.render()], None, True
    for _ in range(args.max_steps):
        action, state = policy.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
        obs, _, terminated, truncated, _ = env.step(action)
        frames.append(env.render())
        start = False
        if terminated or truncated:
            break
    env.close()
    fps = args.fps or env.metadata.get("render_fps", 10)
    try:
        if args.output.endswith(".gif"):
            imageio.mimsave(args.output, frames, duration=1000 / fps, loop=0)
        else:
            imageio.mimsave(args.output, frames, fps=fps)
    except (OSError, ValueError) as exc:
        raise CliError(f"could not write {args.output}: {exc}") from None
    print(f"wrote {len(frames)} frames to {args.output}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="polyenvs", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="every environment id with its spaces and a one-line description")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=_cmd_list)

    p = sub.add_parser("evaluate", help="run a policy on fixed seeds and print its returns and task metrics")
    p.add_argument("env_id")
    p.add_argument("--policy", default="paper", help="'random', a hand baseline's name, or 'paper' (default)")
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--seed", type=int, default=0, help="first seed; episodes use seed, seed+1, ...")
    p.add_argument("--env-kwargs", default="{}", help="JSON object of environment keyword arguments")
    p.add_argument("--policy-kwargs", default="{}", help="JSON object of baseline parameters")
    p.add_argument("--json", action="store_true", help="print one JSON document")
    p.set_defaults(func=_cmd_evaluate)

    p = sub.add_parser("leaderboard", help="evaluate every baseline on every environment; write the table")
    p.add_argument("--episodes", type=int, default=None, help="episodes per policy (default 50, 5 with --quick)")
    p.add_argument("--quick", action="store_true", help="5 episodes per policy; the table says so")
    p.add_argument("--only", default=None, help="only environment ids containing this text")
    p.add_argument("--results-dir", default="benchmarks/results")
    p.add_argument("--output", default="benchmarks/LEADERBOARD.md")
    p.add_argument("--redo", action="store_true", help="re-evaluate even where results exist")
    p.set_defaults(func=_cmd_leaderboard)
    p = sub.add_parser("record", help="record a GIF or MP4 of a policy (needs imageio: polyenvs[render])")
    p.add_argument("env_id")
    p.add_argument("--policy", default="paper")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-steps", type=int, default=300)
    p.add_argument("--fps", type=float, default=None, help="frames per second (default: the env's render_fps)")
    p.add_argument("--env-kwargs", default="{}", help="JSON object of environment keyword arguments")
    p.add_argument("--output", default="episode.gif", help="a .gif, or .mp4 with imageio-ffmpeg installed")
    p.set_defaults(func=_cmd_record)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (CliError, ValueError, KeyError) as exc:
        message = exc.args[0] if exc.args else str(exc)
        print(f"polyenvs {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("polyenvs: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
