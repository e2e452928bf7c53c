"""The ``polyenvs`` command line: list, evaluate (table and JSON), leaderboard, and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import polyenvs
from polyenvs.cli import main


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "polyenvs.cli", *args], capture_output=True, text=True, timeout=300)


def test_list_shows_every_id_with_spaces(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for env_id in polyenvs.ENV_IDS:
        assert env_id in out
    assert "Discrete(3)" in out
    assert main(["list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["id"] for r in rows] == polyenvs.ENV_IDS and all(r["description"] for r in rows)


def test_evaluate_json_document(capsys):
    assert (
        main(
            [
                "evaluate",
                "polyenvs/BuckybotWallFollow-v0",
                "--policy",
                "paper",
                "--episodes",
                "2",
                "--seed",
                "3",
                "--json",
            ]
        )
        == 0
    )
    doc = json.loads(capsys.readouterr().out)
    assert doc["env_id"] == "polyenvs/BuckybotWallFollow-v0" and doc["policy"] == "paper"
    assert doc["seeds"] == [3, 4]
    assert [e["seed"] for e in doc["episodes"]] == [3, 4]
    for key in ("wall_distance_error_cm", "perimeter_fraction", "laps", "blocked_tips", "oscillation_events"):
        assert key in doc["episodes"][0]["metrics"]
        assert doc["summary"][key] == pytest.approx(sum(e["metrics"][key] for e in doc["episodes"]) / 2)
    assert doc["summary"]["return"] == pytest.approx(sum(e["return"] for e in doc["episodes"]) / 2)


def test_evaluate_is_reproducible(capsys):
    args = ["evaluate", "polyenvs/BuckybotGoal-v0", "--policy", "random", "--episodes", "2", "--json"]
    main(args)
    first = json.loads(capsys.readouterr().out)
    main(args)
    assert json.loads(capsys.readouterr().out)["episodes"] == first["episodes"]


def test_evaluate_table_and_env_kwargs(capsys):
    assert (
        main(
            [
                "evaluate",
                "polyenvs/BuckybotExplore-v0",
                "--episodes",
                "1",
                "--env-kwargs",
                '{"floor_plan": "rectangle"}',
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "coverage" in out and "mean" in out


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["evaluate", "polyenvs/Nope-v0"], "unknown environment id"),
        (["evaluate", "polyenvs/BuckybotGoal-v0", "--policy", "nope"], "unknown policy"),
        (["evaluate", "polyenvs/BuckybotGoal-v0", "--env-kwargs", "{not json"], "not valid JSON"),
        (["evaluate", "polyenvs/BuckybotGoal-v0", "--env-kwargs", '{"noise_scale": 5}'], "noise_scale"),
        (["evaluate", "polyenvs/BuckybotGoal-v0", "--env-kwargs", '{"nonsense": 1}'], "nonsense"),
        (["evaluate", "polyenvs/BuckybotGoal-v0", "--episodes", "0"], "episodes"),
        (["leaderboard", "--only", "NothingMatches"], "no environment id"),
    ],
)
def test_errors_are_one_line_without_traceback(args, fragment):
    result = run_cli(*args)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0], result.stderr
    assert "Traceback" not in result.stderr


def test_leaderboard_writes_results_and_table(tmp_path: Path):
    results, table = tmp_path / "results", tmp_path / "LEADERBOARD.md"
    args = ["leaderboard", "--episodes", "2", "--only", "Goal", "--results-dir", str(results), "--output", str(table)]
    assert main(args) == 0
    files = sorted(p.name for p in results.glob("*.json"))
    assert files == ["polyenvs__BuckybotGoal-v0__goal_seeker.json", "polyenvs__BuckybotGoal-v0__random.json"]
    doc = json.loads((results / files[0]).read_text())
    assert doc["n_episodes"] == 2 and doc["versions"]["polyenvs"] == polyenvs.__version__ and doc["date"]
    text = table.read_text()
    assert "| goal_seeker | polyenvs/BuckybotGoal-v0 |" in text and "Quick mode" in text
    assert "1.00" in text  # the paper baseline's normalised score is 1 by construction
    assert not list(results.glob("*.tmp"))  # atomic writes leave no temp files
    before = (results / files[0]).stat().st_mtime_ns
    assert main(args) == 0  # a re-run skips what is done
    assert (results / files[0]).stat().st_mtime_ns == before


def test_console_script_is_installed():
    script = Path(sys.executable).parent / "polyenvs"
    if not script.exists():
        pytest.skip("polyenvs is not installed in this interpreter's environment (source checkout only)")
    result = subprocess.run([str(script), "list"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and polyenvs.ENV_IDS[0] in result.stdout


def test_record_writes_a_gif(tmp_path: Path):
    imageio = pytest.importorskip("imageio.v2")
    out = tmp_path / "episode.gif"
    assert main(["record", "polyenvs/BuckybotGoal-v0", "--max-steps", "5", "--output", str(out)]) == 0
    frames = imageio.mimread(out)
    assert 2 <= len(frames) <= 6 and frames[0].shape[-1] in (3, 4)
