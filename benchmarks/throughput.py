"""Environment throughput against peer environments, measured in interleaved rounds of one process run.

Every figure that matters is a ratio to a peer measured in the same run (CartPole-v1, its native vector env,
MiniGrid, PPO on CartPole), because these shared machines drift by up to 25%. See the performance spec
(``performance.md``) for the peers and the targets. The work is split by job:

- ``benchmarks.harness``: timing a step loop in interleaved rounds, peak memory, ``Measurement``;
- ``benchmarks.peers``: the peer environments and their adapters; ``benchmarks.ours``: our registry's ids;
- ``benchmarks.targets``: every target as data; ``benchmarks.training``: PPO timesteps/s;
- ``benchmarks.report``: the Markdown tables and the report; this module: :func:`run` and the command line;
- a family whose targets pair it with peers of its own (the cart's localizer, the swarms against mpe2 and VMAS,
  the beasts against Ant-v5 and raw ``mj_step``) has a module listed in :data:`FAMILY_BENCHMARKS` whose
  ``section(quick)`` times them in interleaved rounds of its own and returns its Markdown section of the report;
  ``benchmarks.first_step``, listed there too, times the first step of one id per family in fresh processes, and
  ``benchmarks.profiling`` profiles every targeted row (where the time of a step goes).

From the repo root::

    python -m benchmarks.throughput [--quick] [--only SUBSTRING] [--no-write] [--no-training] [--no-families]
                                    [--output PATH]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from benchmarks.harness import Case, Measurement, measure_rounds, not_measured
from benchmarks.ours import polyenvs_cases
from benchmarks.peers import peer_cases
from benchmarks.report import HowMeasured, format_notes, format_report, format_table, format_training_table
from benchmarks.training import measure_training

__all__ = ["FAMILY_BENCHMARKS", "BenchmarkRun", "alternate", "family_sections", "main", "run"]

DEFAULT_OUTPUT = Path(__file__).resolve().parent / "THROUGHPUT.md"
#: Benchmarks with sections of their own (families with peers of their own, the first step in a fresh process, where
#: the time of a step goes): modules with ``section(quick: bool) -> str``.
FAMILY_BENCHMARKS = (
    "benchmarks.bumper",
    "benchmarks.swarm",
    "benchmarks.beast",
    "benchmarks.first_step",
    "benchmarks.profiling",
)

# (seconds per repeat, rounds, PPO timesteps per round)
_FULL = (2.0, 3, 2048)
_QUICK = (0.15, 2, 512)


@dataclass
class BenchmarkRun:
    """What :func:`run` measured: the rows (peers first, then ours), notes, and the order of the first round."""

    rows: list[Measurement]
    notes: list[str] = field(default_factory=list)
    order: list[str] = field(default_factory=list)


def alternate(first: Sequence[Case], second: Sequence[Case]) -> list[Case]:
    """The cases to time, the two lists merged evenly (skipped cases dropped): ``a1 b1 a2 b2 ...`` for equal lengths,
    and the shorter list spread through the longer one otherwise (3 peers, 6 of ours: ``a1 b1 b2 a2 b3 b4 a3 ...``).
    """
    lists = [[case for case in cases if not case.skip] for cases in (first, second)]
    # Each case at its fraction of the way through its list; ties go to ``first``.
    placed = [
        (index / len(cases), which, case) for which, cases in enumerate(lists) for index, case in enumerate(cases)
    ]
    return [case for _, _, case in sorted(placed, key=lambda item: item[:2])]


def run(*, min_seconds: float = 2.0, repeats: int = 3, only: str | None = None, seed: int = 0) -> BenchmarkRun:
    """Measure the peers and our environments in interleaved rounds; rows are listed peers first, then ours."""
    peers = peer_cases(min_seconds=min_seconds, seed=seed)
    ours, notes = polyenvs_cases(only=only, min_seconds=min_seconds, seed=seed)
    timed = alternate(peers, ours)
    measured = dict(zip(map(id, timed), measure_rounds(timed, repeats=repeats), strict=True))
    listed = [*peers, *ours]
    rows = [
        measured[id(case)]
        if id(case) in measured
        else not_measured(case.name, case.setting, case.skip, vector=case.vector)
        for case in listed
    ]
    return BenchmarkRun(rows, notes, [_short_label(case) for case in timed])


def family_sections(quick: bool, notes: list[str]) -> list[str]:
    """Each family benchmark's Markdown section; one that fails becomes a note, and the others still run."""
    import importlib

    sections = []
    for name in FAMILY_BENCHMARKS:
        try:
            sections.append(importlib.import_module(name).section(quick))
        except Exception as exc:  # noqa: BLE001 - a broken family must not hide the rest
            notes.append(f"{name} failed: {type(exc).__name__}: {exc}")
    return sections


def _short_label(case: Case) -> str:
    name = case.name.removeprefix("polyenvs/")
    return f"{name} (vector)" if case.vector else name


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.throughput",
        description="Measure polyenvs environments against peer environments and write benchmarks/THROUGHPUT.md.",
    )
    parser.add_argument(
        "--quick", action="store_true", help=f"{_QUICK[0]:g} s x {_QUICK[1]} rounds per row instead of 2 s x 3"
    )
    parser.add_argument("--only", metavar="SUBSTRING", help="only our envs whose id contains SUBSTRING (peers always)")
    parser.add_argument("--no-write", action="store_true", help="print the tables without writing the report")
    parser.add_argument("--no-training", action="store_true", help="skip the PPO training-speed rows")
    parser.add_argument(
        "--no-families",
        action="store_true",
        help="skip the families' own sections (" + ", ".join(FAMILY_BENCHMARKS) + ")",
    )
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help=f"report path (default: {DEFAULT_OUTPUT})")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the Markdown tables and write the report; return the exit status."""
    args = _parser().parse_args(argv)
    min_seconds, repeats, ppo_timesteps = _QUICK if args.quick else _FULL
    try:
        result = run(min_seconds=min_seconds, repeats=repeats, only=args.only)
        notes = list(result.notes)
        training: list[Measurement] = []
        if not args.no_training:
            env_ids = [row.name for row in result.rows if row.name.startswith("polyenvs/") and not row.vector]
            training, training_notes = measure_training(env_ids, timesteps=ppo_timesteps, repeats=repeats)
            notes += training_notes
        sections = [] if args.no_families else family_sections(args.quick, notes)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130

    print(format_table(result.rows))
    if training:
        print()
        print(format_training_table(training))
    if notes:
        print()
        print(format_notes(notes))
    for section in sections:
        print()
        print(section)

    if not args.no_write:
        from polyenvs.files import write_text_atomic

        command = " ".join(["python -m benchmarks.throughput", *(sys.argv[1:] if argv is None else argv)])
        how = HowMeasured(command, min_seconds, repeats, result.order, quick=args.quick)
        report = format_report(result.rows, notes, how, training=training, sections=sections)
        try:
            write_text_atomic(args.output, report)
        except OSError as exc:
            print(f"error: could not write {args.output}: {exc.strerror or exc}", file=sys.stderr)
            return 1
        print(f"\nwrote {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
