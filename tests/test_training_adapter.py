"""The SB3 VecEnv adapter over the native vector envs gives what DummyVecEnv over gym.make gives, resets included."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import gymnasium as gym  # noqa: E402
from gymnasium.vector import AutoresetMode  # noqa: E402
from pettingzoo import ParallelEnv  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor  # noqa: E402

import polyenvs  # noqa: E402
from polyenvs.core.episode_metrics import RecordEpisodeMetrics  # noqa: E402
from polyenvs.errors import InputError  # noqa: E402
from polyenvs.training.vec_adapter import (  # noqa: E402
    NativeVecEnvAdapter,
    ParallelVecEnvAdapter,
    make_native_vector_env,
    make_training_vec_env,
)


def _same(a, b) -> bool:
    """Equal values, numpy arrays bit for bit with the same dtype, dicts key by key."""
    if isinstance(a, dict) or isinstance(b, dict):
        return isinstance(a, dict) and isinstance(b, dict) and set(a) == set(b) and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)
    return a == b


# Small rooms and short episodes: ~300 steps see both terminations and time limits.
CASES = [
    ("polyenvs/BuckybotWallFollow-v0", {"max_episode_steps": 40}),
    ("polyenvs/BuckybotExplore-v0", {"floor_plan": "corner", "max_episode_steps": 60}),
    ("polyenvs/BuckybotGoal-v0", {"floor_plan": "corner", "max_episode_steps": 40}),
]


@pytest.mark.parametrize(("env_id", "kwargs"), CASES, ids=[c[0].split("/")[1] for c in CASES])
def test_adapter_matches_dummy_vec_env(env_id, kwargs):
    """Observations, rewards, dones, terminal observations, TimeLimit.truncated, the finished episodes' infos
    (episode_metrics as plain floats, time limits included) and action masks equal DummyVecEnv's over gym.make
    under RecordEpisodeMetrics (as training builds it), seeded s + i, through autoresets and a re-seeded reset."""
    n, seed = 4, 17
    adapter = NativeVecEnvAdapter(make_native_vector_env(env_id, n, kwargs))
    dummy = DummyVecEnv([lambda: RecordEpisodeMetrics(gym.make(env_id, **kwargs)) for _ in range(n)])
    rng = np.random.default_rng(0)
    terminated = truncated = 0
    for episode_seed in (seed, seed + 100):
        adapter.seed(episode_seed)
        dummy.seed(episode_seed)
        obs_a, obs_d = adapter.reset(), dummy.reset()
        assert _same(obs_a, obs_d)
        for i in range(n):
            assert _same(adapter.reset_infos[i], dummy.reset_infos[i])
        for t in range(150):
            masks_a, masks_d = adapter.env_method("action_masks"), dummy.env_method("action_masks")
            assert all(m.dtype == bool for m in masks_a)
            assert _same(np.stack(masks_a), np.stack(masks_d)), t
            actions = rng.integers(0, 3, n)
            obs_a, rew_a, done_a, infos_a = adapter.step(actions)
            obs_d, rew_d, done_d, infos_d = dummy.step(actions)
            assert _same(obs_a, obs_d), t
            assert _same(rew_a, rew_d), t
            assert _same(done_a, done_d), t
            for i in range(n):
                assert infos_a[i]["TimeLimit.truncated"] == infos_d[i]["TimeLimit.truncated"]
                if done_d[i]:
                    assert _same(infos_a[i]["terminal_observation"], infos_d[i]["terminal_observation"])
                    assert not _same(infos_a[i]["terminal_observation"], obs_a[i])  # obs is the new episode's
                    metrics = infos_a[i]["episode_metrics"]
                    assert metrics and all(type(v) is float for v in metrics.values())
                    assert metrics == {k: float(v) for k, v in infos_d[i]["episode_metrics"].items()}
                    assert _same(infos_a[i], infos_d[i])  # the whole last info, as DummyVecEnv keeps it
                    truncated += infos_d[i]["TimeLimit.truncated"]
                    terminated += not infos_d[i]["TimeLimit.truncated"]
                else:
                    assert "terminal_observation" not in infos_a[i]
    assert truncated > 0 or terminated > 0
    adapter.close()
    dummy.close()


def test_parity_cases_see_both_kinds_of_episode_end():
    """The parity test above covers terminations and time limits (else it would prove less than it says)."""
    kinds = set()
    for env_id, kwargs in CASES:
        venv = DummyVecEnv([lambda env_id=env_id, kwargs=kwargs: gym.make(env_id, **kwargs) for _ in range(4)])
        venv.seed(17)
        venv.reset()
        rng = np.random.default_rng(0)
        for _ in range(150):
            _, _, dones, infos = venv.step(rng.integers(0, 3, 4))
            kinds.update(infos[i]["TimeLimit.truncated"] for i in np.flatnonzero(dones))
        venv.close()
    assert kinds == {True, False}


def test_adapter_requires_same_step_autoreset():
    venv = gym.make_vec("polyenvs/BuckybotWallFollow-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert venv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    with pytest.raises(ValueError, match="SAME_STEP"):
        NativeVecEnvAdapter(venv)


def test_adapter_attributes_and_methods():
    adapter = NativeVecEnvAdapter(make_native_vector_env("polyenvs/BuckybotWallFollow-v0", 3))
    assert adapter.num_envs == 3
    assert adapter.observation_space.shape == (19,) and adapter.action_space.n == 3
    assert adapter.render_mode is None
    assert adapter.has_attr("action_masks")
    assert not adapter.has_attr("no_such_attribute")
    assert adapter.get_attr("max_episode_steps") == [500, 500, 500]
    assert adapter.env_is_wrapped(gym.Wrapper) == [False, False, False]
    adapter.seed(0)
    adapter.reset()
    masks = adapter.env_method("action_masks", indices=[2])
    assert len(masks) == 1 and masks[0].shape == (3,) and masks[0].dtype == bool
    adapter.set_attr("max_episode_steps", 5)
    for _ in range(5):
        _, _, dones, infos = adapter.step(np.zeros(3, dtype=np.int64))
    assert dones.all() and all(info["TimeLimit.truncated"] for info in infos)
    adapter.close()


def test_info_keys_all_gives_every_key_on_every_row():
    env_id = "polyenvs/BuckybotWallFollow-v0"
    adapter = NativeVecEnvAdapter(make_native_vector_env(env_id, 2), info_keys="all")
    dummy = DummyVecEnv([lambda: gym.make(env_id) for _ in range(2)])
    adapter.seed(5)
    dummy.seed(5)
    adapter.reset()
    dummy.reset()
    for _ in range(3):
        _, _, _, infos_a = adapter.step(np.array([1, 2]))
        _, _, _, infos_d = dummy.step(np.array([1, 2]))
        for a, d in zip(infos_a, infos_d, strict=True):
            assert _same(a, d)
    adapter.close()


def test_make_training_vec_env_picks_native_or_dummy():
    native = make_training_vec_env("polyenvs/BuckybotWallFollow-v0", 2, seed=0)
    assert isinstance(native, VecMonitor) and isinstance(native.venv, NativeVecEnvAdapter)
    native.close()
    dummy = make_training_vec_env("polyenvs/BuckybotWallFollow-v0", 2, seed=0, vec_env="dummy")
    assert isinstance(dummy, DummyVecEnv)
    dummy.close()
    cartpole = make_training_vec_env("CartPole-v1", 2, seed=0)  # no native vector env: DummyVecEnv
    assert isinstance(cartpole, DummyVecEnv)
    cartpole.close()
    with pytest.raises(InputError, match="floor_plan"):
        make_training_vec_env("polyenvs/BuckybotWallFollow-v0", 2, env_kwargs={"floor_plan": "nowhere"})
    with pytest.raises(InputError, match="no same-step autoreset mode"):
        make_training_vec_env("CartPole-v1", 2, vec_env="native")  # Gymnasium's own is next-step only
    with pytest.raises(InputError, match="no native vector env"):
        make_training_vec_env("Pendulum-v1", 2, vec_env="native")


def test_monitor_episode_returns_match():
    """VecMonitor over the adapter reports the episodes Monitor inside DummyVecEnv reports."""
    env_id = "polyenvs/BuckybotGoal-v0"
    native = make_training_vec_env(env_id, 3, seed=2, env_kwargs={"max_episode_steps": 20})
    dummy = make_training_vec_env(env_id, 3, seed=2, env_kwargs={"max_episode_steps": 20}, vec_env="dummy")
    native.reset()
    dummy.reset()
    rng = np.random.default_rng(1)
    seen = 0
    for _ in range(60):
        actions = rng.integers(0, 3, 3)
        _, _, dones, infos_n = native.step(actions)
        _, _, _, infos_d = dummy.step(actions)
        for i in np.flatnonzero(dones):
            seen += 1
            assert infos_n[i]["episode"]["l"] == infos_d[i]["episode"]["l"]
            assert infos_n[i]["episode"]["r"] == pytest.approx(infos_d[i]["episode"]["r"], abs=1e-5)
    assert seen >= 3
    native.close()
    dummy.close()


def test_every_native_id_builds_in_same_step_mode():
    for entry in polyenvs.registry.REGISTRY:
        if getattr(entry, "vector_entry_point", None) is not None:  # Gymnasium rows with a native vector env
            venv = make_native_vector_env(entry.id, 2)
            assert venv.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
            venv.close()


# ------------------------------------------------------------------------------ PettingZoo robots as VecEnv slots


class _Leaving(ParallelEnv):
    """Three robots; robot j leaves after j + 2 cycles; observation = [cycle, seed % 7]; reward 1 per cycle."""

    metadata = {"name": "leaving_v0"}
    render_mode = None

    def __init__(self):
        self.possible_agents = ["r0", "r1", "r2"]
        self._obs_space = gym.spaces.Box(0, 100, (2,), np.float32)
        self._act_space = gym.spaces.Discrete(2)

    def observation_space(self, agent):
        return self._obs_space

    def action_space(self, agent):
        return self._act_space

    def reset(self, seed=None, options=None):
        self.agents, self.cycle, self.tag = list(self.possible_agents), 0, (seed or 0) % 7
        return {a: self._obs() for a in self.agents}, {a: {} for a in self.agents}

    def _obs(self):
        return np.array([self.cycle, self.tag], dtype=np.float32)

    def step(self, actions):
        assert set(actions) == set(self.agents)
        self.cycle += 1
        leaving = {a: self.cycle >= int(a[1]) + 2 for a in self.agents}
        obs = {a: self._obs() for a in self.agents}
        rewards = dict.fromkeys(self.agents, 1.0)
        infos = {a: {"episode_metrics": {"left_at": float(self.cycle)}} if leaving[a] else {} for a in self.agents}
        truncations = dict.fromkeys(self.agents, False)
        self.agents = [a for a in self.agents if not leaving[a]]
        return obs, rewards, leaving, truncations, infos


def test_parallel_adapter_slots_robots_and_restarts_a_copy_when_all_have_left():
    venv = ParallelVecEnvAdapter([_Leaving(), _Leaving()])
    assert venv.num_envs == 6
    venv.seed(5)
    obs = venv.reset()
    assert obs[:, 1].tolist() == [5, 5, 5, 6, 6, 6]  # copy k seeded 5 + k
    actions = np.zeros(6, dtype=np.int64)
    dones_seen, episodes = [], []
    for _ in range(4):
        venv.step_async(actions)
        obs, rewards, dones, infos = venv.step_wait()
        dones_seen.append(dones.tolist())
        episodes.append([info.get("episode", {}).get("l") for info in infos])
    # r0 leaves after 2 cycles, r1 after 3, r2 after 4 (then the copy restarts and fillers end too)
    assert dones_seen[1] == [True, False, False] * 2 and episodes[1] == [2, None, None] * 2
    assert dones_seen[2] == [False, True, False] * 2
    assert dones_seen[3] == [True, True, True] * 2 and episodes[3] == [None, None, 4] * 2
    assert obs[:, 0].tolist() == [0] * 6 and obs[:, 1].tolist() == [0] * 6  # restarted, unseeded
    assert rewards.tolist() == [0, 0, 1] * 2  # fillers get nothing
    assert infos[2]["episode_metrics"] == {"left_at": 4.0} and "terminal_observation" in infos[0]
