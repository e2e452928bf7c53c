"""The Ray backend of :mod:`polyenvs.pool`: the local pool's contract, and a leaderboard on Ray that writes the local
pool's result files. Skipped where Ray is not installed (the distributed extra); kept short, on two CPUs."""

from __future__ import annotations

import json
import math

import pytest

from polyenvs.evaluation.run import Listeners, run_leaderboard
from polyenvs.pool import run_jobs

ray = pytest.importorskip("ray")

GOAL = "polyenvs/BuckybotGoal-v0"


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray instance of two CPUs for the module: the backend joins it instead of starting its own."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.mark.parametrize("backend", ["local", "ray"])
def test_results_and_errors_reach_the_callbacks(backend, local_ray):
    results, errors = {}, {}
    run_jobs(math.sqrt, [4.0, -1.0, 9.0], 2, results.__setitem__, errors.__setitem__, backend=backend)
    assert results == {4.0: 2.0, 9.0: 3.0}
    assert list(errors) == [-1.0] and isinstance(errors[-1.0], ValueError)  # the job's own error, as in the pool
    assert "math domain error" in str(errors[-1.0])


def _result_files(results_dir) -> dict[str, dict]:
    """Every result file's document, without the date it was written."""
    documents = {}
    for path in sorted(results_dir.glob("*.json")):
        document = json.loads(path.read_text())
        del document["date"]
        documents[path.name] = document
    return documents


def test_a_leaderboard_on_ray_writes_the_local_pools_files(tmp_path, local_ray):
    for backend in ("local", "ray"):
        run_leaderboard([GOAL], 2, results_dir=tmp_path / backend, listeners=Listeners(progress=lambda _: None),
                        workers=2, backend=backend)  # fmt: skip
    local, on_ray = _result_files(tmp_path / "local"), _result_files(tmp_path / "ray")
    assert len(local) == 4  # random and goal_seeker, on the default and the held-out layouts
    assert on_ray == local
