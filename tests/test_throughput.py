"""Smoke tests for benchmarks/throughput.py: it runs and reports; timings are never asserted (shared, noisy CPUs)."""

from __future__ import annotations

import math

import gymnasium as gym

from benchmarks import throughput  # the repo root is on the path (pyproject: [tool.pytest.ini_options] pythonpath)


def test_measure_env_steps_on_cartpole_gives_a_positive_finite_rate() -> None:
    result = throughput.measure_env_steps(lambda: gym.make("CartPole-v1"), min_seconds=0.05, repeats=1)
    assert math.isfinite(result.steps_per_second) and result.steps_per_second > 0
    assert math.isfinite(result.us_per_step) and result.us_per_step > 0
    assert result.peak_memory_mb is not None and result.peak_memory_mb >= 0


def test_quick_main_prints_a_table_with_the_cartpole_peer(capsys) -> None:
    assert throughput.main(["--quick", "--no-write", "--no-training", "--only", "nothing-matches"]) == 0
    assert "CartPole-v1" in capsys.readouterr().out


def test_training_table_compares_with_ppo_on_cartpole() -> None:
    rows = [
        throughput.Measurement("CartPole-v1", "SB3 PPO", 1000.0, 1000.0, None),
        throughput.Measurement("polyenvs/BuckybotWallFollow-v0", "SB3 PPO", 700.0, 1e6 / 700.0, None),
    ]
    table = throughput.format_training_table(rows)
    assert "| polyenvs/BuckybotWallFollow-v0 |" in table and "0.70x" in table and "| no |" in table
