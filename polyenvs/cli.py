"""The ``polyenvs`` command line: list environments, evaluate policies, build the leaderboard, record episodes.

Every ``--policy`` takes a baseline name or a trained model's path alike (a training directory or a ``.zip``).
Expected failures (a bad flag value, an unknown id or policy, bad JSON or keyword arguments, a missing, corrupt or
mismatched model, an output path that cannot be written) print one line on stderr and exit 2, before any
evaluation runs. Anything else is a bug and shows its traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from polyenvs.evaluation import (
    MAX_EPISODES,
    MAX_FRAMES,
    MAX_SEED,
    MAX_STEPS,
    check_writable_directory,
    float_flag,
    int_flag,
    is_terminal,
    parse_json_object,
)

__all__ = ["main"]

#: Where ``polyenvs leaderboard`` writes by default: untracked and gitignored, so a run leaves ``git status`` clean.
DEFAULT_LEADERBOARD_DIR = Path("runs/leaderboard")
#: The committed reference results, rewritten only by ``polyenvs leaderboard --update-reference``.
REFERENCE_RESULTS_DIR = Path("benchmarks/results")
REFERENCE_TABLE = Path("benchmarks/LEADERBOARD.md")
#: Committed trained agents (``<env id with / as __>/<algo>/seed<N>/``), evaluated by the leaderboard: here, or in
#: the checkout polyenvs runs from (polyenvs.leaderboard.default_agents_dirs).
AGENTS_DIR = Path("benchmarks/agents")
#: Output formats of ``polyenvs record``: suffix -> what writing it needs.
RECORD_FORMATS = {".gif": "imageio", ".mp4": "imageio-ffmpeg"}
#: ``polyenvs record --fps`` bounds: a GIF frame lasts at most 655.35 s (a 16-bit count of 10 ms), and no player
#: shows more than a few hundred frames a second.
MIN_FPS, MAX_FPS = 0.01, 1000.0


class CliError(Exception):
    """An error the user can fix: printed as one line, no traceback."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage block), like every other error of this command line."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


# ------------------------------------------------------------------------------------------------------ checks


def _check_output_file(path: Path, flag: str) -> None:
    path = Path(path)
    if path.is_dir():
        raise CliError(f"{flag} {path}: is a directory; give a file name")
    check_writable_directory(path.parent, flag, shown=path)


# -------------------------------------------------------------------------------------------- progress display


class ProgressBar:
    """A one-line progress bar on stderr, drawn only when stderr is a terminal (so logs and pipes stay clean).

    ``start(total)`` sets the amount of work, ``advance()`` counts one unit, ``message(text)`` prints a line above
    the bar, ``close()`` ends it. Messages are printed whether or not the bar is drawn.
    """

    def __init__(self, unit: str = "episodes", stream=None, enabled: bool | None = None, width: int = 30):
        self.stream = sys.stderr if stream is None else stream
        self.enabled = is_terminal(self.stream) if enabled is None else enabled
        self.unit, self.width = unit, width
        self.total, self.done, self.label = 0, 0, ""
        self._start = time.monotonic()
        self._drawn = False

    def start(self, total: int, label: str = "", draw: bool = True) -> None:
        """Set the amount of work; with ``draw=False`` the bar first appears at the first ``advance()``."""
        self.total, self.done, self.label = int(total), 0, label
        self._start = time.monotonic()
        if draw:
            self._draw()

    def advance(self, n: int = 1) -> None:
        self.done += n
        self._draw()

    def message(self, text: str) -> None:
        if self._drawn:
            self.stream.write("\r\x1b[K")
        print(text, file=self.stream)
        self._draw()

    def close(self) -> None:
        if self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False

    def render(self) -> str:
        frac = min(self.done / self.total, 1.0) if self.total else 1.0
        filled = round(self.width * frac)
        elapsed = time.monotonic() - self._start
        eta = f", ~{elapsed * (self.total - self.done) / self.done:.0f}s left" if 0 < self.done < self.total else ""
        label = f"{self.label} " if self.label else ""
        bar = "#" * filled + "." * (self.width - filled)
        return f"{label}[{bar}] {self.done}/{self.total} {self.unit} ({elapsed:.0f}s{eta})"

    def _draw(self) -> None:
        if not self.enabled or self.total <= 0:
            return
        self.stream.write("\r" + self.render() + "\x1b[K")
        self.stream.flush()
        self._drawn = True


# ---------------------------------------------------------------------------------------------------- commands


def _describe_space(space) -> str:
    """A one-line summary: ``Discrete(3)``, or ``Box(22,) float32 in [-1, 1]`` instead of every bound."""
    import numpy as np
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        return f"Box{space.shape} {space.dtype} in [{np.min(space.low):g}, {np.max(space.high):g}]"
    return str(space)


def _format_value(value) -> str:
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
    if policy == "paper" and paper_policy(env_id):
        name = f"paper = {paper_policy(env_id)}"
    if "algo" in description and "path" in description:
        name, hidden = f"{description['algo']} model {description['path']}", {"name", "algo", "path", "sha256"}
    params = ", ".join(f"{k}={_format_value(v)}" for k, v in description.items() if k not in hidden)
    return f"{name} ({params})" if params else name


def _format_table(header: list[str], rows: list[list]) -> list[str]:
    """Right-aligned columns, each as wide as its widest cell."""

    def cell(v) -> str:
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    cells = [header] + [[cell(v) for v in row] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    return ["  ".join(f"{c:>{w}}" for c, w in zip(r, widths, strict=True)) for r in cells]


def _cmd_list(args) -> int:
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


def _cmd_evaluate(args) -> int:
    from polyenvs.evaluation import evaluate

    episodes = int_flag("--episodes", args.episodes, 1, MAX_EPISODES)
    seed = int_flag("--seed", args.seed, 0, MAX_SEED)
    env_kwargs = parse_json_object(args.env_kwargs, "--env-kwargs")
    policy_kwargs = parse_json_object(args.policy_kwargs, "--policy-kwargs")
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
        print(f"environment: {', '.join(f'{k}={_format_value(v)}' for k, v in doc['env_kwargs'].items())}")
    print()
    print("\n".join(_format_table(header, rows)))
    return 0


def _cmd_leaderboard(args) -> int:
    from polyenvs.leaderboard import (
        PROTOCOL_EPISODES,
        agents_line,
        default_agents_dirs,
        plot_path,
        run_leaderboard,
        stored_results,
        write_leaderboard,
    )
    from polyenvs.registry import ALL_IDS

    # Everything the user could get wrong is checked here, before the first evaluation.
    episodes = int_flag("--episodes", args.episodes, 1, MAX_EPISODES)
    if episodes is None:
        episodes = 5 if args.quick else PROTOCOL_EPISODES
    if args.update_reference:
        if args.quick or episodes != PROTOCOL_EPISODES:
            raise CliError(
                f"--update-reference writes the committed reference results, which use {PROTOCOL_EPISODES} "
                "episodes: do not combine it with --quick or --episodes"
            )
        if args.results_dir is not None or args.output is not None:
            raise CliError(
                f"--update-reference writes {REFERENCE_RESULTS_DIR} and {REFERENCE_TABLE}: "
                "do not combine it with --results-dir or --output"
            )
        if args.agents_dir is not None or args.policy:
            raise CliError(
                f"--update-reference evaluates the committed agents in {AGENTS_DIR}: "
                "do not combine it with --agents-dir or --policy"
            )
        if not REFERENCE_RESULTS_DIR.is_dir():
            raise CliError(
                f"--update-reference: no {REFERENCE_RESULTS_DIR} directory here; run it from the repository root"
            )
        results_dir, output = REFERENCE_RESULTS_DIR, REFERENCE_TABLE
    else:
        results_dir = Path(args.results_dir) if args.results_dir is not None else DEFAULT_LEADERBOARD_DIR / "results"
        output = Path(args.output) if args.output is not None else DEFAULT_LEADERBOARD_DIR / "LEADERBOARD.md"
    if args.agents_dir is not None:
        agents_dir, looked = Path(args.agents_dir), [Path(args.agents_dir)]
        if not agents_dir.is_dir():
            raise CliError(f"--agents-dir {agents_dir}: no such directory")
    elif args.update_reference:
        agents_dir, looked = AGENTS_DIR, [AGENTS_DIR]
    else:
        looked = default_agents_dirs()
        agents_dir = next((d for d in looked if d.is_dir()), None)
    env_ids = [e for e in ALL_IDS if args.only is None or args.only in e]
    if not env_ids:
        raise CliError(f"--only: no environment id contains {args.only!r}; run 'polyenvs list' for the ids")
    missing = _missing_extras(env_ids)  # found now, not after the environments before them were evaluated
    if missing and (args.update_reference or len(missing) == len(env_ids)):
        why = "--update-reference evaluates every environment: " if args.update_reference else ""
        raise CliError(f"{why}{_missing_line(missing)}")
    env_ids = [e for e in env_ids if e not in missing]
    agents_found = agents_line(agents_dir, env_ids, looked)  # a malformed agent directory: one line, here
    check_writable_directory(results_dir, "--results-dir")
    _check_output_file(output, "--output")
    if results_dir.absolute() == output.absolute():
        raise CliError(f"--output {output} is the results directory")
    for env_id in env_ids:  # the plots go beside the table
        _check_output_file(plot_path(output, env_id), "--output")

    bar = ProgressBar("episodes")

    def plan(total: int) -> None:  # every check passed (the agents loaded too): say what is evaluated
        if missing:
            bar.message(f"left out: {_missing_line(missing)}")
        bar.message(agents_found)
        bar.start(total)

    try:
        selected = run_leaderboard(
            env_ids,
            episodes,
            results_dir,
            redo=args.redo or args.update_reference,
            progress=bar.message,
            on_plan=plan,
            on_episode=lambda _: bar.advance(),
            agents_dir=agents_dir,
            extra_agents=args.policy or (),
        )
    finally:
        bar.close()
    # The table shows every environment with results in the directory, not only the ones just evaluated.
    others = stored_results(
        [e for e in ALL_IDS if e not in env_ids], results_dir, progress=bar.message, agents_dir=agents_dir
    )
    order = {env_id: i for i, env_id in enumerate(ALL_IDS)}
    documents = sorted(selected + others, key=lambda d: order[d["env_id"]])  # stable: policy order kept
    text = write_leaderboard(documents, output)
    print(text)
    plots = sorted({plot_path(output, d["env_id"]).name for d in documents})
    print(
        f"wrote {output} ({len(documents)} results from {results_dir}) and {len(plots)} plot"
        f"{'s' if len(plots) != 1 else ''} beside it",
        file=sys.stderr,
    )
    return 0


def _missing_extras(env_ids: list[str]) -> dict[str, str]:
    """The ids among ``env_ids`` whose optional packages are not installed -> the extra that installs them."""
    from polyenvs.evaluation import InputError, make_env
    from polyenvs.registry import entry

    missing = {}
    for env_id in env_ids:
        extra = entry(env_id).extra
        if extra is None:
            continue
        try:
            make_env(env_id).close()
        except InputError as exc:
            if not isinstance(exc.__cause__, ModuleNotFoundError):
                raise
            missing[env_id] = extra
    return missing


def _missing_line(missing: dict[str, str]) -> str:
    extras = " ".join(f'"polyenvs[{e}]"' for e in dict.fromkeys(missing.values()))
    return (
        f"{', '.join(missing)} need{'s' if len(missing) == 1 else ''} packages that are not installed: "
        f"pip install {extras}"
    )


def _cmd_record(args) -> int:
    import numpy as np

    from polyenvs.evaluation import atomic_path, make_agent, make_env
    from polyenvs.rollout import episode_frames

    seed = int_flag("--seed", args.seed, 0, MAX_SEED)
    max_steps = int_flag("--max-steps", args.max_steps, 1, MAX_STEPS)
    every = int_flag("--every", args.every, 1, MAX_STEPS)
    fps = float_flag("--fps", args.fps, MIN_FPS, MAX_FPS)
    frames = max_steps // every + 2  # the first, one every `every` steps, the last
    if frames > MAX_FRAMES:
        raise CliError(
            f"--max-steps {max_steps} with --every {every} keeps up to {frames} frames in memory, more than "
            f"{MAX_FRAMES}: raise --every to {-(-max_steps // (MAX_FRAMES - 2))} or lower --max-steps"
        )
    output = Path(args.output)
    suffix = output.suffix.lower()
    if suffix not in RECORD_FORMATS:
        raise CliError(f"--output {output}: the file name must end in {' or '.join(RECORD_FORMATS)}")
    try:
        import imageio.v3 as iio
    except ImportError:
        raise CliError('recording needs imageio: pip install "polyenvs[render]"') from None
    if suffix == ".mp4":
        try:
            import imageio_ffmpeg

            imageio_ffmpeg.get_ffmpeg_exe()
        except (ImportError, RuntimeError):
            raise CliError(
                f'--output {output}: writing .mp4 needs imageio-ffmpeg: pip install "polyenvs[render]"'
            ) from None
    _check_output_file(output, "--output")
    env_kwargs = parse_json_object(args.env_kwargs, "--env-kwargs")
    policy_kwargs = parse_json_object(args.policy_kwargs, "--policy-kwargs")

    env = make_env(args.env_id, env_kwargs, render_mode="rgb_array")
    try:
        env_id = args.env_id.split(":", 1)[-1]
        policy = make_agent(args.policy, env_id, env, seed=seed, policy_kwargs=policy_kwargs)
        frames = episode_frames(env, policy, seed, max_steps, every=every)
        fps = fps or min(max(env.metadata.get("render_fps", 10) / every, MIN_FPS), MAX_FPS)
    finally:
        env.close()
    video = np.stack(frames)
    if suffix == ".gif":
        options = {"duration": 1000 / fps, "loop": 0}
    else:  # H.264 in yuv420p needs even sides: repeat the last row / column where needed
        video = np.pad(video, ((0, 0), (0, video.shape[1] % 2), (0, video.shape[2] % 2), (0, 0)), mode="edge")
        options = {"fps": fps, "macro_block_size": 1}
    try:
        with atomic_path(output, keep_suffix=True) as tmp:
            iio.imwrite(tmp, video, extension=suffix, **options)
            if tmp.stat().st_size == 0:  # ffmpeg can fail without an exception
                raise OSError("the writer produced an empty file")
    except OSError as exc:
        raise CliError(f"--output {output}: could not write it: {exc}") from None
    print(f"wrote {len(frames)} frames to {output}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="polyenvs", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    from polyenvs.training.command import add_parser as add_train_parser  # imports nothing heavy until it runs

    add_train_parser(sub)
    from polyenvs.sweep import add_parser as add_sweep_parser  # imports nothing heavy until it runs

    add_sweep_parser(sub)
    from polyenvs.localization.command import add_parser as add_localize_parser  # imports nothing heavy either

    add_localize_parser(sub)
    p = sub.add_parser(
        "list", help="every environment (Gymnasium id or PettingZoo module) with its spaces (one robot's) and a line"
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=_cmd_list)

    p = sub.add_parser("evaluate", help="run a policy on fixed seeds and print its returns and task metrics")
    p.add_argument(
        "env_id", help="a Gymnasium id (polyenvs/BuckybotGoal-v0) or a PettingZoo module (polyenvs.swarm.corridor_v0)"
    )
    p.add_argument(
        "--policy",
        default="paper",
        help="'random', a hand baseline's name, 'paper' (default), or a trained model: a training directory "
        "(model.zip, vecnormalize.pkl, run.json) or a .zip",
    )
    p.add_argument("--episodes", default="10", help=f"number of episodes, 1 to {MAX_EPISODES} (default 10)")
    p.add_argument(
        "--seed", default="0", help=f"first seed, 0 to {MAX_SEED}; episodes use seed, seed+1, ... (default 0)"
    )
    p.add_argument("--env-kwargs", default="{}", help="JSON object of environment keyword arguments")
    p.add_argument("--policy-kwargs", default="{}", help="JSON object of baseline parameters")
    p.add_argument("--json", action="store_true", help="print one JSON document (progress, if any, goes to stderr)")
    p.set_defaults(func=_cmd_evaluate)

    p = sub.add_parser(
        "leaderboard",
        help="evaluate every baseline and trained agent on every environment; write the table and plots",
        description=f"Evaluate random, every hand baseline and every committed trained agent "
        f"({AGENTS_DIR}/<env>/<algo>/seed<N>/, in the current directory or else in the checkout polyenvs runs "
        f"from; a line says which and what it holds) on every environment and write the table, with one PNG per "
        f"environment beside it. By default results go to {DEFAULT_LEADERBOARD_DIR}/ (untracked); "
        f"--update-reference refreshes the committed {REFERENCE_RESULTS_DIR}/ and {REFERENCE_TABLE}.",
    )
    p.add_argument(
        "--episodes", default=None, help=f"episodes per policy, 1 to {MAX_EPISODES} (default 50, 5 with --quick)"
    )
    p.add_argument("--quick", action="store_true", help="5 episodes per policy; the table says so")
    p.add_argument("--only", default=None, help="only evaluate environment ids containing this text")
    p.add_argument(
        "--results-dir", default=None, help=f"where result files go (default {DEFAULT_LEADERBOARD_DIR}/results)"
    )
    p.add_argument(
        "--output", default=None, help=f"the Markdown table (default {DEFAULT_LEADERBOARD_DIR}/LEADERBOARD.md)"
    )
    p.add_argument("--redo", action="store_true", help="re-evaluate even where results exist")
    p.add_argument(
        "--agents-dir",
        default=None,
        help=f"trained agents to evaluate, as <env id with / as __>/<algo>/seed<N>/ (default {AGENTS_DIR} here, "
        "else in the checkout polyenvs runs from)",
    )
    p.add_argument(
        "--policy",
        action="append",
        metavar="PATH",
        help="also evaluate this trained model (a training directory or a .zip with a run.json beside it naming "
        "its environment); its row is labelled by the path; repeatable",
    )
    p.add_argument(
        "--update-reference",
        action="store_true",
        help=f"re-evaluate and overwrite the committed reference results ({REFERENCE_RESULTS_DIR}/, "
        f"{REFERENCE_TABLE}) with the full protocol; run from the repository root",
    )
    p.set_defaults(func=_cmd_leaderboard)

    p = sub.add_parser("record", help="record a GIF or MP4 of a policy (needs polyenvs[render])")
    p.add_argument(
        "env_id", help="a Gymnasium id (polyenvs/BuckybotGoal-v0) or a PettingZoo module (polyenvs.swarm.corridor_v0)"
    )
    p.add_argument("--policy", default="paper", help="a baseline's name, 'paper' (default), or a trained model's path")
    p.add_argument("--policy-kwargs", default="{}", help="JSON object of baseline parameters")
    p.add_argument("--seed", default="0", help=f"episode seed, 0 to {MAX_SEED} (default 0)")
    p.add_argument("--max-steps", default="300", help=f"at most this many steps, 1 to {MAX_STEPS} (default 300)")
    p.add_argument(
        "--every",
        default="1",
        help=f"keep one frame every this many steps, >= 1 (default 1: all); at most {MAX_FRAMES} frames in all",
    )
    p.add_argument(
        "--fps",
        default=None,
        help=f"frames per second, {MIN_FPS:g} to {MAX_FPS:g} (default: the env's render_fps / --every)",
    )
    p.add_argument("--env-kwargs", default="{}", help="JSON object of environment keyword arguments")
    p.add_argument("--output", default="episode.gif", help="a .gif, or a .mp4 (needs imageio-ffmpeg)")
    p.set_defaults(func=_cmd_record)
    return parser


def main(argv: list[str] | None = None) -> int:
    from polyenvs.evaluation import InputError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (CliError, InputError) as exc:
        message = exc.args[0] if exc.args else str(exc)
        print(f"polyenvs {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("polyenvs: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader went away (polyenvs list | head): stop quietly, as other tools do
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error when Python flushes
        return 141


if __name__ == "__main__":
    raise SystemExit(main())
