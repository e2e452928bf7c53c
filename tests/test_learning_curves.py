"""benchmarks.learning_curves: an agent's curve.json drawn against the evaluated levels of random and the paper."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

pytest.importorskip("matplotlib")

from benchmarks import learning_curves  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ENV = "polyenvs__APLiteCorridor-v0"
AGENT = ROOT / "benchmarks" / "agents" / ENV / "ppo_residual_paper"


def _agents(tmp_path: Path) -> Path:
    """Two seeds of a committed agent, only the first with a curve (what an older training did not write)."""
    agents = tmp_path / "agents"
    for seed in ("seed0", "seed1"):
        shutil.copytree(AGENT / seed, agents / ENV / "ppo_residual_paper" / seed, ignore=shutil.ignore_patterns("tb"))
    curve = {
        "timesteps": [2048, 4096, 6144],
        "return": [None, 50.0, 60.0],
        "metrics": {"success_rate": [None, 0.5, 1.0]},
    }
    (agents / ENV / "ppo_residual_paper" / "seed0" / "curve.json").write_text(json.dumps(curve))
    (agents / ENV / "ppo_residual_paper" / "seed1" / "curve.json").unlink(missing_ok=True)
    return agents


def _results(tmp_path: Path) -> Path:
    results = tmp_path / "results"
    results.mkdir()
    for policy in ("random", "aplite", "aplite_goal_seeking"):
        name = f"{ENV}__{policy}.json"
        shutil.copy(ROOT / "benchmarks" / "results" / name, results / name)
    return results


def test_curves_read_the_score_metric_of_the_seeds_that_wrote_one(tmp_path):
    curves = learning_curves._curves(_agents(tmp_path), "polyenvs/APLiteCorridor-v0", "success_rate")
    assert curves == {"ppo_residual_paper": [((4096, 6144), (0.5, 1.0))]}  # no episode yet at 2048: left out


def test_levels_are_random_and_the_paper_as_the_leaderboard_scores_them(tmp_path):
    levels = learning_curves._levels(_results(tmp_path), "polyenvs/APLiteCorridor-v0")
    assert set(levels) == {"random", "aplite"}  # another hand baseline is no level
    assert levels["random"] == (0.0, "random") and levels["aplite"][1] == "paper"
    assert levels["aplite"][0] == pytest.approx(0.96)  # the leaderboard's mean success over its 50 episodes


def test_main_writes_a_png_per_environment_and_the_page(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    args = ["--agents", str(_agents(tmp_path)), "--results", str(_results(tmp_path)), "--out", str(out)]
    assert learning_curves.main(args) == 0
    page = (out / "LEARNING.md").read_text()
    assert "## polyenvs/APLiteCorridor-v0" in page and "ppo_residual_paper (1 seed)" in page
    assert (out / f"LEARNING_{ENV}.png").read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert [p.name for p in out.glob("*.png")] == [f"LEARNING_{ENV}.png"]


def test_a_missing_directory_is_refused_before_any_work(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        learning_curves.main(["--agents", str(tmp_path / "nowhere"), "--out", str(tmp_path)])
    assert info.value.code == 2 and "--agents" in capsys.readouterr().err
    assert not (tmp_path / "LEARNING.md").exists()
