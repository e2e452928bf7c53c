"""The estimator benchmark kind: the interface, names and import paths, the runner's scoring, the command."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the ids)
from polyenvs.commands.localize import add_parser
from polyenvs.errors import InputError
from polyenvs.estimators import Estimator, estimator_class, estimators, make_estimator
from polyenvs.evaluation import charts
from polyenvs.evaluation.localization import CONVERGED_CM, rollout_logs, score_estimator, summarize
from polyenvs.evaluation.localization_report import convergence_plot, convergence_table

ENV_ID = "polyenvs/BumperCartExplore-v0"


class StartPose:
    """A user's estimator: always the start pose (so its error is how far the cart got from its start)."""

    def reset(self, context, start_pose, rng):
        self.pose = np.array(start_pose)

    def update(self, log):
        return self.pose


class Broken(StartPose):
    def update(self, log):
        return np.array([np.nan, 0.0, 0.0])


@pytest.fixture(scope="module")
def logs():
    return rollout_logs(ENV_ID, 6, 5, seed=11)


def test_names_and_import_paths():
    assert list(estimators()) == ["mcl", "dead_reckoning"]  # the registry's, the paper's first
    for name in estimators():
        assert isinstance(make_estimator(name, particles=200), Estimator)
    assert make_estimator("mcl", particles=200).n == 200
    assert estimator_class(f"{__name__}:StartPose") is StartPose
    with pytest.raises(ValueError, match="unknown estimator"):
        estimator_class("kalman")
    with pytest.raises(ValueError, match="cannot import"):
        estimator_class("no.such.module:Thing")
    with pytest.raises(ValueError, match="reset"):
        estimator_class("math:pi")
    with pytest.raises(ValueError, match="bad parameters"):
        make_estimator("mcl", particle=3)


def test_runner_scores_against_the_true_pose_at_each_bump(logs):
    context, runs = logs
    result = score_estimator(f"{__name__}:StartPose", {}, context, runs, 5)
    for r, run in enumerate(runs):
        at_bumps = run.truth[run.bumped][:5]
        expected = np.hypot(*(at_bumps[:, :2] - run.start_pose[:2]).T)
        np.testing.assert_allclose(result["position_cm"][r], expected)
        turn = (at_bumps[:, 2] - run.start_pose[2] + np.pi) % (2 * np.pi) - np.pi
        np.testing.assert_allclose(result["heading_deg"][r], np.abs(np.degrees(turn)))
    summary = summarize(result)
    assert summary["position_error_cm"]["median"][0] == pytest.approx(
        float(np.median(result["position_cm"][:, 0])), abs=1e-4
    )
    close = (result["position_cm"] < CONVERGED_CM) & (result["heading_deg"] < 30)
    assert summary["failure_rates"]["never_converged"] == pytest.approx((~close.any(axis=1)).mean())
    assert summary["failure_rates"]["empty_particle_set"] == 0.0


def test_an_estimator_returning_nonsense_is_an_error(logs):
    context, runs = logs
    with pytest.raises(ValueError, match="finite"):
        score_estimator(f"{__name__}:Broken", {}, context, runs, 5)


def test_an_environment_without_logs_is_refused():
    with pytest.raises(InputError, match="localization"):
        rollout_logs("CartPole-v1", 1, 1, policy="random")


def test_report_table_and_plot(logs):
    context, runs = logs
    document = {"env_id": ENV_ID, "map": "paper", "runs": len(runs), "bumps": 5, "estimators": {},
                "converged_within": {"position_cm": 10.0, "heading_deg": 30.0}}  # fmt: skip
    for name in ("dead_reckoning", f"{__name__}:StartPose"):
        document["estimators"][name] = summarize(score_estimator(name, {}, context, runs, 5))
    table = convergence_table(document)
    assert table.splitlines()[0].split()[0] == "bump" and len(table.splitlines()) == 1 + 5 + 2
    pytest.importorskip("matplotlib")
    axes = convergence_plot(document).axes[0]
    lines = {line.get_label(): line for line in axes.get_lines()}
    for name, band in zip(document["estimators"], axes.collections, strict=True):
        quartiles = document["estimators"][name]["position_error_cm"]
        np.testing.assert_array_equal(lines[name].get_xdata(), [1, 2, 3, 4, 5])  # after the k-th bump, k from 1
        np.testing.assert_allclose(lines[name].get_ydata(), quartiles["median"])
        edge = band.get_paths()[0].vertices[:, 1]  # the quartile band, from q1 up to q3
        assert edge.min() == pytest.approx(min(quartiles["q1"]))
        assert edge.max() == pytest.approx(max(quartiles["q3"]))
    assert lines["10 cm: converged if also within 30°"].get_ydata()[0] == 10.0
    assert axes.get_xlabel() == "bumps" and axes.get_ylabel() == "position error (cm)"


def _args(*argv):
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers())
    return parser.parse_args(["localize", *argv])


@pytest.mark.parametrize(
    "argv,match",
    [(["--runs", "0"], "--runs"), (["--particles", "many"], "--particles"), (["--bumps", "1.5"], "--bumps"),
     (["--estimator", "kalman"], "--estimator kalman"), (["--env-kwargs", "[1]"], "--env-kwargs"),
     (["--estimator-kwargs", '{"tolerance_cm": -1}'], "tolerance_cm"), (["--particles", "5"], "--particles")],
)  # fmt: skip
def test_command_checks_every_flag_before_any_work(tmp_path, argv, match):
    with pytest.raises(InputError, match=match):
        _args(*argv, "--out", str(tmp_path / "out")).func(_args(*argv, "--out", str(tmp_path / "out")))
    assert not (tmp_path / "out").exists()


def test_command_refuses_an_unwritable_out(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    args = _args("--out", str(blocker))
    with pytest.raises(InputError, match="--out"):
        args.func(args)


def test_command_writes_json_and_png(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    out = tmp_path / "loc"
    args = _args("--runs", "3", "--bumps", "4", "--particles", "300", "--out", str(out), "--json", "--no-progress",
                 "--estimator", "mcl", "--estimator", f"{__name__}:StartPose")  # fmt: skip
    assert args.func(args) == 0
    printed = json.loads(capsys.readouterr().out)
    saved = json.loads((out / "localization.json").read_text())
    assert printed == saved
    assert saved["runs"] == 3 and saved["bumps"] == 4 and saved["map"] == "paper"
    mcl = saved["estimators"]["mcl"]
    for key in ("position_error_cm", "heading_error_deg"):
        assert set(mcl[key]) == {"q1", "median", "q3"} and len(mcl[key]["median"]) == 4
        assert all(q1 <= m <= q3 for q1, m, q3 in zip(mcl[key]["q1"], mcl[key]["median"], mcl[key]["q3"], strict=True))
    assert set(mcl["failure_rates"]) == {"empty_particle_set", "never_converged"}
    assert mcl["kwargs"] == {"particles": 300}
    assert saved["estimators"][f"{__name__}:StartPose"]["kwargs"] == {}
    assert (out / "convergence.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.glob(".*.tmp*"))


def test_without_matplotlib_the_json_and_table_are_written_and_it_says_why(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(charts, "available", lambda: False)
    args = _args("--runs", "2", "--bumps", "2", "--estimator", "dead_reckoning", "--no-progress", "--out",
                 str(tmp_path))  # fmt: skip
    assert args.func(args) == 0
    said = capsys.readouterr()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["localization.json"]
    assert said.err.strip() == f"convergence chart left out: it needs matplotlib: {charts.INSTALL_HINT}"
    assert "dead_reckoning" in said.out and said.out.strip().endswith(f"wrote {tmp_path / 'localization.json'}")


def test_command_map_flag_and_table(tmp_path, capsys):
    args = _args("--runs", "2", "--bumps", "3", "--map", "l_room", "--estimator", "dead_reckoning", "--out",
                 str(tmp_path))  # fmt: skip
    assert args.func(args) == 0
    text = capsys.readouterr().out
    assert "dead_reckoning" in text and "wrote" in text
    assert json.loads((tmp_path / "localization.json").read_text())["env_kwargs"] == {"map": "l_room"}
    args = _args("--map", "atlantis", "--out", str(tmp_path / "x"))
    with pytest.raises(InputError, match="map"):
        args.func(args)


def test_heading_in_scores_is_degrees(logs):
    context, runs = logs
    result = score_estimator("dead_reckoning", {}, context, runs, 5)
    assert np.nanmax(result["heading_deg"]) <= 180.0
    assert math.isfinite(np.nanmedian(result["position_cm"]))


def test_every_estimator_in_the_table_reads_the_logs_of_a_registry_id_and_imports():
    from polyenvs.estimators.table import ESTIMATORS
    from polyenvs.registry import ENV_IDS

    assert set(ESTIMATORS) <= set(ENV_IDS)
    for env_id, known in ESTIMATORS.items():
        assert list(known)[0] == "mcl"  # the paper's first: the command's default order
        for name in known:
            assert isinstance(make_estimator(name, env_id), Estimator)


def test_the_default_environment_is_a_current_id_whose_runs_go_past_its_task_budget():
    """``polyenvs localize`` defaults to the id the benchmark ranks on (not a superseded one), and a run ends at its
    bump count, not at the task's budget of 50 cycles."""
    from polyenvs.estimators import DEFAULT_ENV_ID
    from polyenvs.evaluation.localization import rollout_logs
    from polyenvs.registry import entry

    assert entry(DEFAULT_ENV_ID).superseded_by is None and estimators(DEFAULT_ENV_ID)
    _, (run,) = rollout_logs(DEFAULT_ENV_ID, runs=1, bumps=55)
    assert int(run.bumped.sum()) == 55 and len(run.logs) > 50
