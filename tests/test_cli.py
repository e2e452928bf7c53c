"""The ``polyenvs`` command line: list, evaluate (table and JSON), record, and one-line errors checked up front.

The leaderboard command (result files, default and reference paths, progress) is in ``test_leaderboard.py``.
"""

from __future__ import annotations

import io
import json
import math
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import gymnasium as gym
import pytest

import polyenvs
from baselines import make_policy
from polyenvs.cli import main
from polyenvs.commands.flags import ProgressBar
from tests.cli_helpers import run_main

ROOT = Path(__file__).resolve().parent.parent
GOAL, WALL, EXPLORE = "polyenvs/BuckybotGoal-v0", "polyenvs/BuckybotWallFollow-v0", "polyenvs/BuckybotExplore-v0"
QUICK_GOAL = ["leaderboard", "--only", "BuckybotGoal", "--episodes", "1", "--jobs", "1"]


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "polyenvs.cli", *args], capture_output=True, text=True, timeout=300, cwd=ROOT
    )


def assert_one_line_error(code: int, err: str, fragment: str) -> None:
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and fragment in lines[0], err
    assert "Traceback" not in err


class FakeTerminal(io.StringIO):
    def isatty(self):
        return True


def test_list_shows_every_id_with_spaces(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for env_id in polyenvs.registry.ALL_IDS:
        assert env_id in out
    assert "Discrete(3)" in out
    assert main(["list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["id"] for r in rows] == polyenvs.registry.ALL_IDS and all(r["description"] for r in rows)
    assert [r["superseded_by"] for r in rows] == [e.superseded_by for e in polyenvs.registry.REGISTRY]
    assert all(r["missing"] is None and r["action_space"] for r in rows)  # every extra is installed here


def test_superseded_ids_are_named_in_one_line_of_our_own_never_in_gymnasiums_warning():
    """Gymnasium's two-line "out of date" warning reached the user for every -v0 id: ten lines from ``polyenvs
    list``, two before ``localize``'s one-line error (its default id is one), two on an evaluation of one."""
    superseded = [e for e in polyenvs.registry.REGISTRY if e.superseded_by is not None]
    listed = run_cli("list")
    assert listed.returncode == 0 and listed.stderr == "", listed.stderr
    for row in superseded:
        assert f"(superseded by {row.superseded_by})" in next(
            line for line in listed.stdout.splitlines() if line.startswith(f"{row.id} ")
        )
    localize = run_cli("localize", "--map", "nope")
    assert localize.returncode == 2 and len(localize.stderr.splitlines()) == 1, localize.stderr
    old = next(e for e in superseded if e.family == "bumper")
    evaluated = run_cli("evaluate", old.id, "--episodes", "1")
    assert evaluated.returncode == 0, evaluated.stderr
    assert evaluated.stderr.splitlines() == [
        f"polyenvs evaluate: note: {old.id} is superseded by {old.superseded_by} (kept registered, unchanged, for "
        "the results made with it)"
    ]


def test_evaluate_json_document(capsys):
    assert main(["evaluate", WALL, "--policy", "paper", "--episodes", "2", "--seed", "3", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["env_id"] == WALL and doc["policy"] == "paper"
    assert doc["seeds"] == [3, 4]
    assert [e["seed"] for e in doc["episodes"]] == [3, 4]
    for key in ("wall_distance_error_cm", "perimeter_fraction", "laps", "blocked_tips", "oscillation_events"):
        assert key in doc["episodes"][0]["metrics"]
        assert doc["summary"][key] == pytest.approx(sum(e["metrics"][key] for e in doc["episodes"]) / 2)
    assert doc["summary"]["return"] == pytest.approx(sum(e["return"] for e in doc["episodes"]) / 2)


def test_evaluate_is_reproducible(capsys):
    args = ["evaluate", GOAL, "--policy", "random", "--episodes", "2", "--json"]
    main(args)
    first = json.loads(capsys.readouterr().out)
    main(args)
    assert json.loads(capsys.readouterr().out)["episodes"] == first["episodes"]


def test_evaluate_table_and_env_kwargs(capsys):
    assert main(["evaluate", EXPLORE, "--episodes", "1", "--env-kwargs", '{"floor_plan": "rectangle"}']) == 0
    out = capsys.readouterr().out
    assert "coverage" in out and "mean" in out and "floor_plan=rectangle" in out


def test_evaluate_table_is_aligned_and_describes_the_policy_readably(capsys):
    assert main(["evaluate", GOAL, "--episodes", "2"]) == 0
    out = capsys.readouterr().out
    assert "goal_seeker (clearance_cm=40)" in out  # "paper" resolved, parameters as name=value
    assert "{" not in out and "'name'" not in out  # not a raw dict
    lines = out.splitlines()
    table = lines[next(i for i, line in enumerate(lines) if line.split()[:1] == ["seed"]) :]
    assert [line.split()[0] for line in table] == ["seed", "0", "1", "mean"]
    # Right-aligned columns: every row as long as the header, and every header name ends where its values end.
    assert len({len(line) for line in table}) == 1, table
    header_ends = [m.end() for m in re.finditer(r"\S+", table[0])]
    for line in table[1:]:
        assert [m.end() for m in re.finditer(r"\S+", line)] == header_ends, (table[0], line)


def test_evaluate_describes_wall_follower_parameters(capsys):
    assert main(["evaluate", WALL, "--policy", "wall_follower_rules", "--episodes", "1"]) == 0
    out = capsys.readouterr().out
    assert "wall_follower_rules (d_star_cm=50, x_s_cm=30, no_backtrack=true, clockwise_exception=true" in out


def test_evaluate_progress_bar_on_a_terminal_keeps_json_clean(capsys, monkeypatch):
    terminal = FakeTerminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(["evaluate", GOAL, "--episodes", "3", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)  # stdout is exactly one JSON document
    assert len(doc["episodes"]) == 3
    bar = terminal.getvalue()
    assert "3/3 episodes" in bar and "1/3 episodes" in bar and "[" + "#" * 30 + "]" in bar


def test_evaluate_without_a_terminal_prints_no_progress(capsys):
    assert main(["evaluate", GOAL, "--episodes", "2", "--json"]) == 0
    captured = capsys.readouterr()
    json.loads(captured.out)
    assert captured.err == ""


def test_progress_bar_renders_counts_and_stays_silent_off_a_terminal():
    stream = FakeTerminal()
    bar = ProgressBar("episodes", stream=stream)
    bar.start(4, label="goal_seeker")
    bar.advance()
    assert "goal_seeker [" + "#" * 8 + "." * 22 + "] 1/4 episodes" in bar.render()
    bar.message("a note")
    bar.advance(3)
    bar.close()
    text = stream.getvalue()
    assert "a note\n" in text and "4/4 episodes" in text and text.endswith("\n")
    quiet = io.StringIO()
    bar = ProgressBar("episodes", stream=quiet)
    bar.start(2)
    bar.advance(2)
    bar.message("only messages")
    bar.close()
    assert quiet.getvalue() == "only messages\n"


# ------------------------------------------------------------------------------------------ one-line errors


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["evaluate", "polyenvs/Nope-v0"], "unknown environment id"),
        (["evaluate", GOAL, "--policy", "nope"], "unknown policy"),
        (["evaluate", GOAL, "--env-kwargs", "{not json"], "not valid JSON"),
        (["evaluate", GOAL, "--env-kwargs", '{"noise_scale": 5}'], "noise_scale"),
        (["evaluate", GOAL, "--env-kwargs", '{"nonsense": 1}'], "nonsense"),
        (["evaluate", GOAL, "--episodes", "0"], "episodes"),
        (["evaluate", GOAL, "--seed", "-1"], "--seed"),
        (["record", GOAL, "--seed", "-1"], "--seed"),
        (["record", GOAL, "--fps", "-1"], "--fps"),
        (["leaderboard", "--only", "NothingMatches"], "no environment id"),
    ],
)
def test_errors_are_one_line_without_traceback(args, fragment):
    result = run_cli(*args)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0], result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["evaluate", GOAL, "--seed", "-1"], "--seed"),
        (["evaluate", GOAL, "--seed", "abc"], "--seed"),
        (["evaluate", GOAL, "--episodes", "-3"], "--episodes"),
        (["evaluate", GOAL, "--episodes", "1.5"], "--episodes"),
        (["evaluate", GOAL, "--policy-kwargs", "[1]"], "--policy-kwargs"),
        (["evaluate", GOAL, "--policy-kwargs", '{"clearance_cm": NaN}'], "clearance_cm"),
        (["evaluate", GOAL, "--policy-kwargs", '{"nonsense": 1}'], "nonsense"),
        (["evaluate", GOAL, "--policy", "random", "--policy-kwargs", '{"x": 1}'], "random"),
        (["evaluate", WALL, "--policy", "wall_follower", "--policy-kwargs", '{"d_star_cm": NaN}'], "d_star_cm"),
        (["evaluate", WALL, "--policy", "wall_follower", "--policy-kwargs", '{"x_s_cm": Infinity}'], "x_s_cm"),
        (["evaluate", WALL, "--policy-kwargs", '{"no_backtrack": "false"}'], "no_backtrack"),
        (["evaluate", WALL, "--policy-kwargs", '{"too_close_cm": true}'], "too_close_cm"),
        (["record", GOAL, "--seed", "-1"], "--seed"),
        (["record", GOAL, "--max-steps", "-5"], "--max-steps"),
        (["record", GOAL, "--max-steps", "0"], "--max-steps"),
        (["record", GOAL, "--fps", "-1"], "--fps"),
        (["record", GOAL, "--fps", "0"], "--fps"),
        (["record", GOAL, "--fps", "nan"], "--fps"),
        (["record", GOAL, "--fps", "inf"], "--fps"),
        (["record", GOAL, "--fps", "fast"], "--fps"),
        (["record", GOAL, "--output", "episode.png"], ".gif or .mp4"),
        (["record", "polyenvs/Nope-v0"], "unknown environment id"),
        # Gymnasium's own help for a typo'd id, and ours for a module path
        (["evaluate", "polyenvs/BuckybotWalFollow-v0"], "Did you mean: `BuckybotWallFollow`?"),
        (["evaluate", "polyenvs/BeastRoll-v99"], "It provides versioned environments: [ `v0`, `v1`"),
        (["evaluate", "polyenv/BuckybotGoal-v0"], "Namespace polyenv not found. Did you mean: `polyenvs`?"),
        (["evaluate", "polyenvs.swarm.coridor_v0"], "Did you mean: `polyenvs.swarm.corridor_v0`?"),
        (["record", "formation_v0"], "Did you mean: `polyenvs.swarm.formation_v0`?"),
        (["collect", "polyenvs/BuckybotGoal-v99", "--out", "d"], "It provides versioned environments: [ `v0`"),
        (["record", GOAL, "--env-kwargs", '{"nonsense": 1}'], "nonsense"),
        (["record", GOAL, "--policy-kwargs", '{"clearance_cm": -1}'], "clearance_cm"),
        (["leaderboard", "--episodes", "0"], "--episodes"),
        # with a run that is short where a wrong check lets it go ahead (a result file in the directory fails it)
        ([*QUICK_GOAL, "--backend", "slurm"], "--backend must be one of local, ray, got 'slurm'"),
        ([*QUICK_GOAL, "--address", "auto"], "--address joins a Ray cluster: it needs --backend ray"),
        ([*QUICK_GOAL, "--backend", "local", "--address", "auto"], "--address joins a Ray cluster"),
        (["evaluate"], "env_id"),
        ([], "command"),
    ],
)
def test_bad_arguments_are_one_line_naming_the_flag(args, fragment, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a record that wrongly went ahead would write episode.gif here
    code, out, err = run_main(args, capsys)
    assert_one_line_error(code, err, fragment)
    assert list(tmp_path.iterdir()) == []


def test_the_leaderboard_on_ray_without_ray_gives_the_install_hint(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    monkeypatch.chdir(tmp_path)
    code, _, err = run_main([*QUICK_GOAL, "--backend", "ray"], capsys)
    assert_one_line_error(code, err, 'the ray backend needs Ray: pip install ".[distributed]" in a polyenvs clone')
    assert list(tmp_path.iterdir()) == []  # refused before any evaluation


def test_unexpected_errors_inside_an_environment_show_their_traceback(monkeypatch, capsys):
    """A bug (here a KeyError or ValueError from step) is not a user error: it must not become one tidy line."""
    from polyenvs.buckybot.goal import BuckybotGoalEnv

    def broken_step(self, action):
        raise KeyError("internal table")

    monkeypatch.setattr(BuckybotGoalEnv, "step", broken_step)
    with pytest.raises(KeyError, match="internal table"):
        main(["evaluate", GOAL, "--episodes", "1"])

    def broken_step_value(self, action):
        raise ValueError("internal invariant")

    monkeypatch.setattr(BuckybotGoalEnv, "step", broken_step_value)
    with pytest.raises(ValueError, match="internal invariant"):
        main(["evaluate", GOAL, "--episodes", "1"])
    assert "error:" not in capsys.readouterr().err


def test_unexpected_error_exits_with_a_traceback_in_a_subprocess():
    code = (
        "import sys\n"
        "from polyenvs.buckybot.goal import BuckybotGoalEnv\n"
        "def step(self, action): raise KeyError('internal table')\n"
        "BuckybotGoalEnv.step = step\n"
        "from polyenvs.cli import main\n"
        "sys.exit(main(['evaluate', 'polyenvs/BuckybotGoal-v0', '--episodes', '1']))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert result.returncode not in (0, 2)
    assert "Traceback" in result.stderr and "KeyError: 'internal table'" in result.stderr


# ------------------------------------------------------------------------------- baseline parameters


@pytest.mark.parametrize(
    "env_id, policy, name, value",
    [
        (WALL, "wall_follower", "d_star_cm", float("nan")),
        (WALL, "wall_follower", "d_star_cm", float("inf")),
        (WALL, "wall_follower", "d_star_cm", 0.0),
        (WALL, "wall_follower", "d_star_cm", 5.0),  # inside the body
        (WALL, "wall_follower", "d_star_cm", 500.0),  # beyond the sonar
        (WALL, "wall_follower", "d_star_cm", True),
        (WALL, "wall_follower", "d_star_cm", "50"),
        (WALL, "wall_follower", "d_star_cm", None),
        (WALL, "wall_follower", "x_s_cm", float("nan")),
        (WALL, "wall_follower", "x_s_cm", -1.0),
        (WALL, "wall_follower", "x_s_cm", 1e6),
        (WALL, "wall_follower", "x_s_cm", False),
        (WALL, "wall_follower", "too_close_cm", 0.0),
        (WALL, "wall_follower", "too_close_cm", float("-inf")),
        (WALL, "wall_follower", "too_close_cm", 100.0),  # a too-close reading is under the 30.48 cm minimum
        (WALL, "wall_follower", "too_close_cm", "20"),
        (WALL, "wall_follower", "no_backtrack", "false"),
        (WALL, "wall_follower", "clockwise_exception", 1),
        (WALL, "wall_follower", "avoid_failed_tip", None),
        (WALL, "wall_follower_rules", "x_s_cm", float("nan")),
        (EXPLORE, "wall_follow_explorer", "d_star_cm", float("nan")),
        (EXPLORE, "wall_follow_explorer", "no_backtrack", "yes"),
        (GOAL, "goal_seeker", "clearance_cm", float("nan")),
        (GOAL, "goal_seeker", "clearance_cm", 0.0),
        (GOAL, "goal_seeker", "clearance_cm", -40.0),
        (GOAL, "goal_seeker", "clearance_cm", 1000.0),
        (GOAL, "goal_seeker", "clearance_cm", True),
        (GOAL, "goal_seeker", "clearance_cm", "40"),
    ],
)
def test_baseline_parameters_are_validated(env_id, policy, name, value):
    env = gym.make(env_id)
    with pytest.raises(ValueError, match=name):
        make_policy(policy, env_id, env.observation_space, env.action_space, **{name: value})
    env.close()


@pytest.mark.parametrize(
    "env_id, policy, kwargs",
    [
        (WALL, "wall_follower", {}),
        (WALL, "wall_follower", {"d_star_cm": 13, "x_s_cm": 0, "too_close_cm": 30.48, "no_backtrack": True}),
        (WALL, "wall_follower", {"d_star_cm": 182.88, "x_s_cm": 182.88, "avoid_failed_tip": False}),
        (EXPLORE, "wall_follow_explorer", {"x_s_cm": 40.0}),
        (GOAL, "goal_seeker", {"clearance_cm": 25}),
    ],
)
def test_plausible_baseline_parameters_are_accepted(env_id, policy, kwargs):
    env = gym.make(env_id)
    agent = make_policy(policy, env_id, env.observation_space, env.action_space, **kwargs)
    description = agent.describe()
    for key, value in kwargs.items():
        assert description.get(key, value) == value
        assert not isinstance(value, float) or math.isfinite(description.get(key, value))
    obs, _ = env.reset(seed=0)
    action, _ = agent.predict(obs, episode_start=[True])
    assert env.action_space.contains(int(action))
    env.close()


# --------------------------------------------------------------------------------------------------- record


def test_record_writes_a_gif(tmp_path: Path):
    imageio = pytest.importorskip("imageio.v3")
    out = tmp_path / "episode.gif"
    assert main(["record", GOAL, "--max-steps", "5", "--fps", "4", "--output", str(out)]) == 0
    frames = imageio.imread(out, index=None)
    assert 2 <= len(frames) <= 6 and frames[0].shape[-1] in (3, 4)
    assert imageio.immeta(out)["duration"] == 250  # ms per frame at 4 fps
    assert [p.name for p in tmp_path.iterdir()] == ["episode.gif"]  # no temporary file left
    assert (out.stat().st_mode & 0o777) != 0o600


def test_record_keeps_every_kth_frame_and_a_swarm_records_too(tmp_path: Path):
    imageio = pytest.importorskip("imageio.v3")
    out = tmp_path / "episode.gif"
    assert main(["record", GOAL, "--max-steps", "9", "--every", "4", "--output", str(out)]) == 0
    frames = imageio.imread(out, index=None)
    assert len(frames) == 3  # the reset, steps 4 and 8 (the episode runs on past step 9)
    swarm = tmp_path / "swarm.gif"
    args = ["record", "polyenvs.swarm.corridor_v0", "--max-steps", "4", "--output", str(swarm)]
    assert main([*args, "--env-kwargs", '{"n_robots": 2}']) == 0
    assert len(imageio.imread(swarm, index=None)) == 5


def test_record_writes_an_mp4(tmp_path: Path):
    pytest.importorskip("imageio_ffmpeg")
    imageio = pytest.importorskip("imageio.v3")
    out = tmp_path / "episode.mp4"
    assert main(["record", GOAL, "--max-steps", "3", "--output", str(out)]) == 0
    frames = imageio.imread(out)
    assert frames.shape[0] == 4 and frames.shape[-1] == 3
    assert [p.name for p in tmp_path.iterdir()] == ["episode.mp4"]


def test_record_mp4_without_imageio_ffmpeg_is_one_line(tmp_path, monkeypatch, capsys):
    pytest.importorskip("imageio.v3")
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import imageio_ffmpeg now raises ImportError
    code, _, err = run_main(["record", GOAL, "--max-steps", "2", "--output", str(tmp_path / "x.mp4")], capsys)
    assert_one_line_error(code, err, "imageio-ffmpeg")
    assert '.[render]" in a polyenvs clone' in err and list(tmp_path.iterdir()) == []


def test_record_checks_the_output_path_before_running(tmp_path, monkeypatch, capsys):
    pytest.importorskip("imageio.v3")
    import polyenvs.evaluation.episodes

    def no_env(*args, **kwargs):
        raise AssertionError("the episode ran before the output path was checked")

    monkeypatch.setattr(polyenvs.evaluation.episodes, "make_env", no_env)
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for output, fragment in [(blocker / "x.gif", "not a directory"), (tmp_path, ".gif or .mp4")]:
        code, _, err = run_main(["record", GOAL, "--output", str(output)], capsys)
        assert_one_line_error(code, err, "--output")
        assert fragment in err
    (tmp_path / "dir.gif").mkdir()
    code, _, err = run_main(["record", GOAL, "--output", str(tmp_path / "dir.gif")], capsys)
    assert_one_line_error(code, err, "is a directory")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "dir.gif"]


@pytest.mark.skipif(not Path("/proc/self").exists(), reason="needs /proc")
def test_record_into_proc_is_one_line_and_leaves_nothing():
    pytest.importorskip("imageio.v3")
    result = run_cli("record", GOAL, "--max-steps", "2", "--output", "/proc/x.gif")
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "--output" in result.stderr, result.stderr
    assert "Traceback" not in result.stderr and "Exception ignored" not in result.stderr
    assert not Path("/proc/x.gif").exists()


def test_record_failure_while_writing_leaves_no_file(tmp_path, monkeypatch, capsys):
    """The video goes to a temporary file that is renamed only when complete; a failure removes it."""
    iio = pytest.importorskip("imageio.v3")
    written = []

    def failing_write(uri, image, **kwargs):
        Path(uri).write_bytes(b"GIF89a half")  # a partial file, then the disk fills up
        written.append(Path(uri))
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(iio, "imwrite", failing_write)
    out = tmp_path / "episode.gif"
    code, _, err = run_main(["record", GOAL, "--max-steps", "2", "--output", str(out)], capsys)
    assert_one_line_error(code, err, "No space left on device")
    assert written and written[0] != out and written[0].parent == tmp_path
    assert list(tmp_path.iterdir()) == []  # neither the output nor the temporary file


def test_record_accepts_policy_kwargs(tmp_path):
    pytest.importorskip("imageio.v3")
    out = tmp_path / "e.gif"
    assert (
        main(["record", GOAL, "--max-steps", "2", "--policy-kwargs", '{"clearance_cm": 30}', "--output", str(out)]) == 0
    )
    assert out.stat().st_size > 0


# -------------------------------------------------------------------------------------------------- install


def test_console_script_is_installed():
    script = Path(sys.executable).parent / "polyenvs"
    if not script.exists():
        pytest.skip("polyenvs is not installed in this interpreter's environment (source checkout only)")
    result = subprocess.run([str(script), "list"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and polyenvs.ENV_IDS[0] in result.stdout


def test_extras_install_one_pygame_and_an_mp4_writer():
    """pygame and pygame-ce both install the ``pygame`` package; minigrid (dev) needs pygame-ce, so use only it."""
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]

    def names(extra):
        return {re.split(r"[<>=!~\[; ]", req, maxsplit=1)[0].lower() for req in extras[extra]}

    for extra in ("render", "dev"):
        assert "pygame-ce" in names(extra) and "pygame" not in names(extra), extras[extra]
        assert {"imageio", "imageio-ffmpeg"} <= names(extra), extras[extra]
    assert not any("pygame" == n for extra in extras for n in names(extra))


def test_an_environment_extra_brings_what_gymnasium_imports_with_it():
    """Gymnasium's MujocoEnv imports imageio and packaging, not only mujoco: the extra the beasts' rows name must
    install Gymnasium's own mujoco extra (a fresh ``.[train,mujoco]`` install once lacked imageio)."""
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    named = {row.extra for row in polyenvs.registry.REGISTRY if getattr(row, "extra", None)}
    assert named == {"mujoco"}
    assert "gymnasium[mujoco]" in [req.replace(" ", "") for req in extras["mujoco"]]


def test_a_missing_optional_package_is_one_line_naming_the_extra(monkeypatch, capsys):
    import builtins

    real_import = builtins.__import__

    def no_imageio(name, *args, **kwargs):
        if name == "imageio" or name.startswith("imageio."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return real_import(name, *args, **kwargs)

    for module in [m for m in sys.modules if m.startswith(("gymnasium.envs.mujoco", "polyenvs.beast", "imageio"))]:
        monkeypatch.delitem(sys.modules, module)
    monkeypatch.setattr(builtins, "__import__", no_imageio)
    code, out, err = run_main(["evaluate", "polyenvs/BeastRoll-v0", "--episodes", "1"], capsys)
    assert_one_line_error(
        code, err, 'need imageio, which is not installed: pip install ".[mujoco]" in a polyenvs clone'
    )
