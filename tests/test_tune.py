"""``polyenvs tune``: every hand baseline declares what may be tuned; a study on the training layouts improves a
detuned baseline on one id of each family, resumes after kill -9 to the same trials, refuses bad flags before any
work, and writes a directory that is a policy everywhere (evaluate, the residual's base, the leaderboard's rows and
its verdict against the tuned paper)."""

from __future__ import annotations

import dataclasses
import inspect
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("optuna")

import baselines.table
from baselines import make_policy
from baselines.factory import tunable_parameters
from baselines.residual import ResidualSpec, make_composer
from baselines.table import BASELINES, Baseline, HandBaselines
from baselines.tuned import TUNED_FILE
from polyenvs.evaluation.agents import find_agents
from polyenvs.evaluation.episodes import make_env
from polyenvs.evaluation.rollout import agent_spaces
from polyenvs.evaluation.table import leaderboard_tables
from polyenvs.evaluation.verdict import agent_verdict
from polyenvs.registry import import_attribute
from polyenvs.training.tune import TuneRequest, tune, tuning_seeds
from tests.cli_helpers import run_main

CART = "polyenvs/BumperCartExplore-v2"


def _every_baseline() -> list[tuple[str, Baseline]]:
    seen = {}
    for env_id, row in BASELINES.items():
        for baseline in row.baselines:
            seen.setdefault((baseline.factory, tuple(sorted(baseline.kwargs.items()))), (env_id, baseline))
    return list(seen.values())


@pytest.mark.parametrize("env_id, baseline", _every_baseline(), ids=lambda x: getattr(x, "name", x))
def test_every_hand_baseline_declares_its_tunable_parameters_with_the_constructors_defaults(env_id, baseline):
    cls = import_attribute(baseline.factory)
    assert cls.tunables is not None, f"{cls.__name__} declares no tunable parameters"
    signature = inspect.signature(cls.__init__).parameters
    for field in dataclasses.fields(cls.tunables):
        low, high = field.metadata["range"]
        assert field.metadata["unit"] is not None and field.metadata["source"]
        if field.name in signature:  # AP-lite's force law arrives as keywords, checked by the dataclass itself
            assert signature[field.name].default == field.default, f"{cls.__name__}.{field.name}"
    for parameter in tunable_parameters(baseline.name, env_id):
        assert parameter.low <= parameter.start <= parameter.high


def test_a_tunable_starts_where_the_baselines_row_sets_it():
    starts = {p.name: p.start for p in tunable_parameters("wall_follower_rules", "polyenvs/BuckybotWallFollow-v0")}
    assert starts["x_s_cm"] == 30.0 and starts["d_star_cm"] == 50.0
    assert {p.name for p in tunable_parameters("paper", "polyenvs/APLiteCorridor-v0")} >= {"k_mid", "goal_force"}


def _detuned(monkeypatch, env_id: str, name: str, factory: str, **kwargs) -> None:
    """Give ``env_id`` a baseline ``name`` that starts from deliberately bad parameters."""
    row = HandBaselines((Baseline(name, factory, kwargs),), paper=name)
    monkeypatch.setitem(baselines.table.BASELINES, env_id, row)


#: One id of each family, a baseline detuned on it, and the trials and episodes its study gets.
DETUNED = [
    (CART, "baselines.bumper:FixedTurn", {"turn_deg": 2.0}, 6, 6, {}),
    ("polyenvs/BuckybotGoal-v0", "baselines.buckybot:GoalSeeker", {"clearance_cm": 118.0}, 6, 10, {}),
    ("polyenvs/APLiteObstacleField-v0", "baselines.swarm:APLite", {"goal_force": 12.0}, 4, 4, {}),
    ("polyenvs/BeastRecover-v1", "baselines.beast:Righting", {"rate_deg_s": 5.5}, 3, 2, {}),
]  # fmt: skip


@pytest.mark.parametrize("env_id, factory, kwargs, trials, episodes, env_kwargs", DETUNED, ids=[d[0] for d in DETUNED])
def test_a_tiny_study_improves_a_detuned_baseline(monkeypatch, tmp_path, env_id, factory, kwargs, trials, episodes,
                                                  env_kwargs):  # fmt: skip
    if "Beast" in env_id:
        pytest.importorskip("mujoco")
    _detuned(monkeypatch, env_id, "detuned", factory, **kwargs)
    request = TuneRequest(env_id, "paper", trials, seed=0, out=tmp_path, episodes=episodes, env_kwargs=env_kwargs)
    doc = tune(request, progress=lambda _: None)
    first, *others = doc["history"]
    assert first["params"] == doc["paper_params"]
    assert all(doc["paper_params"][k] == v for k, v in kwargs.items() if k in doc["space"])
    assert doc["completed"] and doc["finished_trials"] == trials
    assert doc["best"]["trial"] != 0 and doc["params"] != doc["paper_params"]
    assert doc["history"][doc["best"]["trial"]]["value"] > first["value"]
    assert doc["env_kwargs"]["layouts"] == "train" and doc["objective"]["episode_seeds"][0] == tuning_seeds(0, 1)[0]


def _tune_command(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "polyenvs.cli", "tune", "polyenvs/BuckybotWallFollow-v0", "--trials", "6",
            "--episodes", "8", "--seed", "3", "--out", str(out), *extra]  # fmt: skip


def test_a_study_killed_with_sigkill_resumes_to_the_trials_an_uninterrupted_one_runs(tmp_path):
    whole = tmp_path / "whole"
    subprocess.run(_tune_command(whole), check=True, capture_output=True, timeout=600)
    killed = tmp_path / "killed"
    process = subprocess.Popen(_tune_command(killed), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        tuned = killed / TUNED_FILE
        if tuned.is_file() and json.loads(tuned.read_text())["finished_trials"] >= 3:
            break
        time.sleep(0.02)
    time.sleep(0.3)  # into the next trial (8 episodes of about 0.1 s), which the kill leaves running
    second = subprocess.run(_tune_command(killed), capture_output=True, text=True, timeout=600)
    assert second.returncode == 2 and f"is being tuned into by pid {process.pid}" in second.stderr  # not touched
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    interrupted = json.loads((killed / TUNED_FILE).read_text())
    assert not interrupted["completed"] and interrupted["finished_trials"] < 6
    subprocess.run(_tune_command(killed), check=True, capture_output=True, timeout=600)

    def finished(doc):
        return [(t["params"], t["score"]) for t in doc["history"] if t["state"] in ("complete", "pruned")]

    resumed, reference = (json.loads((d / TUNED_FILE).read_text()) for d in (killed, whole))
    assert "fail" in [t["state"] for t in resumed["history"]]  # the trial the kill cut short, asked again
    assert resumed["completed"] and finished(resumed) == finished(reference)
    assert resumed["params"] == reference["params"]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--policy", "random"], "--policy random: not a hand baseline"),
        (["--trials", "0"], "--trials must be >= 1"),
        (["--sampler", "grid"], "--sampler must be one of tpe, cmaes"),
        (["--episodes", "1.5"], "--episodes must be an integer"),
        (["--env-kwargs", '{"layouts": "test"}'], "a tuning runs on layouts='train'"),
        (["--env-kwargs", '{"bogus": 1}'], "bad environment keyword arguments"),
        (["--max-mean", "bogus=1"], "--max-mean bogus: polyenvs/BumperCartExplore-v2 has no such episode metric"),
        (["--max-mean", "coverage"], "--max-mean must be METRIC=LIMIT"),
        (["--max-mean", "coverage=nan"], "--max-mean coverage must be a finite number"),
        (["--max-mean", "coverage=1", "--sampler", "cmaes"], "--max-mean needs --sampler tpe"),
    ],
)
def test_bad_flags_are_refused_in_one_line_before_any_work(tmp_path, capsys, args, message):
    out = tmp_path / "out"
    base = ["tune", CART, "--trials", "2", "--out", str(out)]
    code, stdout, stderr = run_main([*base, *args], capsys)
    assert code == 2 and message in stderr and len(stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_an_output_directory_holding_another_tuning_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    assert run_main(["tune", CART, "--policy", "fixed_turn", "--trials", "1", "--episodes", "1", "--out", str(out)],
                    capsys)[0] == 0  # fmt: skip
    before = (out / TUNED_FILE).read_bytes()
    code, _, stderr = run_main(["tune", CART, "--policy", "fixed_turn", "--trials", "1", "--episodes", "1",
                                "--seed", "1", "--out", str(out)], capsys)  # fmt: skip
    assert code == 2 and "holds a tuning with seed 0, not 1" in stderr
    assert (out / TUNED_FILE).read_bytes() == before


def _tuned_dir(path: Path, env_id: str = CART, turn_deg: float = 100.0, seed: int = 0) -> Path:
    path.mkdir(parents=True)
    doc = {"env_id": env_id, "policy": "fixed_turn", "params": {"turn_deg": turn_deg}, "seed": seed,
           "completed": True, "env_kwargs": {"layouts": "train"}}  # fmt: skip
    (path / TUNED_FILE).write_text(json.dumps(doc))
    return path


def test_the_tuned_directory_is_the_baseline_with_its_parameters(tmp_path):
    env = make_env(CART)
    spaces = agent_spaces(env)
    tuned = make_policy(str(_tuned_dir(tmp_path / "t")), CART, *spaces)
    assert tuned.base.turn_deg == 100.0 and tuned.describe()["params"] == {"turn_deg": 100.0}
    action, _ = tuned.predict(env.observation_space.sample())
    assert np.isclose(action[0], 100.0 / 180.0)
    with pytest.raises(ValueError, match="tuned on polyenvs/BumperCartExplore-v2, not polyenvs/BumperCartLocalize"):
        make_policy(str(tmp_path / "t"), "polyenvs/BumperCartLocalize-v0", *spaces)
    composer = make_composer(ResidualSpec(str(tmp_path / "t")), CART, *spaces)
    assert composer.base.base.turn_deg == 100.0


def test_the_leaderboard_finds_tuned_rows_and_the_verdict_judges_agents_against_the_tuned_paper(tmp_path):
    agents = tmp_path / "agents"
    for seed in (0, 1):
        _tuned_dir(agents / CART.replace("/", "__") / "tuned_fixed_turn" / f"seed{seed}", seed=seed)
    found = find_agents(agents, CART)
    assert [(a.algo, a.label, a.seed) for a in found] == [("tuned", "tuned_fixed_turn", 0), ("tuned",
                                                           "tuned_fixed_turn", 1)]  # fmt: skip
    assert found[0].meta()["training_layouts"] == "train"

    def doc(policy, values, layouts, agent=None):
        episodes = [{"seed": 1000 + i, "return": v, "length": 1, "metrics": {"coverage": v}} for i, v in
                    enumerate(values)]  # fmt: skip
        d = {"env_id": CART, "policy": policy, "episodes": episodes, "summary": {}, "n_episodes": len(values),
             "env_kwargs": {} if layouts == "default" else {"layouts": layouts}}  # fmt: skip
        if agent is not None:
            d["agent"] = agent
        return d

    rng = np.random.default_rng(0)
    docs = []
    for layouts in ("default", "test"):
        docs += [
            doc("random", rng.uniform(0.1, 0.2, 20), layouts),
            doc("fixed_turn", rng.uniform(0.5, 0.6, 20), layouts),
        ]
        for seed in (0, 1, 2):
            tuned = {"algo": "tuned", "label": "tuned_fixed_turn", "training_seed": seed, "training_layouts": "train"}
            ppo = {"algo": "ppo", "label": "ppo", "training_seed": seed, "training_layouts": "train"}
            docs += [doc("t", rng.uniform(0.8, 0.9, 20), layouts, tuned), doc("p", rng.uniform(0.65, 0.75, 20),
                                                                              layouts, ppo)]  # fmt: skip
    table = leaderboard_tables(docs)[CART]
    assert [r["kind"] for r in table["rows"]][:2] == ["tuned", "agent"]
    verdict = agent_verdict(table)
    assert verdict["agent"]["label"] == "ppo" and verdict["held_out"] is True
    assert verdict["tuned"]["label"] == "tuned_fixed_turn" and verdict["beats_tuned"] is False


def test_polyenvs_list_policies_shows_what_each_baseline_may_tune(capsys):
    code, stdout, _ = run_main(["list", "--policies", "--json"], capsys)
    rows = {row["id"]: row for row in json.loads(stdout)}
    assert code == 0 and set(rows) == set(BASELINES)
    wall = rows["polyenvs/BuckybotWallFollow-v0"]
    assert wall["paper"] == "wall_follower"
    assert {p["name"]: (p["start"], p["low"], p["high"]) for p in wall["baselines"]["wall_follower"]}["d_star_cm"] == (
        50.0, 20.0, 120.0)  # fmt: skip
    code, stdout, _ = run_main(["list", "--policies"], capsys)
    assert "  wall_follower (paper): d_star_cm = 50 [20, 120] cm;" in stdout


def test_a_limit_keeps_the_best_trial_within_the_first_trials_mean(monkeypatch, tmp_path):
    # Coverage capped at the detuned start's own: the trials that cover more are infeasible, however well they score.
    _detuned(monkeypatch, CART, "detuned", "baselines.bumper:FixedTurn", turn_deg=2.0)
    request = TuneRequest(CART, "paper", 6, seed=0, out=tmp_path, episodes=4, limits={"coverage": "first"})
    doc = tune(request, progress=lambda _: None)
    history = doc["history"]
    best = history[doc["best"]["trial"]]
    assert best["feasible"] and best["means"]["coverage"] <= history[0]["means"]["coverage"]
    assert any(not t["feasible"] and t["value"] > best["value"] for t in history)
    assert doc["objective"]["limits"] == {"coverage": "first"}
