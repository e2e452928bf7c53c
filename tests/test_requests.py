"""The requests ``train`` and ``collect`` take: each setting named once, as a field with its default and its meaning
beside it, and checked when the request is made (an InputError naming the field), before any work."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import re
from pathlib import Path

import pytest

from baselines.residual import ResidualSpec
from polyenvs.errors import InputError
from polyenvs.evaluation.datasets import CollectRequest
from polyenvs.limits import MAX_SEED
from polyenvs.training.train import TrainRequest

WALL = "polyenvs/BuckybotWallFollow-v0"


def _undocumented(cls) -> list[str]:
    """The fields of ``cls`` without a ``#:`` comment on the line above (the documentation Sphinx shows for them)."""
    path = Path(inspect.getsourcefile(cls))
    lines = path.read_text(encoding="utf-8").splitlines()
    (body,) = [
        n.body for n in ast.walk(ast.parse("\n".join(lines))) if isinstance(n, ast.ClassDef) and n.name == cls.__name__
    ]
    fields = {f.name for f in dataclasses.fields(cls)}
    declared = [s for s in body if isinstance(s, ast.AnnAssign) and getattr(s.target, "id", None) in fields]
    assert {s.target.id for s in declared} == fields
    return [s.target.id for s in declared if not lines[s.lineno - 2].strip().startswith("#:")]


@pytest.mark.parametrize("cls", [TrainRequest, CollectRequest])
def test_every_field_says_what_it_means_beside_it(cls):
    assert _undocumented(cls) == []


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"algo": "a2c"}, "unknown algorithm 'a2c'"),
        ({"env_id": 3}, "env_id must be a string, got 3"),
        ({"seed": -1}, "seed must be >= 0, got -1"),
        ({"seed": 1.5}, "seed must be an integer, got 1.5"),
        ({"timesteps": 0}, "timesteps must be >= 1, got 0"),
        ({"n_envs": True}, "n_envs must be an integer, got True"),
        ({"checkpoint_every": -1}, "checkpoint_every must be >= 0, got -1"),
        ({"env_kwargs": [("floor_plan", "corner")]}, "env_kwargs must be a dict"),
        ({"layouts": "held-out"}, "layouts must be one of 'default', 'train', 'test', got held-out"),
        ({"layouts": "test", "env_kwargs": {"layouts": "train"}}, "layouts is 'test' but env_kwargs' layouts is"),
        ({"vec_env": "subproc"}, "vec_env must be 'auto', 'native' or 'dummy', got 'subproc'"),
        ({"residual": "paper"}, "residual must be a baselines.residual.ResidualSpec, got 'paper'"),
        ({"residual_log_std": -1.0}, "residual_log_std needs residual"),
    ],
)
def test_a_bad_train_request_is_refused_naming_its_field(tmp_path, fields, message):
    good = TrainRequest(WALL, "ppo", out_dir=tmp_path / "run")
    with pytest.raises(InputError, match="^" + re.escape(message)):  # the message begins with the field's name
        dataclasses.replace(good, **fields)
    assert not (tmp_path / "run").exists()


def test_a_train_request_keeps_its_own_settings(tmp_path):
    """Normalised once (the id without Gymnasium's module prefix, the directory a Path, numpy counts as ints), and
    the caller's dict is copied: changing it later does not change the run."""
    import numpy as np

    env_kwargs = {"max_episode_steps": 20}
    request = TrainRequest(
        f"polyenvs:{WALL}", "ppo", out_dir=str(tmp_path), env_kwargs=env_kwargs, seed=np.int64(3),
        residual=ResidualSpec("paper"),
    )  # fmt: skip
    env_kwargs["max_episode_steps"] = 5
    assert request.env_id == WALL and request.out_dir == tmp_path and request.seed == 3 and type(request.seed) is int
    assert request.env_kwargs == {"max_episode_steps": 20}
    with pytest.raises(dataclasses.FrozenInstanceError):
        request.seed = 4  # type: ignore[misc]
    assert TrainRequest(WALL, "ppo", out_dir=tmp_path).env_kwargs == {}


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"episodes": 0}, "episodes must be >= 1, got 0"),
        ({"episodes": 2.0}, "episodes must be an integer, got 2.0"),
        ({"seed": -1}, "seed must be >= 0, got -1"),
        ({"seed": MAX_SEED, "episodes": 2}, f"seed + episodes - 1 must be <= {MAX_SEED}, got {MAX_SEED + 1}"),
    ],
)
def test_a_bad_collect_request_is_refused_naming_its_field(tmp_path, fields, message):
    good = CollectRequest("polyenvs/APLiteCorridor-v0", out_dir=tmp_path / "demos")
    with pytest.raises(InputError, match="^" + re.escape(message)):
        dataclasses.replace(good, **fields)
    assert not (tmp_path / "demos").exists()


def test_a_collect_request_keeps_its_own_settings(tmp_path):
    env_kwargs, policy_kwargs = {"max_episode_steps": 20}, {"clearance_cm": 5.0}
    request = CollectRequest("polyenvs/APLiteCorridor-v0", "aplite", out_dir=str(tmp_path), env_kwargs=env_kwargs,
                             policy_kwargs=policy_kwargs, results_dir="benchmarks/results")  # fmt: skip
    env_kwargs.clear()
    policy_kwargs.clear()
    assert request.env_kwargs == {"max_episode_steps": 20} and request.policy_kwargs == {"clearance_cm": 5.0}
    assert request.out_dir == tmp_path and request.results_dir == Path("benchmarks/results")
    assert CollectRequest("polyenvs/APLiteCorridor-v0").out_dir == Path("dataset")  # collect's default, as before
