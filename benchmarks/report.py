"""The Markdown tables and the THROUGHPUT.md report: how the numbers were made, the machine, the rows, the notes."""

from __future__ import annotations

import importlib.metadata
import math
import os
import platform
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime

from benchmarks.harness import MEMORY_STEPS_SINGLE, MEMORY_STEPS_VECTOR, Measurement, paired_ratio
from benchmarks.peers import CARTPOLE, MINIGRID, VECTOR_NUM_ENVS
from benchmarks.targets import Kind, Target, target_for

__all__ = ["HowMeasured", "format_notes", "format_report", "format_table", "format_training_table", "reference"]


@dataclass(frozen=True)
class HowMeasured:
    """How a report's numbers were made: the ``command`` that ran, each row's ``min_seconds`` per round over
    ``repeats`` rounds in the first round's ``order`` (the timed rows' labels), whether in ``quick`` mode, and when
    (``date``, by default now)."""

    command: str
    min_seconds: float
    repeats: int
    order: Sequence[str]
    quick: bool = False
    date: datetime = field(default_factory=lambda: datetime.now(UTC))


def reference(rows: Sequence[Measurement], name: str, vector: bool) -> Measurement | None:
    """The measured row called ``name`` of the given kind (the peer a ratio is taken against), or ``None``."""
    return next((row for row in rows if row.name == name and row.vector == vector and row.ok), None)


def _row_ratio(rows: Sequence[Measurement], row: Measurement, peer: str) -> float | None:
    return paired_ratio(row, reference(rows, peer, row.vector))


def _verdict(rows: Sequence[Measurement], row: Measurement, target: Target | None, memory_mb: float | None) -> str:
    if target is None:
        return ""
    return target.verdict({ratio.peer: _row_ratio(rows, row, ratio.peer) for ratio in target.ratios}, memory_mb)


def format_table(rows: Sequence[Measurement]) -> str:
    """The step rows as a Markdown table, with ratios to the peers measured in the same rounds."""
    lines = [
        "| name | setting | steps/s | µs/step | vs CartPole | vs MiniGrid | peak MB | target | meets target | note |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | --- | --- | --- |",
    ]
    for row in rows:
        target = target_for(row.name, Kind.VECTOR if row.vector else Kind.MAKE)
        cells = [
            row.name,
            row.setting,
            _fmt_rate(row.steps_per_second),
            _fmt_us(row.us_per_step),
            _fmt_ratio(_row_ratio(rows, row, CARTPOLE)),
            "" if row.vector else _fmt_ratio(_row_ratio(rows, row, MINIGRID)),
            "" if row.peak_memory_mb is None else f"{row.peak_memory_mb:.2f}",
            "" if target is None else target.describe(),
            _verdict(rows, row, target, row.peak_memory_mb),
            row.note,
        ]
        lines.append(_table_line(cells))
    return "\n".join(lines)


def format_training_table(rows: Sequence[Measurement]) -> str:
    """PPO timesteps/s per environment and the ratio to PPO on CartPole-v1 in the same rounds."""
    lines = [
        "| name | setting | timesteps/s | vs PPO on CartPole | target | meets target | note |",
        "| --- | --- | ---: | ---: | --- | --- | --- |",
    ]
    for row in rows:
        target = target_for(row.name, Kind.PPO)
        cells = [
            row.name,
            row.setting,
            _fmt_rate(row.steps_per_second),
            _fmt_ratio(_row_ratio(rows, row, CARTPOLE)),
            "" if target is None else target.describe(),
            _verdict(rows, row, target, None),
            row.note,
        ]
        lines.append(_table_line(cells))
    return "\n".join(lines)


def format_notes(notes: Sequence[str]) -> str:
    """General notes (a broken import, an ``--only`` that matched nothing) as a Markdown list."""
    return "\n".join(f"- {note}" for note in notes)


def format_report(
    rows: Sequence[Measurement],
    notes: Sequence[str],
    how: HowMeasured,
    *,
    training: Sequence[Measurement] = (),
    sections: Sequence[str] = (),
) -> str:
    """The whole THROUGHPUT.md: how the numbers were made, the machine, the tables and the notes.

    ``sections`` are the families' own Markdown sections (each with its peers, timed in rounds of its own),
    appended at the end.
    """
    text = _preamble(how) + format_table(rows) + "\n"
    if training:
        text += (
            "\n## Training speed\n\nPPO timesteps per second (rollouts and gradient epochs, after a one-rollout"
            f" warm-up), in {_rounds(how.repeats)} with PPO on CartPole-v1 (the ratio is the median of"
            " per-round ratios): the environment should never be the bottleneck.\n\n"
        )
        text += format_training_table(training) + "\n"
    if notes:
        text += "\nNotes:\n\n" + format_notes(notes) + "\n"
    for section in sections:
        text += "\n" + section.rstrip("\n") + "\n"
    return text


def _rounds(repeats: int) -> str:
    return f"{repeats} interleaved round{'' if repeats == 1 else 's'}"


def _preamble(how: HowMeasured) -> str:
    """The report's title, how the numbers were made, and the machine."""
    mode = " **Quick mode**: too short to be more than a smoke test." if how.quick else ""
    order_text = ", ".join(how.order) if how.order else "(no row was timed)"
    return f"""# Throughput

Written by `{how.command}` on {how.date:%Y-%m-%d %H:%M} UTC; rerun it rather than editing this file.{mode}

How the numbers were made:

- All rows in one process run, measured in {_rounds(how.repeats)} after an untimed warm-up of every row
  (numba compilation, lazy setup): each round times every row once for at least {how.min_seconds:g} s, peers and ours
  alternating, in this order (reversed every other round, so that no row is always early or late in a round):
  {order_text}.
- steps/s is a row's median over the rounds. Each ratio is the median over the rounds of the row's rate divided by
  its peer's rate in the same round, so that load drift between rounds cancels out of the ratios.
- Random actions from each environment's own action space (seeded), pre-sampled in blocks before each repeat so that
  sampling stays outside the timed loop; resets on terminated or truncated are included in the timing (vector envs
  reset themselves).
- µs/step is 1e6 / steps/s. Vector rows count env-steps: vector steps x the number of envs.
- Compare ratios, not absolute figures: these machines are shared and drift by up to 25% between runs. "vs CartPole"
  is the ratio to `{CARTPOLE}` via `gym.make` for single-env rows, to CartPole's native vector env
  ({VECTOR_NUM_ENVS} envs) for vector rows; "vs MiniGrid" is the ratio to `{MINIGRID}`.
- Peak MB: the peak of tracemalloc-traced allocations while building the env, resetting it and taking
  {MEMORY_STEPS_SINGLE} steps ({MEMORY_STEPS_VECTOR} for vector envs), in a separate untimed run after the rounds.
  Memory allocated outside Python's allocator (MuJoCo's, torch's) is not seen.
- Targets are those of `benchmarks/targets.py` (issue 19's table, with the spec's memory budgets); "meets target"
  checks every ratio and memory budget of the target, and names any that could not be measured in this run.

Machine: {platform.platform()}, {_cpu_model()}, {os.cpu_count()} CPUs; Python {platform.python_version()};
{_versions()}.

"""


# ---------------------------------------------------------------------------------------------------- cells


def _table_line(cells: Sequence[str]) -> str:
    return "| " + " | ".join(cell.replace("|", "\\|").replace("\n", " ") for cell in cells) + " |"


def _fmt_rate(value: float) -> str:
    return f"{value:,.0f}" if math.isfinite(value) else "—"


def _fmt_us(value: float) -> str:
    if not math.isfinite(value):
        return "—"
    for limit, digits in ((100, 0), (10, 1), (1, 2)):
        if value >= limit:
            return f"{value:.{digits}f}"
    return f"{value:.3f}"


def _fmt_ratio(value: float | None) -> str:
    if value is None:
        return ""
    for limit, digits in ((100, 0), (10, 1), (0.01, 2)):
        if value >= limit:
            return f"{value:.{digits}f}x"
    return f"{value:.4f}x"


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _versions() -> str:
    names = (
        "numpy",
        "numba",
        "gymnasium",
        "minigrid",
        "mujoco",
        "pettingzoo",
        "mpe2",
        "vmas",
        "torch",
        "stable-baselines3",
    )
    found = []
    for name in names:
        try:
            found.append(f"{name} {importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            continue
    return ", ".join(found)
