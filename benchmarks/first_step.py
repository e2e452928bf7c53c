"""Time to the first step: import, ``gym.make``, reset and one step in a fresh process, for one id per family.

Each id is timed in two fresh processes that share a numba cache directory which starts empty: the first compiles
the family's kernels and writes the cache, as the first run after an install does; the second finds the cache, and
is the figure the target (``SCALAR_TARGETS["first_step_s"]`` in ``benchmarks.targets``) applies to. The clock runs
inside each process from before ``import gymnasium`` to after the step, so the interpreter's own start-up is left
out. The id of a family is its first registry entry that no newer version supersedes.

``python -m benchmarks.first_step [--quick]`` prints :func:`section`, the Markdown that ``benchmarks.throughput``
puts in ``THROUGHPUT.md``; :func:`measure` is the importable form.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from benchmarks.targets import SCALAR_TARGETS

__all__ = ["FirstStep", "family_ids", "format_rows", "main", "measure", "section"]

_ROOT = Path(__file__).resolve().parents[1]
_TIMEOUT_S = 300  # a cold compilation on a loaded 2-core machine, with room to spare
_SCRIPT = """
import sys, time
start = time.perf_counter()
import gymnasium as gym
import polyenvs
env = gym.make(sys.argv[1])
env.reset(seed=0)
env.action_space.seed(0)
env.step(env.action_space.sample())
print(time.perf_counter() - start)
"""


@dataclass(frozen=True)
class FirstStep:
    """Seconds to the first step of ``env_id`` in a fresh process: with an empty numba cache, then with the cache."""

    env_id: str
    first_s: float
    cached_s: float


def family_ids() -> list[str]:
    """One Gymnasium id per family of the registry: its first entry that no newer version supersedes."""
    from polyenvs.registry import REGISTRY

    ids: dict[str, str] = {}
    for entry in REGISTRY:
        if entry.kind == "gymnasium" and entry.superseded_by is None:
            ids.setdefault(entry.family, entry.id)
    return list(ids.values())


def _seconds_to_first_step(env_id: str, cache_dir: str) -> float:
    """Run :data:`_SCRIPT` for ``env_id`` in a fresh interpreter with numba's cache in ``cache_dir``."""
    path = os.pathsep.join(filter(None, [str(_ROOT), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir, "PYTHONPATH": path}
    done = subprocess.run(
        [sys.executable, "-c", _SCRIPT, env_id],
        env=env,
        cwd=_ROOT,
        capture_output=True,
        text=True,
        timeout=_TIMEOUT_S,
        check=False,
    )
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"{env_id}: the fresh process failed ({last})")
    return float(done.stdout.strip().splitlines()[-1])


def measure(env_ids: list[str]) -> list[FirstStep]:
    """For each id, the seconds to its first step in a process with an empty numba cache, then in one with it."""
    rows = []
    for env_id in env_ids:
        with tempfile.TemporaryDirectory(prefix="polyenvs-numba-cache-") as cache_dir:
            first = _seconds_to_first_step(env_id, cache_dir)
            rows.append(FirstStep(env_id, first, _seconds_to_first_step(env_id, cache_dir)))
    return rows


def format_rows(rows: list[FirstStep]) -> str:
    """The Markdown section: each id's two figures, the second against its target."""
    target = SCALAR_TARGETS["first_step_s"]
    lines = [
        "## Time to the first step (`python -m benchmarks.first_step`)",
        "",
        "Import, `gym.make`, reset and one step in a fresh process, the clock started before `import gymnasium`:",
        "first with an empty numba cache (compilation, as after an install), then in a second process that finds",
        "the cache the first wrote.",
        "",
        "| id | empty numba cache, s | cache found, s |",
        "| --- | ---: | --- |",
    ]
    lines += [f"| {row.env_id} | {row.first_s:.2f} | {row.cached_s:.2f} {target.note(row.cached_s)} |" for row in rows]
    return "\n".join(lines)


def section(quick: bool = False) -> str:
    """The first-step part of ``THROUGHPUT.md`` (Markdown); ``quick`` times the first family's id only."""
    ids = family_ids()
    return format_rows(measure(ids[:1] if quick else ids))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the first family's id only")
    args = parser.parse_args(argv)
    print(section(args.quick))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
