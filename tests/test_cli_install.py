"""The installed package, not the checkout: a non-editable install (what pip makes of the wheel) finds its training
configs from any directory, and its leaderboard says that it has no trained agents and why.

The install takes the interpreter's own dependencies (``--no-deps``) and builds without isolation, offline.
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
