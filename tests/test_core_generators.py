"""The compiled draws of :mod:`polyenvs.core.generators` are the generators' own, bit for bit."""

import copy
import pickle

import numpy as np
import pytest
from gymnasium.utils import seeding

from polyenvs.core import generators

pytestmark = pytest.mark.skipif(not generators.COMPILED, reason="the compiled draws need numba")


@pytest.mark.parametrize("bit_generator", [np.random.PCG64, np.random.Philox, np.random.MT19937])
def test_draws_and_states_match_the_generators_methods(bit_generator):
    ours, theirs = (np.random.Generator(bit_generator(7)) for _ in range(2))
    addresses = generators.generator_addresses([ours, ours])
    which = np.array([1, 0], dtype=np.int64)  # the second entry is skipped: the generator advances once per round
    normals, uniforms = np.zeros((2, 5, 23)), np.zeros((2, 5, 4))
    expected_normals, expected_uniforms = np.zeros((5, 23)), np.zeros((5, 4))
    # 2,000 rounds of 115 normals: about 900 draws fall in the ziggurat's tail or wedges (other code paths).
    for _ in range(2000):
        generators.normals_then_uniforms(addresses, which, normals, uniforms)
        theirs.standard_normal(out=expected_normals)
        theirs.random(out=expected_uniforms)
        np.testing.assert_array_equal(normals[0], expected_normals)
        np.testing.assert_array_equal(uniforms[0], expected_uniforms)
    assert not normals[1].any() and not uniforms[1].any()
    assert repr(ours.bit_generator.state) == repr(theirs.bit_generator.state)


def test_a_copied_swarm_draws_on_its_own_generators():
    from polyenvs.swarm import corridor_v0

    env = corridor_v0.parallel_env(n_robots=3)
    env.reset(seed=4)
    actions = {agent: np.full(2, 0.5, np.float32) for agent in env.agents}
    env.step(actions)  # the batch now holds its generators' addresses
    for twin in (copy.deepcopy(env), pickle.loads(pickle.dumps(env))):
        expected = env.batch.generators[0].bit_generator.state
        twin_obs = twin.step(actions)[0]
        assert env.batch.generators[0].bit_generator.state == expected  # the original's generator is untouched
        obs = copy.deepcopy(env).step(actions)[0]
        for agent in obs:
            np.testing.assert_array_equal(obs[agent], twin_obs[agent])


def test_the_swarm_steps_as_with_the_generators_methods(monkeypatch):
    from polyenvs.swarm.batched import SwarmVectorEnv

    def rollout():
        env = SwarmVectorEnv("obstacle_field_v0", num_envs=3, n_robots=2, max_cycles=20)
        env.reset(seed=1)
        rng = np.random.default_rng(0)
        return [env.step(rng.uniform(-1, 1, (6, 2)))[:2] for _ in range(50)]

    compiled = rollout()
    monkeypatch.setattr(generators, "COMPILED", False)
    for (obs, rewards), (obs_ref, rewards_ref) in zip(compiled, rollout(), strict=True):
        np.testing.assert_array_equal(obs, obs_ref)
        np.testing.assert_array_equal(rewards, rewards_ref)


def test_addresses_are_one_row_per_generator():
    gens = [seeding.np_random(s)[0] for s in range(4)]
    addresses = generators.generator_addresses(gens)
    assert addresses.shape == (4, 3) and addresses.dtype == np.int64
    assert len(set(addresses[:, generators.STATE].tolist())) == 4


@pytest.mark.parametrize("bit_generator", ["PCG64", "PCG64DXSM", "MT19937", "Philox", "SFC64"])
def test_copy_generator_is_a_deep_copy_in_draws_state_and_spawns(bit_generator) -> None:
    """A reset draws on :func:`~polyenvs.core.rows.copy_generator`'s copy and keeps it: it must continue exactly as
    the generator would (half-used 32-bit and Philox buffers included), independently, and spawn the same children."""
    from polyenvs.core.rows import copy_generator

    rng = np.random.Generator(getattr(np.random, bit_generator)(np.random.SeedSequence(7)))
    rng.integers(0, 2**32, dtype=np.uint32)  # leaves a buffered half word
    rng.standard_normal(3)
    reference, twin = copy.deepcopy(rng), copy_generator(rng)
    assert pickle.dumps(twin.bit_generator.state) == pickle.dumps(reference.bit_generator.state)
    np.testing.assert_array_equal(twin.standard_normal(9), reference.standard_normal(9))
    assert twin.integers(0, 2**32, dtype=np.uint32) == reference.integers(0, 2**32, dtype=np.uint32)
    assert pickle.dumps(rng.bit_generator.state) != pickle.dumps(twin.bit_generator.state)  # not moved with its copy
    np.testing.assert_array_equal(twin.spawn(1)[0].random(4), reference.spawn(1)[0].random(4))
