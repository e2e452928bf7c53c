"""``polyenvs leaderboard``: result files (atomic, readable, self-healing), where they go, and up-front checks."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import polyenvs
import polyenvs.evaluation.agents
import polyenvs.evaluation.protocol
import polyenvs.evaluation.results
import polyenvs.evaluation.run
import polyenvs.files
from polyenvs.cli import main
from polyenvs.evaluation.results import load_result, result_path
from polyenvs.registry import REGISTRY
from tests.cli_helpers import run_main

ROOT = Path(__file__).resolve().parent.parent
GOAL, WALL = "polyenvs/BuckybotGoal-v0", "polyenvs/BuckybotWallFollow-v0"
#: Each policy on the default layouts and on the held-out ones (layouts="test").
GOAL_FILES = sorted(
    f"polyenvs__BuckybotGoal-v0__{policy}{layouts}.json"
    for policy in ("goal_seeker", "random")
    for layouts in ("", "__layouts-test")
)
GOAL_PLOT = "LEADERBOARD_polyenvs__BuckybotGoal-v0.png"  # beside the table


def leaderboard(tmp_path: Path, *extra: str) -> list[str]:
    """``polyenvs leaderboard`` into ``tmp_path``, over the hand baselines only (an empty agents directory: the
    committed agents have tests of their own, in test_trained_policies.py)."""
    no_agents = tmp_path / "no-agents"
    no_agents.mkdir(exist_ok=True)
    agents = [] if "--agents-dir" in extra else ["--agents-dir", str(no_agents)]
    jobs = [] if "--jobs" in extra else ["--jobs", "1"]  # in this process: a pool's start-up is tested apart
    return [
        "leaderboard",
        "--results-dir",
        str(tmp_path / "results"),
        "--output",
        str(tmp_path / "LEADERBOARD.md"),
        *agents,
        *jobs,
        *extra,
    ]


def assert_one_line_error(code, err, fragment):
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and fragment in lines[0], err


@pytest.fixture
def no_evaluation(monkeypatch):
    """Any evaluation fails the test: for errors that must be reported before the work starts."""

    def evaluate(*args, **kwargs):
        raise AssertionError("an evaluation ran before the arguments were checked")

    monkeypatch.setattr(polyenvs.evaluation.run, "evaluate", evaluate)


def test_leaderboard_writes_results_and_table(tmp_path: Path):
    results, table = tmp_path / "results", tmp_path / "LEADERBOARD.md"
    args = leaderboard(tmp_path, "--episodes", "2", "--only", "Goal")
    assert main(args) == 0
    files = sorted(p.name for p in results.glob("*.json"))
    assert files == GOAL_FILES
    doc = json.loads((results / files[0]).read_text())
    assert doc["n_episodes"] == 2 and doc["versions"]["polyenvs"] == polyenvs.__version__ and doc["date"]
    text = table.read_text()
    assert "| goal_seeker | polyenvs/BuckybotGoal-v0 |" in text and "Quick mode" in text
    # Ranked by the task score (success): the paper's goal seeker reaches the goal in both episodes, random not.
    assert text.index("| goal_seeker | 1 [1, 1] |") < text.index("| random |")
    assert f"]({GOAL_PLOT})" in text and (tmp_path / GOAL_PLOT).read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert not [p for p in tmp_path.rglob("*") if ".tmp" in p.name]  # atomic writes leave no temp files
    before = (results / files[0]).stat().st_mtime_ns
    assert main(args) == 0  # a re-run skips what is done
    assert (results / files[0]).stat().st_mtime_ns == before


# ------------------------------------------------------------------------------------------- result files


@pytest.mark.parametrize(
    "content, why",
    [
        ("", "empty"),
        ('{"env_id": "polyenvs/Bucky', "not valid JSON"),
        ("[1, 2]", "not a results document"),
        ('{"env_id": "polyenvs/BuckybotGoal-v0"}', "missing"),
    ],
)
def test_unusable_result_files_are_redone_and_named(tmp_path, capsys, content, why):
    results = tmp_path / "results"
    results.mkdir()
    broken = result_path(results, GOAL, "goal_seeker")
    broken.write_text(content)
    code, out, err = run_main(leaderboard(tmp_path, "--episodes", "1", "--only", "Goal"), capsys)
    assert code == 0, err
    line = next(line for line in err.splitlines() if "redoing" in line)
    assert str(broken) in line and why in line
    doc, problem = load_result(broken, GOAL, "goal_seeker", 1)
    assert problem is None and doc["n_episodes"] == 1
    assert "| goal_seeker |" in out


def test_a_result_for_another_episode_count_is_redone_with_the_reason(tmp_path, capsys):
    assert main(leaderboard(tmp_path, "--episodes", "1", "--only", "Goal")) == 0
    capsys.readouterr()
    code, _, err = run_main(leaderboard(tmp_path, "--episodes", "2", "--only", "Goal"), capsys)
    assert code == 0
    assert "has 1 episodes, not 2" in err
    for name in GOAL_FILES:
        assert json.loads((tmp_path / "results" / name).read_text())["n_episodes"] == 2


def test_temporary_names_are_hidden_predictable_and_gitignored(tmp_path, monkeypatch):
    """A kill between writing and renaming leaves the temporary file: it must not show up in ``git status``."""
    renamed = []
    real_replace = os.replace

    def spy(src, dst):
        renamed.append((Path(src), Path(dst)))
        real_replace(src, dst)

    monkeypatch.setattr(polyenvs.files.os, "replace", spy)
    assert main(leaderboard(tmp_path, "--episodes", "1", "--only", "Goal")) == 0
    assert {dst.name for _, dst in renamed} == {*GOAL_FILES, "LEADERBOARD.md", GOAL_PLOT}
    for src, dst in renamed:
        assert src.parent == dst.parent
        assert re.fullmatch(rf"\.{re.escape(dst.name)}\.[0-9a-f]+\.tmp", src.name), src.name
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs git and the repository")
    leftovers = [f"{d}/{src.name}" for d in ("benchmarks", "benchmarks/results", ".") for src, _ in renamed]
    leftovers.append("benchmarks/.LEADERBOARD.md.0a1b2c3d.tmp.mp4")  # record keeps the suffix for ffmpeg
    ignored = subprocess.run(
        ["git", "check-ignore", "--no-index", *leftovers], cwd=ROOT, capture_output=True, text=True
    ).stdout.split()
    assert sorted(ignored) == sorted(leftovers)


@pytest.mark.parametrize("umask", [0o022, 0o002])
def test_results_get_the_usual_file_mode(tmp_path, umask):
    old = os.umask(umask)
    try:
        assert main(leaderboard(tmp_path, "--episodes", "1", "--only", "Goal")) == 0
    finally:
        os.umask(old)
    expected = 0o666 & ~umask
    for path in [tmp_path / "LEADERBOARD.md", tmp_path / GOAL_PLOT, *(tmp_path / "results").iterdir()]:
        assert path.stat().st_mode & 0o777 == expected, path


def test_write_text_atomic_keeps_the_old_file_when_writing_fails(tmp_path, monkeypatch):
    target = tmp_path / "table.md"
    target.write_text("old")

    def fail(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(polyenvs.files.os, "replace", fail)
    with pytest.raises(OSError, match="disk full"):
        polyenvs.files.write_text_atomic(target, "new")
    assert target.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["table.md"]


def _fake_result(env_id: str, policy: str, returns: list[float]) -> dict:
    return {
        "env_id": env_id,
        "policy": policy,
        "policy_description": {"name": policy},
        "env_kwargs": {},
        "seeds": list(range(1000, 1000 + len(returns))),
        "episodes": [
            {"seed": 1000 + i, "return": r, "length": 10, "metrics": {"laps": 1.0}} for i, r in enumerate(returns)
        ],
        "summary": {"return": sum(returns) / len(returns), "length": 10.0, "laps": 1.0},
        "n_episodes": len(returns),
    }


def test_only_keeps_the_other_environments_in_the_table(tmp_path, capsys):
    results = tmp_path / "results"
    results.mkdir()
    for policy, returns in [("random", [-5.0, -7.0]), ("wall_follower", [100.0, 120.0])]:
        result_path(results, WALL, policy).write_text(json.dumps(_fake_result(WALL, policy, returns)))
    result_path(results, WALL, "wall_follower_rules").write_text("{broken")
    wall_mtimes = {p.name: p.stat().st_mtime_ns for p in results.iterdir()}
    code, out, err = run_main(leaderboard(tmp_path, "--episodes", "2", "--only", "Goal"), capsys)
    assert code == 0, err
    text = (tmp_path / "LEADERBOARD.md").read_text()
    assert f"## {WALL}" in text and f"## {GOAL}" in text
    assert text.index(f"## {WALL}") < text.index(f"## {GOAL}")  # registry order
    assert f"| wall_follower | {WALL} |" in text and f"| goal_seeker | {GOAL} |" in text
    assert "wall_follower_rules" not in text and "left out of the table" in err and "wall_follower_rules" in err
    # Only the selected environment was evaluated: the others' files are untouched.
    assert {p.name: p.stat().st_mtime_ns for p in results.iterdir() if "WallFollow" in p.name} == wall_mtimes


# --------------------------------------------------------------------------------- where results are written


def test_default_run_writes_to_an_untracked_directory(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    shutil.copytree(ROOT / "benchmarks" / "results", tmp_path / "benchmarks" / "results")
    (tmp_path / "benchmarks" / "LEADERBOARD.md").write_text("reference")
    (tmp_path / "benchmarks" / "agents").mkdir()  # found here first: no agents (the checkout's are tested apart)
    before = {p.name: p.read_bytes() for p in (tmp_path / "benchmarks" / "results").iterdir()}
    code, _, err = run_main(["leaderboard", "--quick", "--episodes", "1", "--only", "Goal"], capsys)
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "runs" / "leaderboard" / "results").iterdir()) == GOAL_FILES
    assert (tmp_path / "runs" / "leaderboard" / "LEADERBOARD.md").is_file()
    assert {p.name: p.read_bytes() for p in (tmp_path / "benchmarks" / "results").iterdir()} == before
    assert (tmp_path / "benchmarks" / "LEADERBOARD.md").read_text() == "reference"


def test_default_directory_is_gitignored():
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs git and the repository")
    paths = ["runs/leaderboard/LEADERBOARD.md", "runs/leaderboard/results/polyenvs__BuckybotGoal-v0__random.json"]
    result = subprocess.run(["git", "check-ignore", "--no-index", *paths], cwd=ROOT, capture_output=True, text=True)
    assert result.stdout.split() == paths


def test_update_reference_refreshes_the_committed_files(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(polyenvs.evaluation.protocol, "PROTOCOL_EPISODES", 2)  # the protocol's 50, made fast
    reference = tmp_path / "benchmarks" / "results"
    reference.mkdir(parents=True)
    stale = _fake_result(GOAL, "goal_seeker", [1.0, 2.0])
    result_path(reference, GOAL, "goal_seeker").write_text(json.dumps(stale))  # same count: redone all the same
    code, _, err = run_main(["leaderboard", "--update-reference", "--only", "Goal"], capsys)
    assert code == 0, err
    assert sorted(p.name for p in reference.iterdir()) == GOAL_FILES
    doc = json.loads(result_path(reference, GOAL, "goal_seeker").read_text())
    assert doc["n_episodes"] == 2 and doc["episodes"] != stale["episodes"] and "date" in doc
    assert f"| goal_seeker | {GOAL} |" in (tmp_path / "benchmarks" / "LEADERBOARD.md").read_text()
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize(
    "extra, fragment",
    [
        (["--quick"], "--quick"),
        (["--episodes", "10"], "--episodes"),
        (["--results-dir", "elsewhere"], "--results-dir"),
        (["--output", "elsewhere.md"], "--output"),
        (["--agents-dir", "elsewhere"], "--agents-dir"),
        (["--policy", "runs/ppo"], "--policy"),
    ],
)
def test_update_reference_refuses_other_protocols(tmp_path, monkeypatch, capsys, no_evaluation, extra, fragment):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "benchmarks" / "results").mkdir(parents=True)
    code, _, err = run_main(["leaderboard", "--update-reference", *extra], capsys)
    assert_one_line_error(code, err, "--update-reference")
    assert fragment in err
    assert list((tmp_path / "benchmarks" / "results").iterdir()) == []


def test_update_reference_outside_the_repository_is_refused(tmp_path, monkeypatch, capsys, no_evaluation):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_main(["leaderboard", "--update-reference"], capsys)
    assert_one_line_error(code, err, "repository root")
    assert list(tmp_path.iterdir()) == []


def _reference_of_goal(tmp_path, monkeypatch, capsys, episodes: int = 3) -> Path:
    """A reference of BuckybotGoal in ``tmp_path`` (the current directory): ``episodes`` per policy and layouts."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(polyenvs.evaluation.protocol, "PROTOCOL_EPISODES", episodes)
    reference = tmp_path / "benchmarks" / "results"
    reference.mkdir(parents=True)
    code, _, err = run_main(["leaderboard", "--update-reference", "--only", "Goal", "--jobs", "1"], capsys)
    assert code == 0, err
    return reference


def test_reproduce_checks_every_evaluation_of_the_reference_episode_by_episode(tmp_path, monkeypatch, capsys):
    reference = _reference_of_goal(tmp_path, monkeypatch, capsys)
    reproduce = ["leaderboard", "--reproduce", "--episodes", "2", "--only", "Goal", "--jobs", "1"]
    code, out, err = run_main(reproduce, capsys)
    assert code == 0, err
    assert "reproduced 8 episodes of the reference exactly (sample in runs/leaderboard/reproduce)" in err
    assert sorted(p.name for p in (tmp_path / "runs" / "leaderboard" / "reproduce").iterdir()) == GOAL_FILES
    table = (tmp_path / "runs" / "leaderboard" / "LEADERBOARD.md").read_text()
    assert out.strip() == table.strip() and "3 evaluation episodes" in table  # the reference's table, not the sample's

    # A reference episode the code no longer produces (its last bit changed): named, and the exit status says so.
    path = result_path(reference, GOAL, "goal_seeker", "test")
    doc = json.loads(path.read_text())
    doc["episodes"][1]["return"] = float(np.nextafter(doc["episodes"][1]["return"], np.inf))
    path.write_text(json.dumps(doc))
    code, _, err = run_main(reproduce, capsys)  # the sample is reused: only the comparison runs again
    assert code == 1
    assert f"{GOAL} goal_seeker (layouts=test): seeds 1001 differ from the reference" in err
    assert "reproduced 7 episodes of the reference exactly; 1 evaluation differ" in err


def test_reproduce_matches_an_agent_by_its_row_and_seed_wherever_it_was_found():
    def doc(policy: str, returns: list[float], label: str = "ppo") -> dict:
        episodes = [{"seed": 1000 + i, "return": r, "length": 5, "metrics": {"m": r}} for i, r in enumerate(returns)]
        agent = {"algo": "ppo", "label": label, "training_seed": 0}
        return {"env_id": GOAL, "policy": policy, "episodes": episodes, "agent": agent, "env_kwargs": {}}

    reference = [
        doc("benchmarks/agents/polyenvs__BuckybotGoal-v0/ppo/seed0", [1.0, 2.0, 3.0]),
        doc("benchmarks/agents/polyenvs__BuckybotGoal-v0/ppo_residual_paper/seed0", [4.0] * 3, "ppo_residual_paper"),
    ]
    same = polyenvs.evaluation.results.compare_with_reference([doc("/elsewhere/ppo/seed0", [1.0, 2.0])], reference)
    assert (same.same, same.differ, same.absent) == (2, [], [])
    other = polyenvs.evaluation.results.compare_with_reference([doc("/elsewhere/ppo/seed0", [1.0, 2.5])], reference)
    assert other.same == 1 and other.differ == [f"{GOAL} ppo seed0: seeds 1001 differ from the reference"]
    longer = polyenvs.evaluation.results.compare_with_reference([doc("x", [1.0, 2.0, 3.0, 4.0])], reference)
    assert longer.same == 0 and "the reference has 3 episodes" in longer.absent[0]
    # A metric added since the reference was made (the beasts' power) is not compared; one it recorded is.
    added = doc("x", [1.0, 2.0])
    for episode in added["episodes"]:
        episode["metrics"]["mean_power_w"] = 3.0
    assert polyenvs.evaluation.results.compare_with_reference([added], reference).same == 2
    added["episodes"][0]["metrics"]["m"] = 1.5
    assert polyenvs.evaluation.results.compare_with_reference([added], reference).same == 1
    del added["episodes"][1]["metrics"]["m"]  # one it recorded and the code no longer reports
    assert polyenvs.evaluation.results.compare_with_reference([added], reference).same == 0


@pytest.mark.parametrize("extra", [["--quick"], ["--update-reference"], ["--agents-dir", "."], ["--policy", "x"]])
def test_reproduce_refuses_flags_that_change_what_the_reference_holds(
    tmp_path, monkeypatch, capsys, no_evaluation, extra
):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "benchmarks" / "results").mkdir(parents=True)
    code, _, err = run_main(["leaderboard", "--reproduce", *extra], capsys)
    assert_one_line_error(code, err, f"do not combine it with {extra[0]}")
    assert not (tmp_path / "runs").exists()


def test_reproduce_without_a_reference_says_where_it_looked(tmp_path, monkeypatch, capsys, no_evaluation):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(
        polyenvs.evaluation.agents, "checkout_dirs", lambda relative: [Path(relative)]
    )  # an installed copy
    code, _, err = run_main(["leaderboard", "--reproduce"], capsys)
    assert_one_line_error(code, err, f"no reference results ({tmp_path / 'benchmarks' / 'results'})")
    assert list(tmp_path.iterdir()) == []


def test_readme_main_command_does_not_rewrite_committed_results():
    readme = (ROOT / "README.md").read_text()
    setup = readme[readme.index("## Set-up on a fresh machine") : readme.index("## Install")]
    code = "\n".join(re.findall(r"```bash\n(.*?)```", setup, flags=re.S))
    commands = [line for line in code.splitlines() if "polyenvs leaderboard" in line and not line.startswith("#")]
    assert commands, "the set-up section runs the leaderboard"
    for command in commands:
        assert "--redo" not in command and "--update-reference" not in command and "--quick" not in command


# ------------------------------------------------------------------------------- checks before any work


def test_unwritable_results_dir_is_refused_before_evaluating(tmp_path, capsys, no_evaluation):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for results_dir in (blocker / "results", blocker):
        args = ["leaderboard", "--results-dir", str(results_dir), "--output", str(tmp_path / "L.md")]
        code, _, err = run_main(args, capsys)
        assert_one_line_error(code, err, "--results-dir")
        assert "not a directory" in err
    assert [p.name for p in tmp_path.iterdir()] == ["a_file"]


def test_output_that_is_a_directory_is_refused_before_evaluating(tmp_path, capsys, no_evaluation):
    code, _, err = run_main(["leaderboard", "--results-dir", str(tmp_path / "r"), "--output", str(tmp_path)], capsys)
    assert_one_line_error(code, err, "--output")
    assert "is a directory" in err
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    code, _, err = run_main(
        ["leaderboard", "--results-dir", str(tmp_path / "r"), "--output", str(blocker / "L.md")], capsys
    )
    assert_one_line_error(code, err, "--output")
    assert [p.name for p in tmp_path.iterdir()] == ["a_file"]  # the results directory was not even created


@pytest.mark.skipif(not Path("/proc/self").exists(), reason="needs /proc")
@pytest.mark.parametrize("flag", ["--results-dir", "--output"])
def test_paths_under_proc_are_one_line_before_any_evaluation(flag, tmp_path):
    args = {"--results-dir": str(tmp_path / "r"), "--output": str(tmp_path / "L.md")}
    args[flag] = "/proc/nope" if flag == "--results-dir" else "/proc/nope.md"
    result = subprocess.run(
        [sys.executable, "-m", "polyenvs.cli", "leaderboard", "--episodes", "1", *sum(args.items(), ())],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and flag in lines[0] and "/proc" in lines[0], result.stderr
    assert "episodes ..." not in result.stderr and list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------------------------- progress


class FakeTerminal:
    def __init__(self):
        self.parts = []

    def write(self, text):
        self.parts.append(text)

    def flush(self):
        pass

    def isatty(self):
        return True

    def getvalue(self):
        return "".join(self.parts)


def test_leaderboard_shows_progress_on_a_terminal(tmp_path, monkeypatch, capsys):
    terminal = FakeTerminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(leaderboard(tmp_path, "--episodes", "2", "--only", "Goal")) == 0
    text = terminal.getvalue()
    assert "8/8 episodes" in text and "1/8 episodes" in text  # 2 policies x 2 layouts x 2 episodes, one bar
    assert "goal_seeker: 2 episodes" in text
    assert capsys.readouterr().out.startswith("# polyenvs leaderboard")


# ------------------------------------------------------------------------------------------- trained agents


def test_the_leaderboard_says_where_it_found_the_agents_from_any_directory(tmp_path, monkeypatch, capsys):
    """Run from elsewhere, it used to look for benchmarks/agents in the current directory only and silently
    evaluate no agent; now it also looks in the checkout it runs from, and says where and what it found."""
    monkeypatch.chdir(tmp_path)
    seeds = sorted((ROOT / "benchmarks" / "agents" / "polyenvs__BumperCartExplore-v0" / "ppo").iterdir())
    code, out, err = run_main(
        ["leaderboard", "--only", "BumperCartExplore-v0", "--episodes", "1", "--results-dir", str(tmp_path / "r"),
         "--output", str(tmp_path / "L.md")],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    line = f"trained agents: {len(seeds)} (ppo) for 1 of 1 environment, from {ROOT / 'benchmarks' / 'agents'}"
    assert line in err.splitlines(), err
    assert "| ppo | polyenvs/BumperCartExplore-v0 |" in out


def test_the_leaderboard_says_why_it_found_no_agents(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    empty = tmp_path / "agents"
    empty.mkdir()
    argv = ["leaderboard", "--only", "BumperCartExplore-v0", "--episodes", "1", "--results-dir", str(tmp_path / "r"),
            "--output", str(tmp_path / "L.md")]  # fmt: skip
    code, out, err = run_main([*argv, "--agents-dir", str(empty)], capsys)
    assert code == 0, err
    assert f"trained agents: none in {empty} for the 1 environment run (it has no <env id" in err
    # An installed package without a checkout beside it (the fresh-venv case): nowhere to look but here.
    monkeypatch.setattr(polyenvs.evaluation.agents, "default_agents_dirs", lambda: [Path("benchmarks/agents")])
    code, out, err = run_main(argv, capsys)
    assert code == 0, err
    assert (
        f"trained agents: none found (no {tmp_path / 'benchmarks' / 'agents'}; the committed agents are in the "
        "polyenvs repository's benchmarks/agents/, which an installed package does not include" in err
    )
    assert "| ppo |" not in out


def _without_mujoco(monkeypatch):
    """As in a ``pip install ".[train]"`` without the mujoco extra: importing mujoco fails."""
    import builtins

    real_import = builtins.__import__

    def no_mujoco(name, *args, **kwargs):
        if name == "mujoco" or name.startswith("mujoco."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return real_import(name, *args, **kwargs)

    for module in [m for m in sys.modules if m.startswith(("gymnasium.envs.mujoco", "polyenvs.beast", "mujoco"))]:
        monkeypatch.delitem(sys.modules, module)
    monkeypatch.setattr(builtins, "__import__", no_mujoco)


def test_environments_whose_packages_are_missing_are_left_out_before_any_evaluation(tmp_path, monkeypatch, capsys):
    """``polyenvs leaderboard --quick`` after ``pip install ".[train]"`` evaluated the Buckybot ids, then stopped at
    BeastTumble-v0 with "needs the package 'mujoco'" (exit 2, after minutes of work)."""
    _without_mujoco(monkeypatch)
    code, out, err = run_main(leaderboard(tmp_path, "--only", "ll", "--episodes", "1"), capsys)  # WallFollow, Roll
    assert code == 0, err
    rolls = ", ".join(e.id for e in REGISTRY if e.extra == "mujoco" and "ll" in e.id)  # every BeastRoll version
    assert (
        f'left out: {rolls} need{"s" if "," not in rolls else ""} packages that are not installed: pip install ".[mujoco]" in a polyenvs clone'
        in err.splitlines()
    )
    assert "## polyenvs/BuckybotWallFollow-v0" in out and "BeastRoll" not in out
    code, out, err = run_main(leaderboard(tmp_path, "--only", "Beast", "--episodes", "1", "--redo"), capsys)
    beasts = ", ".join(e.id for e in REGISTRY if e.extra == "mujoco")
    assert_one_line_error(code, err, f"{beasts} need")
    assert 'need packages that are not installed: pip install ".[mujoco]" in a polyenvs clone' in err


def test_the_pool_takes_the_longest_evaluations_first(tmp_path, monkeypatch):
    """Longest first (by the row's step limit), so two workers finish together: the 300-step Goal evaluations go
    after the 500-step WallFollow ones although the plan lists Goal first."""
    import polyenvs.pool

    submitted = []

    def record(work, jobs, workers, on_result, on_error):
        submitted.extend(job[1] for job in jobs)

    monkeypatch.setattr(polyenvs.pool, "run_local", record)
    polyenvs.evaluation.run.run_leaderboard(
        [GOAL, WALL],
        1,
        results_dir=tmp_path,
        listeners=polyenvs.evaluation.run.Listeners(progress=lambda _: None),
        workers=2,
    )
    assert submitted[0] == WALL and submitted[-1] == GOAL
    assert submitted == sorted(submitted, key=lambda env_id: -polyenvs.evaluation.run.step_budget(env_id))
