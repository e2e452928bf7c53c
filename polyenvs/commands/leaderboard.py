"""``polyenvs leaderboard``: evaluate every baseline and trained agent on every environment; write the table and charts."""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass
from pathlib import Path

from polyenvs.commands.flags import CliError, ProgressBar, check_output_file, int_flag
from polyenvs.core.extras import install_hint
from polyenvs.evaluation.agents import DEFAULT_AGENTS_DIR
from polyenvs.evaluation.protocol import REPRODUCE_EPISODES
from polyenvs.files import check_writable_directory
from polyenvs.limits import MAX_EPISODES, MAX_JOBS
from polyenvs.pool import backend_description, check_backend
from polyenvs.registry import REGISTRY, EnvEntry, ParallelEnvEntry

__all__ = ["DEFAULT_LEADERBOARD_DIR", "REFERENCE_RESULTS_DIR", "REFERENCE_TABLE", "add_parser", "run"]

#: Where ``polyenvs leaderboard`` writes by default: untracked and gitignored, so a run leaves ``git status`` clean.
DEFAULT_LEADERBOARD_DIR = Path("runs/leaderboard")
#: The committed reference results, rewritten only by ``polyenvs leaderboard --update-reference``.
REFERENCE_RESULTS_DIR = Path("benchmarks/results")
REFERENCE_TABLE = Path("benchmarks/LEADERBOARD.md")


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "leaderboard",
        help="evaluate every baseline and trained agent on every environment; write the table and charts",
        description=f"Evaluate random, every hand baseline and every committed trained agent "
        f"({DEFAULT_AGENTS_DIR}/<env>/<algo>/seed<N>/, in the current directory or else in the checkout polyenvs runs "
        f"from; a line says which and what it holds) on every environment, on its default and (where it takes "
        f"layouts=) held-out layouts, in parallel over the CPUs (--jobs) or on Ray (--backend ray), and write the table ranked by each "
        f"environment's task score, with charts beside it (matplotlib: the plots extra). By default results go to {DEFAULT_LEADERBOARD_DIR}/ (untracked); "
        f"--update-reference refreshes the committed {REFERENCE_RESULTS_DIR}/ and {REFERENCE_TABLE}; --reproduce "
        "checks this machine against them.",
    )
    p.add_argument(
        "--episodes",
        default=None,
        help=f"episodes per policy, 1 to {MAX_EPISODES} (default: the protocol's, 50 or as the row's score says; "
        f"5 with --quick; {REPRODUCE_EPISODES} with --reproduce)",
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
        "--jobs",
        default=None,
        help=f"evaluations run in parallel, 1 to {MAX_JOBS} (default: the CPU count); the results are the same",
    )
    p.add_argument(
        "--backend",
        default="local",
        help="where the evaluations run: local (a process pool of --jobs workers, default) or ray (Ray tasks of one "
        "CPU each, on a local Ray instance of --jobs CPUs or, with --address, a running cluster; needs "
        "polyenvs[distributed]); the results are the same",
    )
    p.add_argument(
        "--address",
        default=None,
        help="with --backend ray: a running cluster's address (ray://... or auto); every node needs polyenvs and "
        "the agents at the paths they have here; the result files are written here",
    )
    p.add_argument(
        "--agents-dir",
        default=None,
        help=f"trained agents to evaluate, as <env id with / as __>/<algo>/seed<N>/ (default {DEFAULT_AGENTS_DIR} here, "
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
    p.add_argument(
        "--reproduce",
        action="store_true",
        help=f"re-run the first {REPRODUCE_EPISODES} episodes (or --episodes) of every evaluation of the committed "
        f"reference ({REFERENCE_RESULTS_DIR}/, here or in the checkout polyenvs runs from) with its agents, check "
        "each episode against the reference's bit for bit, and write the reference's table and charts; exit status "
        f"1 if any episode differs. The sample goes to {DEFAULT_LEADERBOARD_DIR}/reproduce (or --results-dir)",
    )
    p.set_defaults(func=run)
    return p


@dataclass
class _Plan:
    """What ``polyenvs leaderboard`` evaluates and writes, from its checked flags."""

    episodes: int | None  # None: the protocol's count of each environment
    results_dir: Path
    output: Path
    agents_dir: Path | None
    env_ids: list[str]
    missing: dict[str, str]
    agents_found: str
    workers: int
    backend: str
    address: str | None  # with --backend ray: the cluster to join (None: a local instance)
    reference_dir: Path | None  # with --reproduce: the reference results the sample is checked against


def run(args: argparse.Namespace) -> int:
    # Everything the user could get wrong is checked here, before the first evaluation.
    plan = _plan(args)
    bar = ProgressBar("episodes")
    selected = _evaluate(args, plan, bar)
    if plan.reference_dir is not None:
        return _check_reproduction(plan, selected, bar)
    _write_table(plan, selected, bar)
    return 0


def _episodes(args: argparse.Namespace) -> int | None:
    """--episodes (or --quick's 5, --reproduce's sample, else None: the protocol's count of each environment), and
    the refusals of flags that --update-reference and --reproduce do not combine with."""
    episodes = int_flag("--episodes", args.episodes, 1, MAX_EPISODES)
    if args.reproduce:
        _refuse_with_reproduce(args)
        return episodes if episodes is not None else REPRODUCE_EPISODES
    if episodes is None and args.quick:
        episodes = 5
    if args.update_reference:
        if episodes is not None:
            raise CliError(
                "--update-reference writes the committed reference results, which use the protocol's episodes: "
                "do not combine it with --quick or --episodes"
            )
        if args.results_dir is not None or args.output is not None:
            raise CliError(
                f"--update-reference writes {REFERENCE_RESULTS_DIR} and {REFERENCE_TABLE}: "
                "do not combine it with --results-dir or --output"
            )
        if args.agents_dir is not None or args.policy:
            raise CliError(
                f"--update-reference evaluates the committed agents in {DEFAULT_AGENTS_DIR}: "
                "do not combine it with --agents-dir or --policy"
            )
        if not REFERENCE_RESULTS_DIR.is_dir():
            raise CliError(
                f"--update-reference: no {REFERENCE_RESULTS_DIR} directory here; run it from the repository root"
            )
    return episodes


def _refuse_with_reproduce(args: argparse.Namespace) -> None:
    """--reproduce re-runs the reference's own evaluations, its agents and nothing else."""
    for flag, given in [
        ("--update-reference", args.update_reference),
        ("--quick", args.quick),
        ("--agents-dir", args.agents_dir is not None),
        ("--policy", bool(args.policy)),
    ]:
        if given:
            raise CliError(
                f"--reproduce checks the committed reference with its own agents: do not combine it with {flag}"
            )


def _reference_dirs() -> tuple[Path, Path]:
    """The reference results --reproduce checks and the agents evaluated for them, from the same checkout."""
    from polyenvs.evaluation.agents import checkout_dirs

    candidates = list(zip(checkout_dirs(REFERENCE_RESULTS_DIR), checkout_dirs(DEFAULT_AGENTS_DIR), strict=True))
    for results, agents in candidates:
        if results.is_dir():
            return results, agents
    where = " or ".join(str(results.absolute()) for results, _ in candidates)
    raise CliError(
        f"--reproduce: no reference results ({where}); an installed package does not ship them: run it in a clone "
        "of the repository"
    )


def _outputs(args: argparse.Namespace) -> tuple[Path, Path]:
    """The results directory and the table: the committed ones with --update-reference."""
    if args.update_reference:
        return REFERENCE_RESULTS_DIR, REFERENCE_TABLE
    default_results = DEFAULT_LEADERBOARD_DIR / ("reproduce" if args.reproduce else "results")
    results_dir = Path(args.results_dir) if args.results_dir is not None else default_results
    output = Path(args.output) if args.output is not None else DEFAULT_LEADERBOARD_DIR / "LEADERBOARD.md"
    return results_dir, output


def _agents(args: argparse.Namespace) -> tuple[Path | None, list[Path]]:
    """The agents directory (None: none found) and the directories looked in."""
    from polyenvs.evaluation.agents import default_agents_dirs

    if args.agents_dir is not None:
        agents_dir, looked = Path(args.agents_dir), [Path(args.agents_dir)]
        if not agents_dir.is_dir():
            raise CliError(f"--agents-dir {agents_dir}: no such directory")
    elif args.update_reference:
        agents_dir, looked = DEFAULT_AGENTS_DIR, [DEFAULT_AGENTS_DIR]
    else:
        looked = default_agents_dirs()
        agents_dir = next((d for d in looked if d.is_dir()), None)
    return agents_dir, looked


def _plan(args: argparse.Namespace) -> _Plan:
    """Check every flag (CliError, one line) and say what is evaluated and where it is written."""
    from polyenvs.evaluation.agents import agents_line
    from polyenvs.evaluation.page import plot_path, profile_path

    episodes = _episodes(args)
    reference_dir = None
    if args.reproduce:
        reference_dir, agents_dir = _reference_dirs()
        looked = [agents_dir]
        agents_dir = agents_dir if agents_dir.is_dir() else None
    else:
        agents_dir, looked = _agents(args)
    workers = int_flag("--jobs", args.jobs, 1, MAX_JOBS) if args.jobs is not None else os.cpu_count() or 1
    check_backend(args.backend, args.address)
    results_dir, output = _outputs(args)
    rows = [row for row in REGISTRY if args.only is None or args.only in row.id]
    if not rows:
        raise CliError(f"--only: no environment id contains {args.only!r}; run 'polyenvs list' for the ids")
    missing = _missing_extras(rows)  # found now, not after the environments before them were evaluated
    if missing and (args.update_reference or len(missing) == len(rows)):
        why = "--update-reference evaluates every environment: " if args.update_reference else ""
        raise CliError(f"{why}{_missing_line(missing)}")
    env_ids = [row.id for row in rows if row.id not in missing]
    agents_found = agents_line(agents_dir, env_ids, looked)  # a malformed agent directory: one line, here
    check_writable_directory(results_dir, "--results-dir")
    check_output_file(output, "--output")
    if results_dir.absolute() == output.absolute():
        raise CliError(f"--output {output} is the results directory")
    for chart in [profile_path(output), *(plot_path(output, env_id) for env_id in env_ids)]:  # beside the table
        check_output_file(chart, "--output")
    if reference_dir is not None and results_dir.absolute() == reference_dir.absolute():
        raise CliError(f"--results-dir {results_dir} is the reference that --reproduce checks")
    workers = min(workers, MAX_JOBS)
    return _Plan(episodes, results_dir, output, agents_dir, env_ids, missing, agents_found, workers, args.backend,
                 args.address, reference_dir)  # fmt: skip


def _evaluate(args: argparse.Namespace, plan: _Plan, bar: ProgressBar) -> list[dict]:
    """Evaluate what ``plan`` says (reusing stored results unless --redo) on ``bar``, which it closes."""
    from polyenvs.evaluation.run import Listeners, run_leaderboard

    def on_plan(total: int) -> None:  # every check passed (the agents loaded too): say what is evaluated
        if plan.missing:
            bar.message(f"left out: {_missing_line(plan.missing)}")
        bar.message(plan.agents_found)
        if plan.backend == "ray":
            bar.message(f"evaluations on {backend_description(plan.backend, plan.workers, plan.address)}")
        bar.start(total)

    try:
        return run_leaderboard(
            plan.env_ids,
            plan.episodes,
            results_dir=plan.results_dir,
            redo=args.redo or args.update_reference,
            listeners=Listeners(progress=bar.message, on_plan=on_plan, on_episode=lambda _: bar.advance()),
            agents_dir=plan.agents_dir,
            extra_agents=args.policy or (),
            workers=plan.workers,
            backend=plan.backend,
            address=plan.address,
        )
    finally:
        bar.close()


def _write_table(plan: _Plan, selected: list[dict], bar: ProgressBar) -> None:
    """Write the table (and its plots) of ``selected`` and every other environment's stored results; print it."""
    from polyenvs.evaluation.results import stored_results
    from polyenvs.registry import ALL_IDS

    # The table shows every environment with results in the directory, not only the ones just evaluated.
    others = stored_results(
        [e for e in ALL_IDS if e not in plan.env_ids],
        plan.results_dir,
        progress=bar.message,
        agents_dir=plan.agents_dir,
    )
    _print_table(plan.output, selected + others, plan.results_dir, bar)


def _check_reproduction(plan: _Plan, sample: list[dict], bar: ProgressBar) -> int:
    """Compare ``sample`` with the reference, write and print the reference's table, say what differs: 1 if any
    episode does, else 0."""
    from polyenvs.evaluation.results import compare_with_reference, stored_results
    from polyenvs.registry import ALL_IDS

    assert plan.reference_dir is not None
    reference = stored_results(ALL_IDS, plan.reference_dir, progress=bar.message, agents_dir=plan.agents_dir)
    reproduction = compare_with_reference(sample, reference)
    _print_table(plan.output, reference, plan.reference_dir, bar)
    for line in reproduction.absent + reproduction.differ:
        print(line, file=sys.stderr)
    print(f"{reproduction.summary()} (sample in {plan.results_dir})", file=sys.stderr)
    return 1 if reproduction.differ else 0


def _print_table(output: Path, documents: list[dict], source: Path, bar: ProgressBar) -> None:
    """Write the table of ``documents`` to ``output`` with its charts beside it, and print it."""
    from polyenvs.evaluation.page import write_leaderboard
    from polyenvs.registry import ALL_IDS

    order = {env_id: i for i, env_id in enumerate(ALL_IDS)}
    documents = sorted(documents, key=lambda d: order[d["env_id"]])  # stable: policy order kept
    text = write_leaderboard(documents, output, progress=bar.message)
    print(text)
    charts = text.count("![")
    print(
        f"wrote {output} ({len(documents)} results from {source}) and {charts} chart"
        f"{'s' if charts != 1 else ''} beside it",
        file=sys.stderr,
    )


def _missing_extras(rows: list[EnvEntry | ParallelEnvEntry]) -> dict[str, str]:
    """The ids of the registry ``rows`` whose optional packages are not installed -> the extra that installs them."""
    from gymnasium.error import DependencyNotInstalled

    from polyenvs.errors import InputError
    from polyenvs.evaluation.episodes import make_env
    from polyenvs.evaluation.protocol import old_versions_quietly

    missing = {}
    for row in rows:
        if row.extra is None:
            continue
        try:
            with old_versions_quietly():
                make_env(row.id).close()
        except InputError as exc:
            if not isinstance(exc.__cause__, DependencyNotInstalled | ModuleNotFoundError):
                raise
            missing[row.id] = row.extra
    return missing


def _missing_line(missing: dict[str, str]) -> str:
    return (
        f"{', '.join(missing)} need{'s' if len(missing) == 1 else ''} packages that are not installed: "
        f"{install_hint(*dict.fromkeys(missing.values()))}"
    )
