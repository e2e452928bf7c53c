"""The ``polyenvs localize`` subcommand: the localization benchmark.

``polyenvs localize [--estimator NAME ...] [--particles N] [--runs R] [--bumps K] [--map NAME] [--env ENV_ID]
[--env-kwargs JSON] [--estimator-kwargs JSON] [--policy NAME] [--seed S] [--out DIR] [--json]
[--progress/--no-progress]``

Rolls out ``R`` seeded logs of the cart (the paper's random bounce) until ``K`` bumps each, runs every estimator
on the same logs and prints the convergence table (median and quartiles of the position error after each bump,
heading error, failure rates); writes ``DIR/localization.json`` and the curves ``DIR/convergence.png`` (drawn
with matplotlib, the ``plots`` extra; without it the chart is left out and stderr says why). Every flag and the
output directory are checked before any work: a bad value raises
:class:`~polyenvs.errors.InputError`, which the command line prints as one line (exit 2).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from polyenvs.commands.flags import ProgressBar, add_progress_flag, int_flag, is_terminal, parse_json_object
from polyenvs.errors import InputError
from polyenvs.estimators import DEFAULT_ENV_ID
from polyenvs.files import check_writable_directory
from polyenvs.limits import MAX_BUMPS, MAX_PARTICLES, MAX_RUNS, MAX_SEED

__all__ = ["DEFAULT_ENV_ID", "add_parser", "run"]

#: Where ``polyenvs localize`` writes by default (gitignored, like every run's output).
DEFAULT_LOCALIZE_DIR = Path("runs/localize")
DEFAULT_ESTIMATORS = ("mcl", "dead_reckoning")


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``localize`` subcommand to an ``argparse`` subparsers object; ``args.func`` is :func:`run`."""
    p = subparsers.add_parser(
        "localize",
        help="score localizers on seeded bump-cart logs (error against the number of bumps)",
        description="The localization benchmark: roll out seeded logs of the bumper cart (random bounce), run each "
        "estimator on the same logs, and report the median and quartiles of the position and heading error after "
        "each bump and the failure rates (runs whose particle set emptied; runs that never came within 10 cm and "
        "30 deg). Writes DIR/localization.json and DIR/convergence.png (the chart needs matplotlib: the plots extra).",
    )
    p.add_argument(
        "--estimator",
        action="append",
        default=None,
        help="'mcl' (the paper's bump-space Monte Carlo localizer), 'dead_reckoning', or a user's 'module:Class'; "
        f"repeatable (default: {' and '.join(DEFAULT_ESTIMATORS)})",
    )
    p.add_argument(
        "--particles",
        default="1000",
        help=f"particles for sampling estimators, 10 to {MAX_PARTICLES} (mcl: at most 100000; default 1000)",
    )
    p.add_argument("--runs", default="100", help=f"seeded runs, 1 to {MAX_RUNS} (default 100)")
    p.add_argument("--bumps", default="15", help=f"bumps per run, 1 to {MAX_BUMPS} (default 15)")
    p.add_argument("--map", default=None, help="the environment's map (default: its own, the paper's arena)")
    p.add_argument(
        "--env", default=DEFAULT_ENV_ID, help=f"environment id producing the logs (default {DEFAULT_ENV_ID})"
    )
    p.add_argument("--env-kwargs", default="{}", help="JSON object of environment keyword arguments")
    p.add_argument("--estimator-kwargs", default="{}", help="JSON object of keyword arguments for every estimator")
    p.add_argument("--policy", default="paper", help="the logging policy (default 'paper': the random bounce)")
    p.add_argument("--seed", default="0", help=f"first seed, 0 to {MAX_SEED}; run r uses seed + r (default 0)")
    p.add_argument("--out", default=None, help=f"output directory (default {DEFAULT_LOCALIZE_DIR}/MAP)")
    p.add_argument("--json", action="store_true", help="print the JSON document instead of the table")
    add_progress_flag(p)
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``polyenvs localize`` for parsed ``args``; 0 when done."""
    from polyenvs.estimators import estimator_kwargs, estimators, make_estimator
    from polyenvs.evaluation.localization import CONVERGED_CM, CONVERGED_DEG, rollout_logs, score_estimator, summarize
    from polyenvs.evaluation.localization_report import convergence_table

    particles = int_flag("--particles", args.particles, 10, MAX_PARTICLES)
    runs = int_flag("--runs", args.runs, 1, MAX_RUNS)
    bumps = int_flag("--bumps", args.bumps, 1, MAX_BUMPS)
    seed = int_flag("--seed", args.seed, 0, MAX_SEED)
    env_kwargs = parse_json_object(args.env_kwargs, "--env-kwargs")
    if args.map is not None:
        env_kwargs["map"] = args.map
    shared_kwargs = parse_json_object(args.estimator_kwargs, "--estimator-kwargs")
    names = list(dict.fromkeys(args.estimator or estimators(args.env) or DEFAULT_ESTIMATORS))
    kwargs = {}
    for name in names:
        try:
            kwargs[name] = estimator_kwargs(name, {**shared_kwargs, "particles": particles}, args.env)
            make_estimator(name, args.env, **kwargs[name])  # parameters checked now, not after the rollouts
        except ValueError as exc:
            raise InputError(f"--estimator {name}: {exc}") from None
    map_name = env_kwargs.get("map", "paper") if isinstance(env_kwargs.get("map", "paper"), str) else "custom"
    out_dir = Path(args.out) if args.out is not None else DEFAULT_LOCALIZE_DIR / map_name
    check_writable_directory(out_dir, "--out")
    progress_on = args.progress if args.progress is not None else is_terminal(sys.stderr)

    bar = ProgressBar(unit="runs", enabled=progress_on)
    bar.start(runs * (1 + len(names)), label="logs")
    start = time.monotonic()
    context, logs = rollout_logs(args.env, runs, bumps, seed=seed, env_kwargs=env_kwargs, policy=args.policy,
                                 progress=bar)  # fmt: skip
    document = {
        "env_id": args.env,
        "env_kwargs": env_kwargs,
        "map": map_name,
        "policy": args.policy,
        "runs": runs,
        "bumps": bumps,
        "seed": seed,
        "converged_within": {"position_cm": CONVERGED_CM, "heading_deg": CONVERGED_DEG},
        "estimators": {},
    }
    for name in names:
        bar.label = name
        result = score_estimator(name, kwargs[name], context, logs, bumps, seed=seed, progress=bar, env_id=args.env)
        summary = summarize(result)
        summary["kwargs"] = kwargs[name]
        document["estimators"][name] = summary
    bar.close()
    document["wall_clock_s"] = round(time.monotonic() - start, 2)
    written = _write_outputs(document, out_dir)
    if args.json:
        print(json.dumps(document, indent=1))
    else:
        print(convergence_table(document))
        print(f"wrote {' and '.join(str(path) for path in written)}")
    return 0


def _write_outputs(document: dict, out_dir: Path) -> list[Path]:
    """Write ``localization.json`` and, with matplotlib, the chart ``convergence.png`` into ``out_dir``; without
    matplotlib say on stderr why the chart is left out (as the leaderboard does). Returns the paths written."""
    from polyenvs.evaluation import charts
    from polyenvs.evaluation.localization_report import convergence_plot
    from polyenvs.files import write_json_atomic

    written = [out_dir / "localization.json"]
    write_json_atomic(written[0], document)
    if charts.available():
        written.append(out_dir / "convergence.png")
        charts.save(convergence_plot(document), written[1])
    else:
        print(f"convergence chart left out: it needs matplotlib: {charts.INSTALL_HINT}", file=sys.stderr)
    return written
