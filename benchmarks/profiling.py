"""Where the time of a step goes: a cProfile of every row the throughput targets cover.

Each row (every polyenvs id through ``gym.make`` and its native vector env, as the main table builds them; the
swarms at 20 robots and the batched swarm, as ``benchmarks.swarm`` steps them; the bump-space localizer, as
``benchmarks.bumper`` times it) is warmed up, then stepped under ``cProfile`` for about a second. The section lists,
per row, the share of the profiled time spent in our code (``polyenvs``, ``baselines``: Python, and the compiled
numba kernels, which cProfile lists under their own names), in Gymnasium's and PettingZoo's wrappers and utilities,
in other C calls (NumPy's, MuJoCo's, the interpreter's builtins) and in other Python (NumPy's Python layer, for
instance), and the functions with the most own time.

cProfile adds a few hundred nanoseconds to every Python call, so Python-heavy rows look slower under it than in the
main table: the µs column is the profiled figure, not the timed one, and the shares overstate Python's part.
"""

from __future__ import annotations

import cProfile
import pstats
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from benchmarks.harness import one_line, progress, run_steps

__all__ = ["Profile", "format_section", "profile_work", "section"]

#: Profiled seconds per row (after an untimed warm-up), and in quick mode.
ROW_SECONDS = 1.0
QUICK_ROW_SECONDS = 0.2
#: Functions listed per row, by own time.
TOP_FUNCTIONS = 3
#: Where a function's file says which part of the stack it belongs to (the first match wins).
_PARTS = (
    ("ours", ("/polyenvs/", "/baselines/")),
    ("wrappers", ("/gymnasium/", "/pettingzoo/")),
)


@dataclass(frozen=True)
class Profile:
    """One row's profile: the units of work done (steps, env-steps, updates), the profiled seconds, the share of
    them per part of the stack, and the functions with the most own time as (label, share)."""

    units: int
    seconds: float
    parts: dict[str, float]
    top: list[tuple[str, float]]

    @property
    def us_per_unit(self) -> float:
        return 1e6 * self.seconds / max(self.units, 1)


def _part(filename: str, name: str) -> str:
    if filename == "~":  # cProfile's file name for C functions; our kernels compiled ahead of the call are among them
        return "ours" if "polyenvs." in name or "baselines." in name else "c"
    for part, markers in _PARTS:
        if any(marker in filename for marker in markers):
            return part
    return "other"


def _label(filename: str, name: str) -> str:
    """``module/file.py:function`` from the package down, or the C function's name."""
    if filename == "~":
        return name.strip("<>")
    for root in ("/polyenvs/", "/baselines/", "/gymnasium/", "/pettingzoo/", "/numpy/", "/benchmarks/"):
        if root in filename:
            return root.strip("/") + "/" + filename.split(root, 1)[1] + ":" + name
    return filename.rsplit("/", 1)[-1] + ":" + name


def profile_work(work: Callable[[], int], seconds: float) -> Profile:
    """Call ``work()`` (which returns the units of work it did) under cProfile until ``seconds`` have passed."""
    work()  # untimed: compilation, caches, lazy setup
    profiler = cProfile.Profile()
    units, start = 0, time.perf_counter()
    profiler.enable()
    while time.perf_counter() - start < seconds:
        units += work()
    profiler.disable()
    stats = pstats.Stats(profiler).stats  # (file, line, name) -> (calls, primitive calls, own time, cumulative, ...)
    own = {
        key: value[2] for key, value in stats.items() if key[2] != "<method 'disable' of '_lsprof.Profiler' objects>"
    }
    total = sum(own.values()) or 1.0
    parts = dict.fromkeys(("ours", "wrappers", "c", "other"), 0.0)
    for (filename, _, name), seconds_own in own.items():
        parts[_part(filename, name)] += seconds_own / total
    top = sorted(own.items(), key=lambda item: -item[1])[:TOP_FUNCTIONS]
    return Profile(units, total, parts, [(_label(key[0], key[2]), value / total) for key, value in top])


def _env_work(env, vector: bool, seed: int = 0) -> Callable[[], int]:
    """Steps of ``env`` with a block of pre-sampled actions per call (resetting a single env at episode ends)."""
    env.reset(seed=seed)
    env.action_space.seed(seed)
    num_envs = getattr(env, "num_envs", 1)
    block = [env.action_space.sample() for _ in range(max(1, 256 // num_envs))]

    def work() -> int:
        run_steps(env, block, vector)
        return len(block) * num_envs

    return work


def _rows() -> list[tuple[str, Callable[[], Callable[[], int]]]]:
    """(row label, a builder of its work function) for every profiled row."""
    import gymnasium as gym

    import polyenvs  # noqa: F401 - registers the ids
    from benchmarks import bumper, swarm
    from benchmarks.peers import VECTOR_NUM_ENVS
    from polyenvs.registry import REGISTRY

    rows: list[tuple[str, Callable[[], Callable[[], int]]]] = []
    for entry in REGISTRY:
        if entry.kind != "gymnasium":
            continue
        rows.append((f"{entry.id} `gym.make`", lambda i=entry.id: _env_work(gym.make(i), vector=False)))
        if entry.vector_entry_point:
            make_vec = lambda i=entry.id: gym.make_vec(  # noqa: E731
                i, num_envs=VECTOR_NUM_ENVS, vectorization_mode="vector_entry_point"
            )
            rows.append((f"{entry.id} vector x{VECTOR_NUM_ENVS}", lambda m=make_vec: _env_work(m(), vector=True)))
    for task in swarm.TASKS:
        rows.append(
            (
                f"swarm {task} N=20 (joint steps)",
                lambda t=task: _joint_steps(swarm.swarm_stepper(swarm.swarm_env(t, 20))),
            )
        )
    rows.append(
        ("batched obstacle_field_v0 1024x4", lambda: _vector_steps(swarm.batched_stepper("obstacle_field_v0", 1024, 4)))
    )
    rows.append((f"BumpSpaceMCL {bumper.PARTICLES} particles (updates)", _localizer_work))
    return rows


def _joint_steps(steps: Callable[[int], int]) -> Callable[[], int]:
    def work() -> int:
        steps(16)
        return 16

    return work


def _vector_steps(steps: Callable[[int], int]) -> Callable[[], int]:
    return lambda: steps(1)


def _localizer_work() -> Callable[[], int]:
    from benchmarks.bumper import LocalizerRunner

    runner = LocalizerRunner(min_seconds=ROW_SECONDS)  # only its logs and filter are used: the profile times itself
    runner.warm_up()
    logs = runner.logs[1]

    def work() -> int:
        runner.mcl.reset(runner.context, np.zeros(3), np.random.default_rng(0))
        for log in logs:
            runner.mcl.update(log)
        return len(logs)

    return work


def measure(seconds: float = ROW_SECONDS) -> list[tuple[str, Profile | str]]:
    """Every row's :class:`Profile`, or a one-line error for a row that failed."""
    results: list[tuple[str, Profile | str]] = []
    for label, build in _rows():
        progress(f"profiling {label} ...")
        try:
            results.append((label, profile_work(build(), seconds)))
        except Exception as exc:  # noqa: BLE001 - a broken row must not hide the others
            results.append((label, f"error: {one_line(exc)}"))
    return results


def format_section(results: list[tuple[str, Profile | str]]) -> str:
    """The profiles as the Markdown section of ``THROUGHPUT.md``."""
    lines = [
        "## Where the time goes (`python -m benchmarks.profiling`)",
        "",
        "Each row stepped under cProfile for about a second after a warm-up. Shares of the profiled time: our code"
        " (`polyenvs`, `baselines`: Python and compiled numba kernels), Gymnasium's and PettingZoo's wrappers, other C"
        " calls (NumPy, MuJoCo, builtins), other Python (NumPy's Python layer, ...); then the functions with the most"
        " own time. µs per unit is the profiled figure (cProfile slows every Python call, so Python-heavy rows look"
        " slower than in the tables above and the shares overstate Python), not the timed one.",
        "",
        "| row | µs per unit (profiled) | ours | wrappers | C | other | most own time |",
        "| --- | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for label, result in results:
        if isinstance(result, str):
            lines.append(f"| {label} | - | - | - | - | - | {result} |")
            continue
        shares = " | ".join(f"{100 * result.parts[part]:.0f}%" for part in ("ours", "wrappers", "c", "other"))
        top = ", ".join(f"`{name}` {100 * share:.0f}%" for name, share in result.top)
        lines.append(f"| {label} | {result.us_per_unit:,.1f} | {shares} | {top} |")
    return "\n".join(lines) + "\n"


def section(quick: bool = False) -> str:
    """This benchmark's part of ``THROUGHPUT.md``."""
    return format_section(measure(QUICK_ROW_SECONDS if quick else ROW_SECONDS))


def main(argv: list[str] | None = None) -> int:
    import argparse

    parser = argparse.ArgumentParser(prog="python -m benchmarks.profiling", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--quick", action="store_true", help=f"{QUICK_ROW_SECONDS:g} s per row instead of {ROW_SECONDS:g}"
    )
    args = parser.parse_args(argv)
    print(section(args.quick))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
