"""Properties every polyenvs Gymnasium environment keeps, parametrised over the registry.

A family added later gets all of these by registering its ids in ``polyenvs.registry``. The per-row checks are the
methods of :class:`GymnasiumRowChecks`: :class:`TestRegistryRows` runs them on every registry row, and a row that is
not in the registry can be handed to them by a ``Test`` subclass of its own (``tests/test_adding_guide.py``: the
adding guide's toy tasks).
"""

from __future__ import annotations

import pickle
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import polyenvs
from polyenvs.core.rows import RowsEnv
from polyenvs.registry import REGISTRY, import_attribute
from tests.parameter_helpers import assert_physical_keywords_reach_their_fields, unknown_keyword_message
from tests.vector_helpers import assert_native_matches_sync

ENV_IDS = polyenvs.ENV_IDS


def _rollout(env, seed: int, n_steps: int, action_seed: int = 0):
    env.action_space.seed(action_seed)
    obs, info = env.reset(seed=seed)
    trace = [(obs, 0.0, False, False)]
    for _ in range(n_steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        trace.append((obs, reward, terminated, truncated))
        if terminated or truncated:
            obs, info = env.reset()
            trace.append((obs, 0.0, False, False))
    return trace


def _bad_actions(space: gym.Space) -> list:
    if isinstance(space, gym.spaces.Discrete):
        return [space.n, -1, 1.5, "a", None, [0, 1], np.complex128(1), True]
    assert isinstance(space, gym.spaces.Box), space
    good = space.sample()
    return [
        np.full(space.shape, np.nan),
        np.full(space.shape, np.inf),
        good[:-1],
        np.concatenate([good, good]),
        "a",
        None,
        # A wrong dtype is an error, not a cast: numpy would drop the imaginary part and read True as 1.
        np.full(space.shape, 0.2 + 5j),
        (good + 0j).tolist(),
        np.zeros(space.shape, dtype=bool),
        good.astype(str),
    ]


def _constructed_class(env_id: str) -> type:
    """The class ``gym.make(env_id, **kwargs)`` builds with the keywords: the entry point's, or for a single-robot
    swarm id the swarm task's inside it."""
    cls = _env_class(env_id)
    return getattr(cls, "swarm_class", cls)


def _env_class(env_id: str) -> type:
    return import_attribute(gym.spec(env_id).entry_point)


GYMNASIUM_ROWS = [e for e in REGISTRY if e.kind == "gymnasium"]
VECTOR_IDS = [e.id for e in GYMNASIUM_ROWS if e.vector_entry_point]
ROWS_IDS = [env_id for env_id in ENV_IDS if issubclass(_env_class(env_id), RowsEnv)]


class GymnasiumRowChecks:
    """Every check of one Gymnasium row, as the fixtures of a ``Test`` subclass name it: ``env_id`` (a registered
    id), ``entry`` (its :class:`~polyenvs.registry.EnvEntry`), ``vector_id`` (an id with a native vector env) and
    ``rows_id`` (an id whose class is a :class:`~polyenvs.core.rows.RowsEnv`)."""

    #: The multiprocessing start method of the async vector env's workers (None: the default, which importing
    #: torchrl makes "spawn" for the whole test session).
    async_context: str | None = None

    def test_gymnasium_env_checker(self, env_id):
        env = gym.make(env_id, render_mode="rgb_array")
        check_env(env.unwrapped, skip_render_check=False)
        env.close()

    def test_sb3_env_checker(self, env_id):
        sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
        env = gym.make(env_id)
        sb3_checker.check_env(env.unwrapped, warn=True)
        env.close()

    def test_same_seed_same_trajectory(self, env_id):
        a, b = _rollout(gym.make(env_id), 7, 200), _rollout(gym.make(env_id), 7, 200)
        assert len(a) == len(b)
        for (oa, ra, ta, ua), (ob, rb, tb, ub) in zip(a, b, strict=True):
            assert np.array_equal(oa, ob) and ra == rb and ta == tb and ua == ub
        c = _rollout(gym.make(env_id), 8, 200)
        assert any(not np.array_equal(x[0], y[0]) for x, y in zip(a, c, strict=False))

    def test_observations_are_fresh_arrays(self, env_id):
        env, twin = gym.make(env_id), gym.make(env_id)
        obs0, _ = env.reset(seed=0)
        twin.reset(seed=0)
        kept = obs0.copy()
        env.action_space.seed(3)
        first = env.action_space.sample()
        obs1 = env.step(first)[0]
        twin.step(first)
        assert not np.shares_memory(obs0, obs1)
        assert np.array_equal(obs0, kept), "the environment wrote into an observation it had returned"
        # Scribbling on returned observations must not change what happens next.
        obs0[...] = 0.5
        obs1[...] = 0.5
        for _ in range(5):
            action = env.action_space.sample()
            assert np.array_equal(env.step(action)[0], twin.step(action)[0])

    def test_observations_stay_in_space(self, env_id):
        env = gym.make(env_id)
        env.action_space.seed(1)
        obs, _ = env.reset(seed=1)
        for _ in range(1000):
            assert env.observation_space.contains(obs), obs
            obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                obs, _ = env.reset()

    def test_reward_terms_sum_and_info_keys_match(self, env_id):
        env = gym.make(env_id)
        _, reset_info = env.reset(seed=2)
        names = set(env.unwrapped.episode_metrics())
        for _ in range(50):
            _, reward, terminated, truncated, info = env.step(env.action_space.sample())
            terms = [v for k, v in info.items() if k.startswith("reward_")]
            assert terms and np.isclose(sum(terms), reward)
            assert set(info) - {"episode_metrics"} == set(reset_info)  # the metrics: at the end only
            assert set(info.get("episode_metrics", names)) == set(env.unwrapped.episode_metrics()) == names
            if terminated or truncated:
                break

    def test_pickles(self, env_id):
        env = gym.make(env_id)
        env.reset(seed=4)
        clone = pickle.loads(pickle.dumps(env))
        env.action_space.seed(4)
        for _ in range(5):
            action = env.action_space.sample()
            assert np.array_equal(env.step(action)[0], clone.step(action)[0])

    def test_async_vector_env(self, env_id):
        envs = gym.make_vec(
            f"polyenvs:{env_id}", num_envs=2, vectorization_mode="async", vector_kwargs={"context": self.async_context}
        )
        try:
            obs, _ = envs.reset(seed=0)
            assert obs.shape == (2, *envs.single_observation_space.shape)
            obs, rewards, *_ = envs.step(envs.action_space.sample())
            assert rewards.shape == (2,)
        finally:
            envs.close()

    def test_render_rgb_array(self, env_id):
        env = gym.make(env_id, render_mode="rgb_array")
        env.reset(seed=0)
        first = env.render()
        assert first.dtype == np.uint8 and first.ndim == 3 and first.shape[2] == 3
        for _ in range(3):
            env.step(env.action_space.sample())
            assert env.render().shape == first.shape
        env.close()

    def test_rendering_does_not_change_the_simulation(self, env_id):
        plain, drawn = gym.make(env_id), gym.make(env_id, render_mode="rgb_array")
        a, b = plain.reset(seed=5)[0], drawn.reset(seed=5)[0]
        assert np.array_equal(a, b)
        plain.action_space.seed(0)
        for _ in range(20):
            action = plain.action_space.sample()
            drawn.render()
            assert np.array_equal(plain.step(action)[0], drawn.step(action)[0])

    def test_bad_actions_raise_and_change_nothing(self, env_id):
        env, twin = gym.make(env_id), gym.make(env_id)
        env.reset(seed=0)
        twin.reset(seed=0)
        env.action_space.seed(0)
        for action in _bad_actions(env.action_space):
            with pytest.raises((ValueError, TypeError)):
                env.unwrapped.step(action)
        for _ in range(5):
            action = env.action_space.sample()
            assert np.array_equal(env.step(action)[0], twin.step(action)[0])

    def test_step_and_render_before_reset_raise_reset_needed(self, env_id):
        env = gym.make(env_id, render_mode="rgb_array").unwrapped
        with pytest.raises(gym.error.ResetNeeded, match=r"reset\(\) before step"):
            env.step(env.action_space.sample())
        with pytest.raises(gym.error.ResetNeeded, match=r"reset\(\) before render"):
            env.render()
        env.reset(seed=0)
        env.step(env.action_space.sample())
        assert env.render().ndim == 3

    def test_unknown_and_malformed_options_raise_and_change_nothing(self, env_id):
        env, twin = gym.make(env_id), gym.make(env_id)
        env.reset(seed=0)
        twin.reset(seed=0)
        for options in ({"bogus": 1}, [1], "x", 3, {0: 1}):
            with pytest.raises(ValueError, match="option"):
                env.reset(seed=1, options=options)
        env.action_space.seed(0)
        for _ in range(5):
            action = env.action_space.sample()
            assert np.array_equal(env.step(action)[0], twin.step(action)[0])

    def test_unknown_keyword_raises_the_standard_type_error(self, env_id):
        """Tools probe constructors for keywords (TorchRL's ``GymEnv`` tries ``frameskip``) and catch Python's own
        wording: an unknown keyword must raise ``TypeError: X.__init__() got an unexpected keyword argument 'NAME'``."""
        with pytest.raises(TypeError, match=unknown_keyword_message(_constructed_class(env_id), "frameskip")):
            gym.make(env_id, frameskip=4)

    def test_each_physical_parameter_is_a_keyword_that_reaches_its_field(self, env_id, monkeypatch):
        """Each physical parameter is named once, in its family's dataclass: ``gym.make(id, name=value)`` takes every
        one, whichever task subclass is in between, and a misspelled one raises Python's own ``TypeError``."""
        assert_physical_keywords_reach_their_fields(
            _constructed_class(env_id), lambda **kwargs: gym.make(env_id, **kwargs), monkeypatch
        )

    def test_action_masks_where_actions_are_discrete(self, env_id):
        """Discrete envs publish ``info["action_mask"]`` (MaskablePPO's); continuous ones have no mask to publish."""
        env = gym.make(env_id)
        _, info = env.reset(seed=0)
        if isinstance(env.action_space, gym.spaces.Discrete):
            assert info["action_mask"].dtype == np.int8 and info["action_mask"].shape == (env.action_space.n,)
            assert np.array_equal(env.unwrapped.action_masks(), info["action_mask"].astype(bool))
        else:
            assert "action_mask" not in info and not hasattr(env.unwrapped, "action_masks")

    def test_documented_like_gymnasium(self, entry):
        cls = gym.spec(entry.id).entry_point
        module, name = cls.split(":")
        doc = getattr(__import__(module, fromlist=[name]), name).__doc__
        for section in (
            "## Description",
            "## Action Space",
            "## Observation Space",
            "## Rewards",
            "## Starting State",
            "## Episode End",
            "## Arguments",
            "## Version History",
        ):
            assert section in doc, f"{entry.id} docstring lacks {section}"
        assert entry.description

    def test_time_limit_truncates_not_terminates(self, env_id):
        spec = gym.spec(env_id)
        assert spec.max_episode_steps is not None
        env = gym.make(env_id, max_episode_steps=3)
        env.reset(seed=0)
        for _ in range(3):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        assert truncated or terminated

    @pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
    def test_native_vector_env_matches_sync_vector_env(self, vector_id, mode):
        """Sub-env i reset with seed s is gym.make(id) reset with seed s + i, bit for bit (observations, rewards, ends,
        every info key), through autoresets, in both of Gymnasium's autoreset modes (same-step: with final_obs and
        final_info)."""
        assert assert_native_matches_sync(vector_id, mode) >= 1

    def test_native_vector_env_matches_sync_vector_env_on_held_out_layouts(self, vector_id):
        """The same with ``layouts="test"``: each sub-env draws its own held-out layout at every reset, as the single
        env seeded s + i does."""
        assert assert_native_matches_sync(vector_id, AutoresetMode.NEXT_STEP, layouts="test") >= 1

    def test_native_vector_env_refuses_bad_input_and_changes_nothing(self, vector_id):
        """The native vector env keeps the single env's rules: step before reset, a wrong dtype or an unknown option
        raise, and the batch goes on as if the call had not been made."""
        envs, twin = gym.make_vec(vector_id, num_envs=2), gym.make_vec(vector_id, num_envs=2)
        with pytest.raises(gym.error.ResetNeeded):
            envs.step(envs.action_space.sample())
        envs.reset(seed=0)
        twin.reset(seed=0)
        good = envs.action_space.sample()
        for bad in (good + 0.5j, good.astype(bool), good.astype(str)):
            with pytest.raises(ValueError, match="action"):
                envs.step(bad)
        for options in ({"bogus": 1}, [1], "x"):
            with pytest.raises(ValueError, match="option"):
                envs.reset(seed=1, options=options)
        envs.action_space.seed(0)
        for _ in range(5):
            action = envs.action_space.sample()
            assert np.array_equal(envs.step(action)[0], twin.step(action)[0])

    def test_rows_envs_check_num_rows_and_leave_many_rows_to_the_vector_env(self, rows_id):
        """The rows protocol's ``num_rows``: checked by name; an instance of many rows is a vector env's core, and its
        own Gymnasium ``reset`` refuses to run one row of it."""
        cls = _env_class(rows_id)
        for bad in (0, 1.5, True, 10**7):
            with pytest.raises(ValueError, match="num_rows"):
                cls(num_rows=bad)
        core = cls(num_rows=3)
        assert core._observations.shape[0] == 3
        with pytest.raises(TypeError, match="RowsVectorEnv"):
            core.reset(seed=0)

    @pytest.mark.parametrize("value", [["rgb_array"], {"rgb_array": 1}, 3])
    def test_render_mode_of_any_type_is_refused_by_name(self, env_id, value):
        # The class itself: gym.make reads render_mode as a string before the environment sees it.
        module, name = gym.spec(env_id).entry_point.split(":")
        cls = getattr(__import__(module, fromlist=[name]), name)
        with pytest.raises(ValueError, match="render_mode"):
            cls(render_mode=value)


class TestRegistryRows(GymnasiumRowChecks):
    """The checks on every Gymnasium row of the registry."""

    @pytest.fixture(params=ENV_IDS)
    def env_id(self, request) -> str:
        return request.param

    @pytest.fixture(params=GYMNASIUM_ROWS, ids=lambda e: e.id)
    def entry(self, request):
        return request.param

    @pytest.fixture(params=VECTOR_IDS)
    def vector_id(self, request) -> str:
        return request.param

    @pytest.fixture(params=ROWS_IDS)
    def rows_id(self, request) -> str:
        return request.param


def test_make_in_a_fresh_process():
    code = "import gymnasium as gym; e = gym.make('polyenvs:" + ENV_IDS[0] + "'); e.reset(seed=0); print('ok')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda v: gym.make("polyenvs/APLiteCorridor-v0", platform=v), "platform"),
        (lambda v: gym.make("polyenvs/BeastRoll-v0", polyhedron=v), "polyhedron"),
        (lambda v: gym.make("polyenvs/BeastRoll-v0", control=v), "control"),
    ],
    ids=["platform", "polyhedron", "control"],
)
@pytest.mark.parametrize("value", [["x80pro"], {"a": 1}, np.array(["cube"]), 1])
def test_choices_of_any_type_are_refused_by_name(make, name, value):
    """A choice check names its parameter whatever the value's type: a list used to give ``TypeError: unhashable
    type: 'list'`` without a name."""
    with pytest.raises(ValueError, match=name):
        make(value)
