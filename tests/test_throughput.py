"""Smoke tests for the throughput benchmark (benchmarks/): it runs and reports; timings are never asserted (shared,
noisy CPUs). The interleaving test runs on a fake clock, so its rates are exact."""

from __future__ import annotations

import functools
import math

import gymnasium as gym
import pytest

# The repo root is on the path (pyproject: [tool.pytest.ini_options] pythonpath).
from benchmarks import harness, report, targets, throughput
from benchmarks.harness import Measurement


def test_measure_env_steps_on_cartpole_gives_a_positive_finite_rate() -> None:
    result = harness.measure_env_steps(lambda: gym.make("CartPole-v1"), min_seconds=0.05, repeats=1)
    assert math.isfinite(result.steps_per_second) and result.steps_per_second > 0
    assert math.isfinite(result.us_per_step) and result.us_per_step > 0
    assert result.peak_memory_mb is not None and result.peak_memory_mb >= 0


def test_quick_main_prints_a_table_with_the_cartpole_peer(capsys) -> None:
    assert throughput.main(["--quick", "--no-write", "--no-training", "--only", "nothing-matches"]) == 0
    out = capsys.readouterr().out
    assert "| CartPole-v1 | `gym.make` (default wrappers) |" in out
    assert "nothing-matches" in out  # the note says that no id matched


def test_quick_main_writes_a_report_that_says_how_rows_were_interleaved(tmp_path, capsys) -> None:
    output = tmp_path / "THROUGHPUT.md"
    argv = ["--quick", "--no-training", "--only", "nothing-matches", "--output", str(output)]
    assert throughput.main(argv) == 0
    text = output.read_text(encoding="utf-8")
    assert text.startswith("# Throughput") and "interleaved round" in text and "same round" in text
    assert "Machine:" in text and "| CartPole-v1 |" in text


def test_training_table_compares_with_ppo_on_cartpole() -> None:
    rows = [
        Measurement("CartPole-v1", "SB3 PPO", 1000.0, 1000.0, None),
        Measurement("polyenvs/BuckybotWallFollow-v0", "SB3 PPO", 700.0, 1e6 / 700.0, None),
    ]
    table = report.format_training_table(rows)
    assert "| polyenvs/BuckybotWallFollow-v0 |" in table and "0.70x" in table and "| no |" in table


def test_table_checks_every_ratio_and_memory_budget_of_the_spec() -> None:
    rows = [
        Measurement("CartPole-v1", "make", 100_000.0, 10.0, 0.01),
        Measurement("MiniGrid-Empty-8x8-v0", "make", 5_000.0, 200.0, 0.02),
        Measurement("CartPole-v1", "vector", 8e6, 0.125, 0.3, vector=True),
        # 0.7x CartPole and 14x MiniGrid, but over the 5 MB budget.
        Measurement("polyenvs/BuckybotWallFollow-v0", "make", 70_000.0, 1e6 / 70_000, 6.0),
        # 0.1x CartPole's vector env: short of WallFollow's 0.15x, enough for Explore's 0.08x.
        Measurement("polyenvs/BuckybotWallFollow-v0", "vector", 8e5, 1.25, 50.0, vector=True),
        Measurement("polyenvs/BuckybotExplore-v0", "vector", 8e5, 1.25, 50.0, vector=True),
    ]
    lines = report.format_table(rows).splitlines()
    single, vector_wall_follow, vector_explore = lines[-3:]
    assert "0.70x" in single and "14.0x" in single and "< 5 MB" in single and "| no |" in single
    assert ">= 0.15x CartPole vector env" in vector_wall_follow and "| no |" in vector_wall_follow
    assert ">= 0.08x CartPole vector env" in vector_explore and "| yes |" in vector_explore
    buckybot = targets.target_for("polyenvs/BuckybotGoal-v0", targets.Kind.MAKE)
    assert buckybot is not None and buckybot.describe() == ">= 0.6x CartPole-v1, >= 10x MiniGrid, < 5 MB"


class _FakeClock:
    """Time that moves only when a fake env steps, by that env's cost times the load of the current round."""

    def __init__(self) -> None:
        self.now = 0.0
        self.load = 1.0

    def __call__(self) -> float:
        return self.now


class _FakeEnv:
    """A single env whose step costs ``cost`` fake seconds (scaled by the clock's load)."""

    def __init__(self, clock: _FakeClock, cost: float) -> None:
        self.clock, self.cost = clock, cost
        self.action_space = gym.spaces.Discrete(2)

    def reset(self, *, seed=None, options=None):
        return 0, {}

    def step(self, action):
        self.clock.now += self.cost * self.clock.load
        return 0, 0.0, False, False, {}

    def close(self) -> None:
        pass


def test_rounds_alternate_peers_and_ours_and_ratios_are_taken_per_round() -> None:
    clock = _FakeClock()
    costs = {"peer A": 1e-3, "ours A": 2e-3, "peer B": 1e-3, "ours B": 4e-3}

    def fake_case(name: str) -> harness.Case:
        make = functools.partial(_FakeEnv, clock, costs[name])
        return harness.env_case(name, "", make, min_seconds=0.5, clock=clock, measure_memory=False)

    cases = throughput.alternate([fake_case("peer A"), fake_case("peer B")], [fake_case("ours A"), fake_case("ours B")])
    assert [case.name for case in cases] == ["peer A", "ours A", "peer B", "ours B"]

    # The machine's load drifts from round to round: the rates follow it, the per-round ratios do not.
    loads = [1.0, 3.0, 2.0]
    timed: list[tuple[int, str]] = []

    def on_repeat(round_index: int, case: harness.Case, rate: float) -> None:
        timed.append((round_index, case.name))
        clock.load = loads[len(timed) // len(cases)] if len(timed) < len(cases) * len(loads) else 1.0

    rows = harness.measure_rounds(cases, repeats=3, on_repeat=on_repeat)

    # Every round times every row once, alternating; every other round runs backwards.
    assert timed == [
        (0, "peer A"), (0, "ours A"), (0, "peer B"), (0, "ours B"),
        (1, "ours B"), (1, "peer B"), (1, "ours A"), (1, "peer A"),
        (2, "peer A"), (2, "ours A"), (2, "peer B"), (2, "ours B"),
    ]  # fmt: skip
    by_name = {row.name: row for row in rows}
    peer_a, ours_a = by_name["peer A"], by_name["ours A"]
    assert len(ours_a.per_repeat) == 3 and ours_a.session == peer_a.session is not None
    assert ours_a.per_repeat == pytest.approx([500.0, 500.0 / 3, 250.0], rel=1e-6)
    assert ours_a.steps_per_second == pytest.approx(250.0, rel=1e-6)  # the median over the rounds
    assert harness.paired_ratio(ours_a, peer_a) == pytest.approx(0.5, rel=1e-6)
    assert harness.paired_ratio(by_name["ours B"], by_name["peer B"]) == pytest.approx(0.25, rel=1e-6)


def test_alternate_spreads_the_shorter_list_through_the_longer() -> None:
    peers = [harness.Case(f"peer {i}", "") for i in range(3)] + [harness.Case("absent", "", skip="skipped")]
    ours = [harness.Case(f"ours {i}", "") for i in range(6)]
    names = [case.name.split()[0] for case in throughput.alternate(peers, ours)]
    assert names == ["peer", "ours", "ours", "peer", "ours", "ours", "peer", "ours", "ours"]


def test_paired_ratio_is_the_median_of_per_round_ratios() -> None:
    peer = Measurement("peer", "", 200.0, 5e3, None, per_repeat=(100.0, 200.0, 300.0), session=7)
    row = Measurement("ours", "", 90.0, 1e4, None, per_repeat=(60.0, 100.0, 90.0), session=7)
    # Per round: 0.6, 0.5, 0.3 -> 0.5; the ratio of the medians would be 90 / 200 = 0.45.
    assert harness.paired_ratio(row, peer) == pytest.approx(0.5)
    unpaired = Measurement("ours", "", 90.0, 1e4, None, per_repeat=(60.0, 100.0, 90.0), session=8)
    assert harness.paired_ratio(unpaired, peer) == pytest.approx(0.45)
    assert harness.paired_ratio(harness.not_measured("x", "", "skipped"), peer) is None


def test_a_failing_row_is_reported_and_the_others_still_measured() -> None:
    def broken():
        raise RuntimeError("kernel exploded\nsecond line")

    cases = [
        harness.env_case("CartPole-v1", "", lambda: gym.make("CartPole-v1"), min_seconds=0.02, measure_memory=False),
        harness.env_case("broken", "", broken, min_seconds=0.02),
        harness.Case("absent", "", skip="skipped: absent not installed"),
    ]
    good, bad, skipped = harness.measure_rounds(cases, repeats=2)
    assert good.ok and len(good.per_repeat) == 2
    assert not bad.ok and bad.note == "error: RuntimeError: kernel exploded"
    assert not skipped.ok and skipped.note.startswith("skipped:")


def test_ppo_rows_include_the_native_adapter_and_dummy_vec_env_against_cartpole_at_8_envs() -> None:
    pytest.importorskip("stable_baselines3")
    from benchmarks import training

    wall_follow = "polyenvs/BuckybotWallFollow-v0"
    tiny = {"n_steps": 8, "batch_size": 32, "n_epochs": 1}  # tiny budgets: a smoke test, never a timing
    rows, notes = training.measure_training(
        [wall_follow], timesteps=16, repeats=1, vec_timesteps=64, vec_overrides=tiny
    )
    assert notes == []
    assert all(row.ok and math.isfinite(row.steps_per_second) and row.steps_per_second > 0 for row in rows)
    single = [(row.name, row.num_envs) for row in rows if not row.vector]
    assert single == [("CartPole-v1", 1), (wall_follow, 1)]
    vector = [(row.name, row.num_envs, row.setting.split(" via ")[1].split(",")[0]) for row in rows if row.vector]
    assert vector == [
        ("CartPole-v1", 8, "DummyVecEnv"),
        (wall_follow, 8, "native VecEnv adapter"),
        (wall_follow, 8, "DummyVecEnv"),
    ]
    assert len({row.session for row in rows}) == 1  # one session: every ratio pairs rounds
    table = report.format_training_table(rows).splitlines()
    # The 8-env rows take their ratio to the 8-env CartPole row, and are checked against the PPO target.
    assert all(">= 0.8x PPO on CartPole" in line for line in table if line.startswith(f"| {wall_follow} |"))
    assert sum(line.startswith("| CartPole-v1 |") and "| 1.00x |" in line for line in table) == 2


def test_time_to_beat_trains_in_chunks_and_compares_with_the_paper_on_the_same_seeds() -> None:
    pytest.importorskip("stable_baselines3")
    from benchmarks import time_to_beat

    tiny = {"n_steps": 8, "batch_size": 32, "n_epochs": 1}
    result = time_to_beat.time_to_beat(budget=128, chunk=64, episodes=2, overrides=tiny, stop_when_beaten=False)
    assert result.seeds == [1000, 1001]  # the published evaluation seeds
    assert [chunk.timesteps for chunk in result.chunks] == [64, 128]
    assert all(math.isfinite(chunk.ppo_iqm) and chunk.total_s >= chunk.train_s for chunk in result.chunks)
    assert math.isfinite(result.paper_iqm)
    text = time_to_beat.format_result(result)
    assert "| 128 |" in text and ("did not exceed" in text or "first exceeded" in text)
