"""Smoke tests for the throughput benchmark (benchmarks/): it runs and reports; timings are never asserted (shared,
noisy CPUs). The interleaving test runs on a fake clock, so its rates are exact."""

from __future__ import annotations

import functools
import math

import gymnasium as gym
import pytest

# The repo root is on the path (pyproject: [tool.pytest.ini_options] pythonpath).
from benchmarks import harness, peers, report, targets, throughput
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
    assert "## Time to the first step" in text and "(target <= 1 s: " in text  # benchmarks.first_step's section
    assert "## Where the time goes" in text and "| polyenvs/BuckybotGoal-v0 `gym.make` |" in text  # profiling's


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
        # 1.1x CartPole and 22x MiniGrid, but over the 5 MB budget.
        Measurement("polyenvs/BuckybotWallFollow-v0", "make", 110_000.0, 1e6 / 110_000, 6.0),
        # 0.2x CartPole's vector env: short of WallFollow's 0.35x, enough for Explore's 0.15x.
        Measurement("polyenvs/BuckybotWallFollow-v0", "vector", 1.6e6, 0.625, 50.0, vector=True),
        Measurement("polyenvs/BuckybotExplore-v0", "vector", 1.6e6, 0.625, 50.0, vector=True),
        # Localize's gym.make row has a memory budget only: its verdict is on memory and says so.
        Measurement("polyenvs/BumperCartLocalize-v0", "make", 10_000.0, 100.0, 1.0),
    ]
    lines = report.format_table(rows).splitlines()
    single, vector_wall_follow, vector_explore, localize = lines[-4:]
    assert "1.10x" in single and "22.0x" in single and "< 5 MB" in single and "| no |" in single
    assert ">= 0.35x CartPole vector env" in vector_wall_follow and "| no |" in vector_wall_follow
    assert ">= 0.15x CartPole vector env" in vector_explore and "| yes |" in vector_explore
    assert "| < 5 MB, rate: see the localizer's updates/s | yes (memory only) |" in localize
    buckybot = targets.target_for("polyenvs/BuckybotGoal-v0", targets.Kind.MAKE)
    assert buckybot is not None and buckybot.describe() == ">= 1x CartPole-v1, >= 10x MiniGrid, < 5 MB"


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
    assert all(">= 1x PPO on CartPole" in line for line in table if line.startswith(f"| {wall_follow} |"))
    assert sum(line.startswith("| CartPole-v1 |") and "| 1.00x |" in line for line in table) == 2


def test_time_to_beat_trains_in_chunks_and_compares_with_the_paper_on_the_same_seeds() -> None:
    pytest.importorskip("stable_baselines3")
    from benchmarks import time_to_beat

    tiny = {"n_steps": 8, "batch_size": 32, "n_epochs": 1}
    race = time_to_beat.Race(budget=128, chunk=64, episodes=2, overrides=tiny, stop_when_beaten=False)
    result = time_to_beat.time_to_beat(race)
    assert result.seeds == [1000, 1001]  # the published evaluation seeds
    assert [chunk.timesteps for chunk in result.chunks] == [64, 128]
    assert all(math.isfinite(chunk.ppo_iqm) and chunk.total_s >= chunk.train_s for chunk in result.chunks)
    assert math.isfinite(result.paper_iqm)
    text = time_to_beat.format_result(result)
    assert "| 128 |" in text and ("did not exceed" in text or "first exceeded" in text)


# ------------------------------------------------------------------------- issue 33's targets, in one place

_BUCKYBOT = ("polyenvs/BuckybotWallFollow-v0", "polyenvs/BuckybotGoal-v0", "polyenvs/BuckybotExplore-v0")
_CART_EXPLORE = ("polyenvs/BumperCartExplore-v0", "polyenvs/BumperCartExplore-v1", "polyenvs/BumperCartExplore-v2")
_BEASTS = tuple(f"polyenvs/Beast{task}-v{v}" for task in ("Tumble", "Roll", "Turn", "Recover") for v in (0, 1))
_MAKE, _VECTOR = targets.Kind.MAKE, targets.Kind.VECTOR
# (ids, kind, {peer: minimum ratio}, memory budget in MB): issue 33's table, with the spec's budgets it keeps.
_RATIO_TARGETS = [
    (_BUCKYBOT, _MAKE, {peers.CARTPOLE: 1.0, peers.MINIGRID: 10.0}, 5.0),
    (_BUCKYBOT[:2], _VECTOR, {peers.CARTPOLE: 0.35}, 200.0),
    (_BUCKYBOT[2:], _VECTOR, {peers.CARTPOLE: 0.15}, 200.0),
    (_CART_EXPLORE, _MAKE, {peers.CARTPOLE: 0.6}, 5.0),
    (("polyenvs/BumperCartLocalize-v0",), _MAKE, {}, 5.0),
    (_CART_EXPLORE, _VECTOR, {peers.CARTPOLE: 0.06}, None),
    (("polyenvs/APLiteCorridor-v0", "polyenvs/APLiteObstacleField-v0"), _MAKE, {peers.CARTPOLE: 0.4}, None),
    (_BEASTS, _MAKE, {peers.ANT: 1.0}, None),
]
_AT_LEAST, _AT_MOST, _BELOW = targets.Direction.AT_LEAST, targets.Direction.AT_MOST, targets.Direction.BELOW
_SCALAR_TARGETS = [
    ("swarm_vs_mpe2_at_20", 100.0, _AT_LEAST),
    ("swarm_joint_steps_per_s_at_256", 200.0, _AT_LEAST),
    ("swarm_memory_mb_at_256", 50.0, _BELOW),
    ("batched_swarm_vs_vmas", 4.0, _AT_LEAST),
    ("beast_vs_raw_mj_step", 1.10, _AT_MOST),
    ("beast_vector_vs_single", 1.7, _AT_LEAST),
    ("localizer_updates_per_s", 20_000.0, _AT_LEAST),
    ("first_step_s", 1.0, _AT_MOST),
]


@pytest.mark.parametrize(("ids", "kind", "minimums", "memory_mb"), _RATIO_TARGETS)
def test_every_ratio_target_of_issue_33_applies_to_its_ids(ids, kind, minimums, memory_mb) -> None:
    for env_id in ids:
        target = targets.target_for(env_id, kind)
        assert target is not None, env_id
        assert {ratio.peer: ratio.minimum for ratio in target.ratios} == minimums, env_id
        assert target.max_memory_mb == memory_mb, env_id


def test_ppo_through_the_native_adapter_targets_1x_ppo_on_cartpole_on_every_id_but_localize() -> None:
    from polyenvs.registry import REGISTRY

    ids = [entry.id for entry in REGISTRY if entry.kind == "gymnasium"]
    assert "polyenvs/BumperCartLocalize-v0" in ids
    for env_id in ids:
        target = targets.target_for(env_id, targets.Kind.PPO)
        minimum = 0.8 if "Localize" in env_id else 1.0  # a localizer update over 1,000 particles every step
        assert target is not None and [(r.peer, r.minimum) for r in target.ratios] == [(peers.CARTPOLE, minimum)]


@pytest.mark.parametrize(("name", "value", "direction"), _SCALAR_TARGETS)
def test_every_scalar_target_of_issue_33_has_its_value_and_direction(name, value, direction) -> None:
    bound = targets.SCALAR_TARGETS[name]
    assert (bound.value, bound.direction) == (value, direction)


def test_a_bound_prints_itself_and_checks_its_direction() -> None:
    at_least, at_most, below = targets.Bound(20_000.0), targets.Bound(1.03, _AT_MOST, "x"), targets.Bound(50, _BELOW)
    assert at_least.note() == "(target >= 20,000)" and at_least.note(19_999.0) == "(target >= 20,000: missed)"
    assert at_least.met_by(20_000.0) and not at_least.met_by(19_999.0)
    assert at_most.note(1.03) == "(target <= 1.03x: met)" and not at_most.met_by(1.04)
    assert not below.met_by(50.0) and below.met_by(49.9)


def test_a_memory_only_target_says_yes_or_no_on_memory_alone() -> None:
    localize = targets.target_for("polyenvs/BumperCartLocalize-v0", targets.Kind.MAKE)
    assert localize is not None and localize.ratios == ()
    assert localize.verdict({}, 4.9) == "yes (memory only)"
    assert localize.verdict({peers.CARTPOLE: 0.01}, 5.0) == "no (memory only)"
    assert localize.verdict({}, None) == ""  # nothing checked: blank, never a bare yes


def test_family_modules_print_the_targets_of_targets_py(monkeypatch) -> None:
    from benchmarks import beast, bumper, first_step, swarm

    scalars = {
        "localizer_updates_per_s": targets.Bound(12_345.0),
        "beast_vs_raw_mj_step": targets.Bound(1.234, _AT_MOST, "x"),
        "swarm_vs_mpe2_at_20": targets.Bound(123.0, unit="x"),
        "swarm_joint_steps_per_s_at_256": targets.Bound(234.0),
        "swarm_memory_mb_at_256": targets.Bound(34.5, _BELOW, " MB"),
        "batched_swarm_vs_vmas": targets.Bound(4.5, unit="x"),
        "first_step_s": targets.Bound(0.75, _AT_MOST, " s"),
    }
    for name, bound in scalars.items():
        monkeypatch.setitem(targets.SCALAR_TARGETS, name, bound)
    cart = targets.Target("polyenvs/BumperCart", _MAKE, (targets.Ratio(peers.CARTPOLE, 0.55, "CartPole-v1"),))
    beasts = targets.Target("polyenvs/Beast", _MAKE, (targets.Ratio(peers.ANT, 1.5, "Ant-v5"),))
    monkeypatch.setattr(targets, "TARGETS", (cart, beasts))

    cart_line, localizer_line = bumper.target_lines({"cycles_vs_cartpole": 0.6, "localizer_updates_per_s": 12_000.0})
    assert cart_line.endswith("0.60x (target >= 0.55x: met)")
    assert localizer_line.endswith("12,000 (target >= 12,345: missed)")
    note = beast.overhead_note("polyenvs/BeastRoll-v1", 5000.0, 1.2, 1.4)
    assert (
        "1.200x the raw mj_step (target <= 1.234x: met)" in note
        and "1.40x Ant-v5's steps/s (target >= 1.5x: missed)" in note
    )
    rows = [
        {"row": "corridor_v0 N=20", "joint_steps_per_s": 10.0, "agent_steps_per_s": 200.0, "ratio_vs_mpe2": 130.0},
        {"row": "corridor_v0 N=256", "joint_steps_per_s": 230.0, "agent_steps_per_s": 1.0, "peak_memory_mb": 30.0},
        {"row": "batched", "env_steps_per_s": 1e6, "ratio_vs_vmas": 5.0, "peak_memory_mb": 40.0},
    ]
    table = swarm.format_rows(rows)
    for text in ("130.0x mpe2 (target >= 123x: met)", "230 joint steps/s (target >= 234: missed)",
                 "30.0 (target < 34.5 MB: met)", "5.00x VMAS (target >= 4.5x: met) | 40.0 |"):  # fmt: skip
        assert text in table, text
    first = first_step.format_rows([first_step.FirstStep("polyenvs/BuckybotGoal-v0", 4.0, 0.8)])
    assert "| polyenvs/BuckybotGoal-v0 | 4.00 | 0.80 (target <= 0.75 s: missed) |" in first


def test_no_module_of_benchmarks_writes_a_target_of_its_own() -> None:
    import re
    from pathlib import Path

    # A target stated anywhere but targets.py: "target >= 0.1x", "(target <= 1.15)", "target < 50".
    literal = re.compile(r"target\s*[<>]=?\s*[\d.,]+")
    folder = Path(targets.__file__).parent
    found = [
        f"{path.name}: {match.group()}"
        for path in sorted(folder.glob("*.py"))
        if path.name != "targets.py"
        for match in literal.finditer(path.read_text(encoding="utf-8"))
    ]
    assert found == []


def _busy() -> int:
    total = 0
    for i in range(20_000):
        total += i * i
    return total


def test_a_profile_names_the_function_that_takes_the_time_and_where_it_lives() -> None:
    from benchmarks import profiling

    profile = profiling.profile_work(lambda: (_busy(), len("x"))[1], seconds=0.2)
    assert profile.units >= 1 and profile.us_per_unit > 0
    assert abs(sum(profile.parts.values()) - 1.0) < 1e-9
    (name, share), *_ = profile.top
    assert name.endswith("test_throughput.py:_busy") and share > 0.8  # the loop, not len() or the lambda
    # Our compiled kernels are C functions to cProfile, but they are our code; MuJoCo's are not.
    assert profiling._part("~", "<built-in method polyenvs.buckybot.goal._step_kernel>") == "ours"
    assert profiling._part("~", "<built-in method mujoco._functions.mj_step>") == "c"
    assert profiling._part("/x/site-packages/gymnasium/wrappers/common.py", "step") == "wrappers"
    assert profiling._part("/x/polyenvs/core/rows.py", "step") == "ours"
    line = profiling.format_section([("a row", profile), ("a broken row", "error: boom")]).splitlines()
    assert any(text.startswith("| a row |") and "test_throughput.py:_busy" in text for text in line)
    assert "| a broken row | - | - | - | - | - | error: boom |" in line
