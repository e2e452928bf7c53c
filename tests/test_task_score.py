"""The task score: declared on every registry row, emitted by its environment, and what the leaderboard ranks,
normalises and charts by (default and held-out layouts), evaluated one by one or on a process pool alike."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import polyenvs.evaluation.protocol
import polyenvs.evaluation.results
import polyenvs.evaluation.rollout
import polyenvs.evaluation.run
import polyenvs.evaluation.table
import polyenvs.evaluation.verdict
from baselines.table import hand_baselines
from polyenvs.cli import main
from polyenvs.evaluation import charts
from polyenvs.evaluation.episodes import make_env
from polyenvs.evaluation.page import leaderboard_markdown, write_leaderboard
from polyenvs.evaluation.results import result_path
from polyenvs.evaluation.rollout import is_parallel
from polyenvs.evaluation.table import leaderboard_tables
from polyenvs.registry import REGISTRY, Score

GOAL, TURN, WALL = "polyenvs/BuckybotGoal-v0", "polyenvs/BeastTurn-v0", "polyenvs/BuckybotWallFollow-v0"


def _one_step_metrics(env_id: str) -> dict:
    env = make_env(env_id)
    try:
        if is_parallel(env):
            env.reset(seed=0)
            env.step({a: env.action_space(a).sample() for a in env.agents})
            return env.unwrapped.episode_metrics()
        env.reset(seed=0)
        env.action_space.seed(0)
        env.step(env.action_space.sample())
        return env.unwrapped.episode_metrics()
    finally:
        env.close()


@pytest.mark.parametrize("row", REGISTRY, ids=lambda r: r.id)
def test_every_row_scores_a_metric_its_environment_emits(row):
    assert isinstance(row.score, Score), f"{row.id} declares no task score"
    metrics = _one_step_metrics(row.id)
    for name in filter(None, (row.score.metric, row.score.tie_break)):
        assert name in metrics, f"{row.id} scores {name!r}, which its episode metrics lack: {sorted(metrics)}"
    if row.score.upper_anchor is not None:
        assert row.score.upper_anchor in hand_baselines(row.id).names


def test_a_bad_direction_is_refused():
    with pytest.raises(ValueError, match="direction"):
        Score("success", "up")


def _doc(env_id: str, policy: str, values: list[float], metric: str, layouts: str = "default", **extra) -> dict:
    episodes = [
        {"seed": 1000 + i, "return": 10 * v, "length": 5, "metrics": {metric: v, **{k: x[i] for k, x in extra.items()}}}
        for i, v in enumerate(values)
    ]
    kwargs = {} if layouts == "default" else {"layouts": layouts}
    return {"env_id": env_id, "policy": policy, "episodes": episodes, "summary": {}, "n_episodes": len(values),
            "env_kwargs": kwargs}  # fmt: skip


def test_rows_are_ranked_by_the_score_and_the_tie_break_at_the_ceiling():
    docs = [
        _doc(GOAL, "random", [0.0] * 4, "success", steps_to_goal=[300] * 4),
        _doc(GOAL, "goal_seeker", [1.0] * 4, "success", steps_to_goal=[30, 30, 30, 30]),
        _doc(GOAL, "fast", [1.0] * 4, "success", steps_to_goal=[20, 20, 20, 20]),
    ]
    docs[2]["agent"] = {"algo": "ppo", "label": "ppo", "training_seed": 0}
    table = leaderboard_tables(docs)[GOAL]
    assert [r["label"] for r in table["rows"]] == ["ppo", "goal_seeker", "random"]  # fewer steps wins at 1
    assert table["discriminative"] and table["rows"][1]["normalised"] == pytest.approx(1.0)
    # A score where lower is better (the turn's heading error) ranks the other way, floor 0.
    turn = leaderboard_tables(
        [
            _doc(TURN, "random", [180.0] * 4, "heading_error_deg"),
            _doc(TURN, "sharp_turn_cone", [5.0] * 4, "heading_error_deg"),
        ]
    )[TURN]
    assert [r["label"] for r in turn["rows"]] == ["sharp_turn_cone", "random"]
    assert turn["rows"][0]["normalised"] == pytest.approx(1.0) and turn["rows"][1]["normalised"] == 0.0


def test_overlapping_intervals_are_reported_not_normalised():
    docs = [
        _doc(WALL, "random", [0.1, 0.2, 0.3, 0.4], "perimeter_fraction"),
        _doc(WALL, "wall_follower", [0.2, 0.3, 0.4, 0.5], "perimeter_fraction"),
    ]
    table = leaderboard_tables(docs)[WALL]
    assert not table["discriminative"] and all(r["normalised"] is None for r in table["rows"])
    text = leaderboard_markdown(docs)
    assert "**Not discriminative**" in text and "| wall_follower | 0.35 [0.2, 0.5] | not discriminative |" in text


def test_a_superseded_version_says_which_version_the_benchmark_ranks_on():
    old = "polyenvs/BumperCartExplore-v0"
    docs = [_doc(old, p, [0.8, 0.85, 0.9], "wall_fraction_touched") for p in ("random", "random_bounce")]
    text = leaderboard_markdown(docs)
    assert "**Superseded** by `polyenvs/BumperCartExplore-v2`, which the benchmark ranks on" in text
    assert "Superseded" not in leaderboard_markdown([_doc(WALL, "random", [0.1, 0.2], "perimeter_fraction")])


def test_held_out_results_are_evaluated_and_shown_with_the_gap(tmp_path, monkeypatch, capsys):
    """Every environment is evaluated on "default" (no keyword: today's episodes) and "test"."""
    calls = []

    def fake_evaluate(env_id, policy, episodes, seed, env_kwargs=None, on_episode=None):
        calls.append((policy, env_kwargs))
        held_out = (env_kwargs or {}).get("layouts") == "test"
        values = [0.0] * episodes if policy == "random" else [0.5 if held_out else 1.0] * episodes
        return _doc(env_id, policy, values, "success", "test" if held_out else "default",
                    steps_to_goal=[30] * episodes)  # fmt: skip

    monkeypatch.setattr(polyenvs.evaluation.run, "evaluate", fake_evaluate)
    (tmp_path / "agents").mkdir()
    args = ["leaderboard", "--only", "Goal", "--episodes", "2", "--jobs", "1", "--agents-dir", str(tmp_path / "agents"),
            "--results-dir", str(tmp_path / "results"), "--output", str(tmp_path / "LB.md")]  # fmt: skip
    assert main(args) == 0
    assert sorted(calls, key=str) == sorted(
        [(p, kw) for p in ("random", "goal_seeker") for kw in (None, {"layouts": "test"})], key=str
    )
    assert result_path(tmp_path / "results", GOAL, "goal_seeker", "test").name.endswith("__layouts-test.json")
    text = (tmp_path / "LB.md").read_text()
    assert "| goal_seeker | 1 [1, 1] | 1.00 | 10.00 [10.00, 10.00] | 0.5 [0.5, 0.5] | 0.5 |" in text
    calls.clear()
    assert main(args) == 0 and calls == []  # both layouts' files are reused
    assert "done before" in capsys.readouterr().err


def test_a_row_whose_score_needs_more_episodes_runs_them_by_default(tmp_path, monkeypatch):
    """``Score.episodes`` is the protocol's count for its row: the default run evaluates that many (and reuses no
    result with fewer); ``--episodes`` and ``--quick`` still override it."""
    counts = []

    def fake_evaluate(env_id, policy, episodes, seed, env_kwargs=None, on_episode=None):
        counts.append(episodes)
        held_out = (env_kwargs or {}).get("layouts") == "test"
        return _doc(env_id, policy, [float(policy != "random")] * episodes, "success", "test" if held_out else "default",
                    steps_to_goal=[30] * episodes)  # fmt: skip

    monkeypatch.setattr(polyenvs.evaluation.run, "evaluate", fake_evaluate)
    monkeypatch.setattr(polyenvs.evaluation.protocol, "PROTOCOL_EPISODES", 2)  # the protocol's 50, made fast
    real_entry = polyenvs.evaluation.protocol.entry
    score = Score("success", "max", ceiling=1.0, tie_break="steps_to_goal", episodes=60)
    monkeypatch.setattr(
        polyenvs.evaluation.protocol, "entry", lambda env_id: dataclasses.replace(real_entry(env_id), score=score)
    )
    (tmp_path / "agents").mkdir()
    args = ["leaderboard", "--only", "Goal", "--jobs", "1", "--agents-dir", str(tmp_path / "agents"),
            "--results-dir", str(tmp_path / "results"), "--output", str(tmp_path / "LB.md")]  # fmt: skip
    assert main(args) == 0 and counts == [60] * 4
    assert "60 evaluation episodes" in (tmp_path / "LB.md").read_text()
    counts.clear()
    assert main([*args, "--episodes", "3"]) == 0 and counts == [3] * 4


def test_a_score_refuses_fewer_episodes_than_the_protocol():
    with pytest.raises(ValueError, match="episodes"):
        Score("success", episodes=10)


def test_the_committed_reference_holds_each_rows_protocol_count():
    from polyenvs.commands.leaderboard import REFERENCE_RESULTS_DIR

    root = Path(__file__).resolve().parents[1]
    rows = {row.id: polyenvs.evaluation.protocol.protocol_episodes(row.id) for row in REGISTRY}
    for path in sorted((root / REFERENCE_RESULTS_DIR).glob("*.json")):
        doc = json.loads(path.read_text())
        assert doc["n_episodes"] == rows[doc["env_id"]], f"{path.name}: {doc['n_episodes']} episodes"


def _agent(doc: dict, seed: int = 0, training_layouts: str = "train") -> dict:
    doc["agent"] = {"algo": "ppo", "label": "ppo", "training_seed": seed, "training_layouts": training_layouts}
    return doc


def test_the_verdict_says_whether_an_agent_beats_the_paper_default_and_held_out():
    rng = np.random.default_rng(1)
    paper = [_doc(WALL, "wall_follower", list(rng.uniform(0.5, 0.6, 30)), "perimeter_fraction", layouts=layouts)
             for layouts in ("default", "test")]  # fmt: skip
    random = _doc(WALL, "random", list(rng.uniform(0.0, 0.1, 30)), "perimeter_fraction")
    better = _agent(_doc(WALL, "x", list(rng.uniform(0.7, 0.8, 30)), "perimeter_fraction"))
    overlapping = _agent(_doc(WALL, "x", list(rng.uniform(0.5, 0.6, 30)), "perimeter_fraction", layouts="test"))
    verdict = polyenvs.evaluation.verdict.agent_verdict(leaderboard_tables([*paper, random, better, overlapping])[WALL])
    assert verdict["reference"]["label"] == "wall_follower" and verdict["agent"]["label"] == "ppo"
    assert verdict["default"] is True and verdict["held_out"] is False
    # Lower is better on the turn: an agent with a larger heading error does not beat it.
    turn = [_doc(TURN, "sharp_turn_cone", [1.0, 1.1, 0.9] * 10, "heading_error_deg"),
            _agent(_doc(TURN, "x", [2.0, 2.1, 1.9] * 10, "heading_error_deg"))]  # fmt: skip
    assert polyenvs.evaluation.verdict.agent_verdict(leaderboard_tables(turn)[TURN])["default"] is False
    turn[1] = _agent(_doc(TURN, "x", [0.2, 0.3, 0.1] * 10, "heading_error_deg"))
    assert polyenvs.evaluation.verdict.agent_verdict(leaderboard_tables(turn)[TURN])["default"] is True
    # An interval that only reaches below the paper's is no win (its worse end, the upper one, is above).
    turn[1] = _agent(_doc(TURN, "x", list(rng.uniform(0.0, 2.2, 30)), "heading_error_deg"))
    verdict = polyenvs.evaluation.verdict.agent_verdict(leaderboard_tables(turn)[TURN])
    assert verdict["agent"]["score"]["low"] < 0.9 < verdict["agent"]["score"]["high"] and verdict["default"] is False

    # Both at the ceiling: the tie-break decides (fewer steps to the goal), on each layouts' own episodes.
    def goal(agent_steps: int, agent_held_out_steps: int) -> dict:
        docs = [_doc(GOAL, "goal_seeker", [1.0] * 30, "success", layouts, steps_to_goal=[30] * 30)
                for layouts in ("default", "test")]  # fmt: skip
        docs += [_agent(_doc(GOAL, "x", [1.0] * 30, "success", "default", steps_to_goal=[agent_steps] * 30)),
                 _agent(_doc(GOAL, "x", [1.0] * 30, "success", "test", steps_to_goal=[agent_held_out_steps] * 30))]  # fmt: skip
        return polyenvs.evaluation.verdict.agent_verdict(leaderboard_tables(docs)[GOAL])

    assert [goal(25, 35)[k] for k in ("default", "held_out")] == [True, False]
    assert [goal(35, 25)[k] for k in ("default", "held_out")] == [False, True]
    # Without an agent there is no verdict, and the page says so.
    assert polyenvs.evaluation.verdict.agent_verdict(leaderboard_tables([*paper, random])[WALL]) is None
    page = leaderboard_markdown([*paper, random, better])
    assert (
        "a trained agent beats the paper's algorithm on the held-out layouts on 0 of the 1 environments the "
        "benchmark ranks on (1 have such an agent), and on the default layouts on 1." in page
    )
    assert f"| {WALL} | wall_follower " in page and "(train layouts) |" in page and "| no | **yes** |" in page
    # An agent trained on the default layouts (not the training ones) is shown, labelled, and not counted.
    page = leaderboard_markdown([*paper, random, _agent({**better}, training_layouts="default")])
    assert "(default layouts: not counted) |" in page and "| no | **yes** |" in page
    assert "on the held-out layouts on 0 of the 1 environments the benchmark ranks on (0 have such an agent)" in page
    assert "Counting every agent, whatever it trained on: 0 on the held-out layouts, 1 on the default ones." in page
    # A version the benchmark no longer ranks on is shown, not counted.
    roll = "polyenvs/BeastRoll-v0"
    old = [_doc(roll, "rolling_gait", [0.82] * 30, "distance_m"), _agent(_doc(roll, "x", [0.9] * 30, "distance_m"))]
    page = leaderboard_markdown([*paper, random, better, *old])
    assert f"| {roll} (superseded by polyenvs/BeastRoll-v1: not counted) | rolling_gait " in page
    assert (
        "on 0 of the 1 environments the benchmark ranks on (1 have such an agent), and on the default layouts on 1"
        in page
    )


def _random_and_paper(rng) -> list[dict]:
    """WallFollow's random and paper's results on the default layouts, the paper clearly above random."""
    return [
        _doc(WALL, "random", list(rng.uniform(0.0, 0.2, 8)), "perimeter_fraction"),
        _doc(WALL, "wall_follower", list(rng.uniform(0.6, 0.9, 8)), "perimeter_fraction"),
    ]


def test_charts_are_interval_plots_and_a_performance_profile(tmp_path):
    pytest.importorskip("matplotlib")
    rng = np.random.default_rng(0)
    docs = [
        *_random_and_paper(rng),
        _doc(WALL, "wall_follower", list(rng.uniform(0.3, 0.5, 8)), "perimeter_fraction", "test"),
    ]
    text = write_leaderboard(docs, tmp_path / "LB.md")
    for name in ("LB_polyenvs__BuckybotWallFollow-v0.png", "LB_profile.png"):
        assert f"]({name})" in text and (tmp_path / name).read_bytes().startswith(b"\x89PNG\r\n\x1a\n")


def test_charts_draw_more_trained_algorithms_than_colours_each_its_own_line(tmp_path):
    """The reference page has a dozen trained recipes (ppo, ppo_bc_<baseline>, ppo_residual_<baseline>, ...)."""
    pytest.importorskip("matplotlib")
    rng = np.random.default_rng(0)
    docs = _random_and_paper(rng)
    labels = [f"algo{i}" for i in range(len(charts.SERIES_STYLES) + 3)]
    for label in labels:
        docs.append(_doc(WALL, label, list(rng.uniform(0.5, 1.0, 8)), "perimeter_fraction"))
        docs[-1]["agent"] = {"algo": "ppo", "label": label, "training_seed": 0}
    profile = charts.performance_profile_plot(leaderboard_tables(docs))
    curves = {label: [(np.arange(3), rng.uniform(size=3))] for label in labels}
    learning = charts.learning_curve_plot(WALL, "perimeter_fraction", curves, {"wall_follower": (0.8, "paper")})
    for figure, expected in ((profile, ["random", "paper's algorithm", *labels]), (learning, labels)):
        lines = {line.get_label(): (line.get_color(), line.get_linestyle()) for line in figure.axes[0].get_lines()}
        assert set(expected) <= set(lines)
        drawn = [lines[label] for label in labels]
        assert len(set(drawn)) == len(charts.SERIES_STYLES)  # each style once before any repeats
        assert all(style != "--" for _, style in drawn)  # dashed is a hand policy's evaluated level
        charts.save(figure, tmp_path / "chart.png")


def test_without_matplotlib_the_table_is_written_and_says_why(tmp_path, monkeypatch):
    monkeypatch.setattr(charts, "available", lambda: False)
    said = []
    write_leaderboard(
        [_doc(WALL, "random", [0.1, 0.2], "perimeter_fraction")], tmp_path / "LB.md", progress=said.append
    )
    assert (tmp_path / "LB.md").is_file() and not list(tmp_path.glob("*.png"))
    assert said == [f"charts left out: they need matplotlib: {charts.INSTALL_HINT}"]


@pytest.mark.slow
def test_a_process_pool_gives_the_serial_results(tmp_path, capsys):
    """The main job's --jobs: the same result files as one by one (apart from the date), a line per evaluation."""
    files = {}
    for jobs in ("1", "2"):
        out = tmp_path / jobs
        args = ["leaderboard", "--only", "Goal", "--episodes", "2", "--jobs", jobs, "--agents-dir", str(tmp_path),
                "--results-dir", str(out), "--output", str(out / "LB.md")]  # fmt: skip
        assert main(args) == 0
        err = capsys.readouterr().err
        assert "goal_seeker: 2 episodes in" in err and "random: 2 episodes in" in err
        files[jobs] = {p.name: json.loads(p.read_text()) for p in sorted(out.glob("*.json"))}
        for doc in files[jobs].values():
            doc.pop("date")
    assert files["1"] == files["2"] and {"polyenvs__BuckybotGoal-v0__random.json"} <= set(files["1"])


def test_the_committed_reference_is_read_with_its_scores():
    """Reading the committed results needs no re-evaluation: every row with results gets a table."""
    from polyenvs.commands.leaderboard import REFERENCE_RESULTS_DIR

    root = Path(polyenvs.evaluation.results.__file__).resolve().parents[2]
    docs = polyenvs.evaluation.results.stored_results(
        [r.id for r in REGISTRY], root / REFERENCE_RESULTS_DIR, lambda _: None
    )
    assert {d["env_id"] for d in docs} <= {r.id for r in REGISTRY}
    assert all(t["score"] is not None for t in leaderboard_tables(docs).values())


def _formation_episode(policy: str, steps: int = 200) -> dict:
    from baselines import make_policy
    from polyenvs.evaluation.rollout import agent_spaces, run_episode

    env = make_env("polyenvs.swarm.formation_v0", {"max_cycles": steps})
    try:
        if policy == "still":
            zero = np.zeros((len(env.possible_agents), 2), dtype=np.float32)

            class Still:
                def predict(self, obs, state=None, episode_start=None, deterministic=True):
                    return zero[: len(obs)], None

            agent = Still()
        else:
            agent = make_policy(policy, "polyenvs.swarm.formation_v0", *agent_spaces(env))
        return run_episode(env, agent, 1000)["metrics"]
    finally:
        env.close()


def test_formation_progress_counts_only_progress_in_formation(monkeypatch):
    """The formation's score: standing still keeps the lattice and scores 0; the paper's springs score the
    centroid's progress, which counts for nothing once the formation no longer holds."""
    import polyenvs.swarm.formation_v0 as formation

    assert _formation_episode("still")["formation_progress_m"] == 0.0
    held = _formation_episode("formation")
    assert held["formation_progress_m"] > 2.0, held  # 20 s at up to 0.5 m/s, in formation
    monkeypatch.setattr(formation, "FORMATION_HOLDS_ERROR", -1.0)  # a formation that never holds
    assert _formation_episode("formation")["formation_progress_m"] == 0.0


def test_the_goal_tie_break_counts_the_steps_to_the_goal():
    from baselines import make_policy
    from polyenvs.evaluation.rollout import agent_spaces, run_episode

    env = make_env(GOAL)
    result = run_episode(env, make_policy("paper", GOAL, *agent_spaces(env)), 1000)
    env.close()
    assert result["metrics"]["success"] == 1.0 and result["metrics"]["steps_to_goal"] == result["length"]


def test_success_scores_rank_by_their_rate_not_its_iqm():
    """Every success score aggregates as its mean (an IQM of 0/1 episodes is 1 at a 76% success rate, which would
    tie a policy that fails a quarter of its episodes with one that never fails), and the table uses it."""
    successes = [row for row in REGISTRY if row.score is not None and "success" in row.score.metric]
    assert successes and all(row.score.aggregate == "mean" for row in successes)
    runs = [np.r_[np.ones(38), np.zeros(12)]]
    stats = polyenvs.evaluation.table._interval(runs, successes[0].score)
    assert stats["value"] == pytest.approx(0.76) and stats["high"] < 1.0


def test_a_training_seed_that_fails_widens_the_agents_interval_and_can_flip_the_verdict():
    """The run is the unit: three seeds well above the paper beat it; a fourth that fails makes the difference's
    interval reach below 0 (episodes resampled within each seed alone would keep it narrow and the win)."""
    rng = np.random.default_rng(3)
    paper = [_doc(WALL, "wall_follower", list(rng.uniform(0.5, 0.6, 30)), "perimeter_fraction", layouts=layouts)
             for layouts in ("default", "test")]  # fmt: skip
    random = _doc(WALL, "random", list(rng.uniform(0.0, 0.1, 30)), "perimeter_fraction")

    def seeds(values: list[tuple[float, float]]) -> list[dict]:
        return [_agent(_doc(WALL, "x", list(rng.uniform(lo, hi, 30)), "perimeter_fraction", layouts=layouts), seed)
                for seed, (lo, hi) in enumerate(values) for layouts in ("default", "test")]  # fmt: skip

    good = [(0.7, 0.8), (0.72, 0.82), (0.68, 0.78)]
    three = leaderboard_tables([*paper, random, *seeds(good)])[WALL]
    four = leaderboard_tables([*paper, random, *seeds([*good, (0.0, 0.1)])])[WALL]
    agent = [next(r for r in t["rows"] if r["kind"] == "agent") for t in (three, four)]
    assert [len(a["seed_scores"]) for a in agent] == [3, 4]
    widths = [a["held_out"]["high"] - a["held_out"]["low"] for a in agent]
    assert widths[1] > 5 * widths[0]
    verdicts = [polyenvs.evaluation.verdict.agent_verdict(t) for t in (three, four)]
    assert [v["held_out"] for v in verdicts] == [True, False] and [v["default"] for v in verdicts] == [True, False]
    assert verdicts[0]["improvement"][0] == 1.0 and verdicts[1]["improvement"][0] == 0.75
