"""Smoke tests for benchmarks/throughput.py: it runs and reports; timings are never asserted (shared, noisy CPUs)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import gymnasium as gym

# The benchmarks package lives at the repo root, which plain `pytest` (unlike `python -m pytest`) does not import from.
_REPO_ROOT = str(Path(__file__).resolve().parents[1])
if _REPO_ROOT not in sys.path:
    sys.path.insert(0, _REPO_ROOT)

from benchmarks import throughput


def test_measure_env_steps_on_cartpole_gives_a_positive_finite_rate() -> None:
    result = throughput.measure_env_steps(lambda: gym.make("CartPole-v1"), min_seconds=0.05, repeats=1)
    assert math.isfinite(result.steps_per_second) and result.steps_per_second > 0
    assert math.isfinite(result.us_per_step) and result.us_per_step > 0
    assert result.peak_memory_mb is not None and result.peak_memory_mb >= 0


def test_quick_main_prints_a_table_with_the_cartpole_peer(capsys) -> None:
    assert throughput.main(["--quick", "--no-write", "--only", "nothing-matches"]) == 0
    assert "CartPole-v1" in capsys.readouterr().out
