"""Properties every polyenvs PettingZoo parallel environment keeps, parametrised over the registry.

The counterpart of ``test_envs_shared.py`` for the other kind: a family gets all of these by listing its modules
in ``polyenvs.registry`` as ``ParallelEnvEntry`` rows. PettingZoo's own checks first, then the conventions of the
Gymnasium suite that apply to a swarm (seeded determinism, fresh observations inside their spaces, reward terms that
sum, bad input that raises and changes nothing, pickling, documentation). The checks are the methods of
:class:`ParallelRowChecks`, on the row its ``Test`` subclass's ``entry`` fixture gives: :class:`TestRegistryModules`
runs them on every parallel row of the registry, ``tests/test_adding_guide.py`` on the adding guide's toy swarm.
"""

from __future__ import annotations

import importlib
import inspect
import pickle

import gymnasium as gym
import numpy as np
import pytest
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test

from polyenvs.registry import REGISTRY
from tests.parameter_helpers import assert_physical_keywords_reach_their_fields, unknown_keyword_message

ENTRIES = [e for e in REGISTRY if e.kind == "pettingzoo"]


def _module(entry):
    return importlib.import_module(entry.id)


def _make(entry, **kwargs):
    return _module(entry).parallel_env(**{"max_cycles": entry.max_cycles, **entry.kwargs, **kwargs})


def _actions(env, rng_seed: int, step: int) -> dict:
    actions = {}
    for i, agent in enumerate(env.agents):
        space = env.action_space(agent)
        space.seed(rng_seed * 100_003 + step * 1009 + i)
        actions[agent] = space.sample()
    return actions


def _rollout(env, seed: int, cycles: int, action_seed: int = 0) -> list:
    observations, _ = env.reset(seed=seed)
    trace = [observations]
    for step in range(cycles):
        if not env.agents:
            break
        observations, rewards, terminations, truncations, _ = env.step(_actions(env, action_seed, step))
        trace.append((observations, rewards, terminations, truncations))
    return trace


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, tuple | list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return np.array_equal(a, b)


class ParallelRowChecks:
    """Every check of one parallel row (a :class:`~polyenvs.registry.ParallelEnvEntry`), the ``entry`` fixture of a
    ``Test`` subclass."""

    def test_parallel_api(self, entry):
        parallel_api_test(_make(entry), num_cycles=200)

    def test_aec_api(self, entry):
        api_test(_module(entry).env(max_cycles=entry.max_cycles), num_cycles=100)

    def test_parallel_seed(self, entry):
        parallel_seed_test(lambda: _make(entry), num_cycles=100)

    def test_max_cycles(self, entry):
        max_cycles_test(_module(entry))

    def test_render(self, entry):
        render_test(lambda render_mode=None: _module(entry).env(max_cycles=entry.max_cycles, render_mode=render_mode))

    def test_same_seed_same_episode_bit_for_bit(self, entry):
        a, b = _rollout(_make(entry), 7, 150), _rollout(_make(entry), 7, 150)
        assert _same(a, b)
        c = _rollout(_make(entry), 8, 150)
        assert not _same(a, c)

    def test_spaces_are_built_once_per_agent(self, entry):
        env = _make(entry)
        env.reset(seed=0)
        for agent in env.possible_agents:
            assert env.observation_space(agent) is env.observation_space(agent)
            assert env.action_space(agent) is env.action_space(agent)
        first = env.possible_agents[0]
        assert all(env.observation_space(a) == env.observation_space(first) for a in env.possible_agents)
        assert all(env.action_space(a) == env.action_space(first) for a in env.possible_agents)

    def test_observations_and_state_stay_in_their_spaces(self, entry):
        env = _make(entry)
        observations, _ = env.reset(seed=1)
        for step in range(300):
            for agent, obs in observations.items():
                assert env.observation_space(agent).contains(obs), (agent, obs)
            state = env.state()
            assert env.state_space.contains(state) and np.all(np.isfinite(state))
            if not env.agents:
                break
            observations, rewards, *_ = env.step(_actions(env, 1, step))
            assert all(np.isfinite(r) for r in rewards.values())

    def test_observations_are_fresh_arrays(self, entry):
        env, twin = _make(entry), _make(entry)
        first, _ = env.reset(seed=0)
        twin.reset(seed=0)
        kept = {a: o.copy() for a, o in first.items()}
        actions = _actions(env, 0, 0)
        second = env.step(actions)[0]
        twin.step(actions)
        for agent in second:
            assert not np.shares_memory(first[agent], second[agent])
            assert np.array_equal(first[agent], kept[agent]), (
                "the environment wrote into an observation it had returned"
            )
            second[agent][...] = 0.5  # scribbling on returned observations must not change what happens next
        for step in range(1, 6):
            if not env.agents:
                break
            actions = _actions(env, 0, step)
            assert _same(env.step(actions)[0], twin.step(actions)[0])

    def test_reward_terms_sum(self, entry):
        env = _make(entry)
        env.reset(seed=2)
        for step in range(50):
            if not env.agents:
                break
            _, rewards, _, _, infos = env.step(_actions(env, 2, step))
            for agent, reward in rewards.items():
                terms = [v for k, v in infos[agent].items() if k.startswith("reward_")]
                assert terms and np.isclose(sum(terms), reward)

    def test_metrics_when_robots_leave(self, entry):
        """Every robot's last info holds ``episode_metrics`` (what ``polyenvs evaluate`` averages), all finite."""
        env = _make(entry, max_cycles=20)
        env.reset(seed=3)
        reported = set()
        for step in range(25):
            if not env.agents:
                break
            _, _, terminations, truncations, infos = env.step(_actions(env, 3, step))
            for agent in terminations:
                if terminations[agent] or truncations[agent]:
                    metrics = infos[agent]["episode_metrics"]
                    assert metrics and all(np.isfinite(v) for v in metrics.values())
                    reported.add(agent)
        assert not env.agents and reported == set(env.possible_agents)

    def test_bad_actions_raise_and_change_nothing(self, entry):
        env, twin = _make(entry), _make(entry)
        env.reset(seed=0)
        twin.reset(seed=0)
        agent = env.agents[0]
        good = _actions(env, 0, 0)
        space = env.action_space(agent)
        bad_values = [None, "a"]
        if hasattr(space, "shape") and space.shape:
            bad_values += [np.full(space.shape, np.nan), np.zeros(space.shape[0] + 1)]
            # A wrong dtype is an error, not a cast: numpy would drop the imaginary part and read True as 1.
            bad_values += [
                np.full(space.shape, 0.2 + 5j),
                np.zeros(space.shape, bool),
                np.zeros(space.shape).astype(str),
            ]
        else:
            bad_values += [getattr(space, "n", 0), -1]
        for value in bad_values:
            with pytest.raises((ValueError, TypeError)):
                env.step({**good, agent: value})
        with pytest.raises((ValueError, KeyError)):
            env.step({**good, "no_such_robot": good[agent]})
        for step in range(5):
            if not env.agents:
                break
            actions = _actions(env, 0, step)
            assert _same(env.step(actions), twin.step(actions))

    def test_aec_bad_action_raises_when_given_and_changes_nothing(self, entry):
        """An AEC action is checked when its agent gives it; a rejected one leaves the episode as it was."""
        env, twin = _module(entry).env(max_cycles=entry.max_cycles), _module(entry).env(max_cycles=entry.max_cycles)
        env.reset(seed=0)
        twin.reset(seed=0)
        agent = env.agent_selection
        space = env.action_space(agent)
        for value in (np.full(space.shape, np.nan), np.full(space.shape, 0.2 + 5j), "x", None):
            with pytest.raises(ValueError, match=agent):
                env.step(value)
        for k in range(3 * len(env.agents)):
            assert env.agent_selection == twin.agent_selection
            observation, *_ = env.last()
            assert _same(observation, twin.last()[0])
            if env.terminations[env.agent_selection] or env.truncations[env.agent_selection]:
                break
            space = env.action_space(env.agent_selection)
            space.seed(k)
            action = space.sample()
            env.step(action)
            twin.step(action)

    def test_step_and_render_before_reset_raise(self, entry):
        parallel = _make(entry, render_mode="rgb_array")
        with pytest.raises(gym.error.ResetNeeded, match=r"reset\(\) before step"):
            parallel.step({})
        with pytest.raises(gym.error.ResetNeeded, match=r"reset\(\) before render"):
            parallel.render()
        aec = _module(entry).env(render_mode="rgb_array")
        with pytest.raises(gym.error.ResetNeeded, match=r"reset\(\) before step"):
            aec.step(np.zeros(2, np.float32))

    def test_unknown_and_malformed_options_raise_and_change_nothing(self, entry):
        env, twin = _make(entry), _make(entry)
        env.reset(seed=0)
        twin.reset(seed=0)
        for options in ({"bogus": 1}, [1], "x", 3):
            with pytest.raises(ValueError, match="option"):
                env.reset(seed=1, options=options)
        for step in range(5):
            actions = _actions(env, 0, step)
            assert _same(env.step(actions), twin.step(actions))

    def test_bad_constructor_arguments_name_the_parameter(self, entry):
        module = _module(entry)
        for value in (0, -1, True, "10", 1.5):
            with pytest.raises(ValueError, match="max_cycles"):
                module.parallel_env(max_cycles=value)
        if hasattr(_make(entry), "n_robots"):  # a swarm whose size is a keyword
            for value in (0, True, "3", 2.5, 10**9):
                with pytest.raises(ValueError, match="n_robots"):
                    module.parallel_env(n_robots=value)

    def test_unknown_keyword_raises_the_standard_type_error(self, entry):
        """As the Gymnasium suite's: every constructor of the module raises Python's own ``TypeError`` for an unknown
        keyword, naming the environment's class."""
        module, cls = _module(entry), type(_make(entry))
        for constructor in (module.parallel_env, module.raw_env, module.env):
            with pytest.raises(TypeError, match=unknown_keyword_message(cls, "frameskip")):
                constructor(frameskip=4)

    def test_each_physical_parameter_is_a_keyword_that_reaches_its_field(self, entry, monkeypatch):
        """As the Gymnasium suite's: ``parallel_env(name=value)`` takes each physical parameter of the family's
        dataclass, whichever task subclass is in between."""
        assert_physical_keywords_reach_their_fields(
            type(_make(entry)), lambda **kwargs: _make(entry, **kwargs), monkeypatch
        )

    def test_pickles_mid_episode(self, entry):
        env = _make(entry)
        env.reset(seed=4)
        env.step(_actions(env, 4, 0))
        clone = pickle.loads(pickle.dumps(env))
        for step in range(1, 6):
            if not env.agents:
                break
            actions = _actions(env, 4, step)
            assert _same(env.step(actions), clone.step(actions))

    def test_documented_like_gymnasium(self, entry):
        doc = inspect.getdoc(type(_make(entry))) or ""
        for section in ("## Description", "## Action Space", "## Observation Space", "## Rewards", "## Arguments"):
            assert section in doc, f"{entry.id}: the parallel env's class docstring lacks {section}"
        assert entry.description


class TestRegistryModules(ParallelRowChecks):
    """The checks on every parallel row of the registry."""

    @pytest.fixture(params=ENTRIES, ids=lambda e: e.id)
    def entry(self, request):
        return request.param
