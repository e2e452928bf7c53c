"""The installed package, not the checkout: a non-editable install (what pip makes of the wheel) finds its training
configs from any directory, and its leaderboard says that it has no trained agents and why; and what a base install
(``pip install .``, no extra) does where an extra is missing.

The install takes the interpreter's own dependencies (``--no-deps``) and builds without isolation, offline. A missing
extra is played by a subprocess whose ``sys.modules`` holds ``None`` for the extra's packages (importing one then
raises ``ModuleNotFoundError``), so nothing is uninstalled from the environment the tests run in.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
GOAL = "polyenvs/BuckybotGoal-v0"


def test_pyproject_lists_every_package_and_maps_the_configs_into_it():
    setuptools = pytest.importorskip("setuptools")
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = setuptools.find_packages(str(ROOT), include=["polyenvs", "polyenvs.*", "baselines", "baselines.*"])
    assert sorted(config["packages"]) == sorted([*found, "polyenvs.configs"]), "a package is missing from the list"
    assert config["package-dir"] == {"polyenvs.configs": "configs"}
    assert "*.yml" in config["package-data"]["polyenvs.configs"]


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    pytest.importorskip("setuptools")
    pytest.importorskip("stable_baselines3")
    base = tmp_path_factory.mktemp("install")
    source = base / "source"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    for name in ("polyenvs", "baselines", "configs"):
        shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    target = base / "site-packages"
    done = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--no-index",
         "--target", str(target), str(source)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    if done.returncode != 0:
        pytest.fail(f"pip install failed: {done.stderr[-2000:]}")
    return target


def _run(installed: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(installed), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


def test_the_installed_package_ships_the_configs(installed, tmp_path):
    done = _run(installed, tmp_path, "-c", "import polyenvs.training.config as c; print(c.default_config_path('ppo'))")
    assert done.returncode == 0, done.stderr
    assert Path(done.stdout.strip()) == installed / "polyenvs" / "configs" / "ppo.yml"
    for path in sorted((ROOT / "configs").glob("*.yml")):
        assert (installed / "polyenvs" / "configs" / path.name).read_text() == path.read_text()


def test_train_from_any_directory_reads_the_shipped_config(installed, tmp_path):
    """It said ``config file configs/ppo.yml does not exist`` anywhere but the repository root."""
    done = _run(installed, tmp_path, "-m", "polyenvs.cli", "train", GOAL, "--algo", "ppo", "--timesteps", "64",
                "--n-envs", "1", "--out", "run", "--no-progress")  # fmt: skip
    assert done.returncode == 0, done.stderr
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["completed"] is True and run["config_file"] == str(installed / "polyenvs" / "configs" / "ppo.yml")


def test_the_installed_leaderboard_says_it_found_no_agents_and_why(installed, tmp_path):
    """It silently evaluated no trained agent."""
    done = _run(installed, tmp_path, "-m", "polyenvs.cli", "leaderboard", "--only", "BumperCartExplore-v0",
                "--episodes", "1")  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert (
        f"trained agents: none found (no {tmp_path / 'benchmarks' / 'agents'}; the committed agents are in the "
        "polyenvs repository's benchmarks/agents/, which an installed package does not include: run from a "
        "checkout or pass --agents-dir DIR)" in done.stderr.splitlines()
    ), done.stderr


def test_the_installed_package_has_one_version_and_ships_its_type_hints(installed, tmp_path):
    """``polyenvs --version``, ``polyenvs.__version__`` and the distribution's metadata agree (pyproject reads the
    constant), and ``py.typed`` travels with both packages so type checkers read their hints (PEP 561)."""
    import polyenvs

    done = _run(installed, tmp_path, "-m", "polyenvs.cli", "--version")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"polyenvs {polyenvs.__version__}"
    metadata = next(installed.glob("polyenvs-*.dist-info")) / "METADATA"
    assert f"Version: {polyenvs.__version__}" in metadata.read_text().splitlines()
    assert (installed / "polyenvs" / "py.typed").is_file() and (installed / "baselines" / "py.typed").is_file()


def _without(packages: list[str], code: str, cwd: Path) -> subprocess.CompletedProcess:
    """``python -c code`` in ``cwd`` as if ``packages`` were not installed."""
    shim = f"import sys; sys.modules.update(dict.fromkeys({packages!r}))\n"
    return subprocess.run([sys.executable, "-c", shim + code], cwd=cwd, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")})  # fmt: skip


def _cli(*argv: str) -> str:
    return f"from polyenvs.cli import main; sys.exit(main({list(argv)!r}))"


def test_without_mujoco_the_list_names_the_extra_and_gym_make_raises_dependency_not_installed(tmp_path):
    """On a base install ``polyenvs list`` printed only a traceback (``No module named 'mujoco'``, exit 1), and
    ``gym.make`` of a beast raised a bare ``ModuleNotFoundError`` where Gymnasium's MuJoCo envs name their extra."""
    import polyenvs

    listed = _without(["mujoco"], _cli("list"), tmp_path)
    assert listed.returncode == 0 and listed.stderr == "", listed.stderr
    lines = listed.stdout.splitlines()
    for row in polyenvs.registry.REGISTRY:
        line = next(line for line in lines if line.startswith(f"{row.id} "))
        installed = " action " in line
        assert installed == (row.extra is None), line
        assert installed or line.split(None, 1)[1].startswith(
            'the Platonic beasts need mujoco, which is not installed: pip install ".[mujoco]" in a polyenvs clone'
        ), line
    made = _without(["mujoco"], "import gymnasium as gym, polyenvs; gym.make('polyenvs/BeastRoll-v1')", tmp_path)
    assert made.stderr.strip().splitlines()[-1] == (
        "gymnasium.error.DependencyNotInstalled: the Platonic beasts need mujoco, which is not installed: "
        'pip install ".[mujoco]" in a polyenvs clone'
    ), made.stderr


def test_without_pygame_a_human_window_raises_dependency_not_installed(tmp_path):
    """The render extra's window, the one optional package ``gym.make``'s environments import besides MuJoCo."""
    code = f"import gymnasium as gym, polyenvs; env = gym.make({GOAL!r}, render_mode='human'); env.reset(seed=0)"
    shown = _without(["pygame"], code + "; env.render()", tmp_path)
    assert shown.stderr.strip().splitlines()[-1] == (
        'gymnasium.error.DependencyNotInstalled: render_mode="human" needs pygame: pip install ".[render]" in a polyenvs clone'
    ), shown.stderr


@pytest.mark.parametrize(
    ("extra", "packages", "argv"),
    [
        ("mujoco", ["mujoco"], ["evaluate", "polyenvs/BeastRoll-v1", "--episodes", "1"]),
        ("train", ["yaml", "stable_baselines3", "sb3_contrib", "torch"], ["train", GOAL, "--algo", "ppo", "--out", "x"]),
        ("train", ["stable_baselines3", "sb3_contrib", "torch"], ["train", GOAL, "--algo", "ppo", "--out", "x"]),
        ("train", ["stable_baselines3", "sb3_contrib", "torch"], ["sweep", "--envs", GOAL, "--algos", "ppo", "--seeds", "0", "--out", "x"]),
        ("collect", ["minari", "h5py"], ["collect", GOAL, "--episodes", "1", "--out", "x"]),
        ("render", ["imageio"], ["record", GOAL, "--max-steps", "2", "--output", "x.gif"]),
        ("distributed", ["ray"], ["sweep", "--envs", GOAL, "--algos", "ppo", "--seeds", "0", "--backend", "ray", "--out", "x"]),
    ],
)  # fmt: skip
def test_a_missing_extra_is_one_line_naming_its_install_line(extra, packages, argv, tmp_path):
    done = _without(packages, _cli(*argv), tmp_path)
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.splitlines()) == 1 and f'pip install ".[{extra}]" in a polyenvs clone' in done.stderr, (
        done.stderr
    )
    assert list(tmp_path.iterdir()) == []
