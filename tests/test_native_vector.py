"""The native vector env given the env class (polyenvs/core/vector_entry.py), and the swarm's vector env on the
shared seeding of polyenvs/core/rows.py."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.envs.registration import EnvSpec

from polyenvs.registry import REGISTRY, import_attribute
from polyenvs.swarm import corridor_v0
from polyenvs.swarm.batched import SwarmVectorEnv
from tests.vector_helpers import assert_same

NATIVE_IDS = [row.id for row in REGISTRY if row.kind == "gymnasium" and row.native_vector]


@pytest.mark.parametrize("env_id", NATIVE_IDS)
def test_make_vec_builds_the_env_classs_own_vector_env_from_a_json_spec(env_id):
    """The registration is a string (Minari stores the spec as JSON) that ``gym.make_vec`` resolves, from the JSON
    spec too, to the entry point class's ``VectorEnv``: one class per env class, bound to it, which pickles."""
    spec = EnvSpec.from_json(gym.spec(env_id).to_json())
    env_class = import_attribute(spec.entry_point)
    envs = gym.make_vec(spec, num_envs=2, vectorization_mode="vector_entry_point")
    assert type(envs) is env_class.VectorEnv is env_class.VectorEnv and envs.env_class is env_class
    assert type(envs).__name__ == env_class.__name__.removesuffix("Env") + "VectorEnv"
    envs.reset(seed=4)
    clone = pickle.loads(pickle.dumps(envs))
    assert type(clone) is type(envs)
    envs.action_space.seed(0)
    for _ in range(3):
        actions = envs.action_space.sample()
        assert_same(envs.step(actions), clone.step(actions))


def test_each_task_class_has_a_vector_env_of_its_own():
    """A family base and its tasks each get theirs (the binding is not inherited from the class read first)."""
    classes = [import_attribute(gym.spec(env_id).entry_point) for env_id in NATIVE_IDS]
    bases = {cls.__mro__[1] for cls in classes}
    for cls in [*bases, *classes]:
        assert cls.VectorEnv.env_class is cls
    assert len({cls.VectorEnv for cls in [*bases, *classes]}) == len({*bases, *classes})


def test_an_unseeded_swarm_reset_continues_each_environments_generator():
    """Environment e of ``SwarmVectorEnv`` reset with seed s, then without one, is the PettingZoo env reset with seed
    s + e, then without one (before the shared seeding, the batch drew fresh entropy there)."""
    kwargs = {"n_robots": 2, "max_cycles": 50}
    batch = SwarmVectorEnv("corridor_v0", num_envs=3, **kwargs)
    singles = [corridor_v0.parallel_env(**kwargs) for _ in range(3)]
    batch.reset(seed=7)
    for e, env in enumerate(singles):
        env.reset(seed=7 + e)
    obs, _ = batch.reset()
    for e, env in enumerate(singles):
        single_obs, _ = env.reset()
        assert all(np.array_equal(obs[2 * e + r], single_obs[f"robot_{r}"]) for r in range(2))


def test_swarm_seeds_per_environment_or_per_row_and_bad_seeds_change_nothing():
    batch, twin = (
        SwarmVectorEnv("corridor_v0", num_envs=3, n_robots=2),
        SwarmVectorEnv("corridor_v0", num_envs=3, n_robots=2),
    )
    by_env = batch.reset(seed=[5, 6, 7])[0]
    assert np.array_equal(twin.reset(seed=5)[0], by_env)
    assert np.array_equal(twin.reset(seed=[5, 0, 6, 0, 7, 0])[0], by_env)  # an environment takes its first row's
    for bad in (-1, [5, 6], [5, -6, 7], 2.0, True):
        with pytest.raises(ValueError, match="seed"):
            batch.reset(seed=bad)
        assert np.array_equal(batch.batch.observations, by_env)
