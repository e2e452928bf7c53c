"""Helpers shared by the vector-environment tests."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from polyenvs.core.episode_metrics import RecordEpisodeMetrics


def assert_same(a, b, where=""):
    """Recursive bit-for-bit equality of vector-env outputs (arrays, object arrays, nested info dicts)."""
    if isinstance(a, dict):
        assert set(a) == set(b), f"{where}: keys differ: {set(a) ^ set(b)}"
        for key in a:
            assert_same(a[key], b[key], f"{where}/{key}")
    elif isinstance(a, tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert a.shape == b.shape, where
        for i, (x, y) in enumerate(zip(a.tolist(), b.tolist(), strict=True)):
            if isinstance(x, np.ndarray | dict):
                assert_same(x, y, f"{where}[{i}]")
            else:
                assert type(x) is type(y) and x == y, where
                assert not isinstance(x, float | np.floating) or math.copysign(1.0, x) == math.copysign(1.0, y), (
                    f"{where}: {x} vs {y}"
                )
    else:
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape, f"{where}: {a.dtype}{a.shape} vs {b.dtype}{b.shape}"
        # Bytes, not ==: == takes -0.0 for 0.0 (and never NaN for NaN), which hid a sign difference.
        assert a.tobytes() == b.tobytes(), f"{where}: {a} vs {b}"


def assert_native_matches_sync(env_id: str, mode, steps: int = 75, **make_kwargs) -> int:
    """Step the native vector env and ``SyncVectorEnv`` of ``env_id`` side by side on the same seeded random
    actions, bit for bit, through autoresets; returns how many episodes ended. The sync env's copies are wrapped in
    ``RecordEpisodeMetrics``: the native env applies the time limit itself, and reports the metrics there too."""
    make = {"num_envs": 4, "max_episode_steps": 30, **make_kwargs}
    native = gym.make_vec(env_id, vectorization_mode="vector_entry_point", autoreset_mode=mode, **make)
    sync = gym.make_vec(
        env_id,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        wrappers=[RecordEpisodeMetrics],
        **make,
    )
    assert native.metadata["autoreset_mode"] == mode
    assert_same(native.reset(seed=11), sync.reset(seed=11), "reset")
    native.action_space.seed(0)
    ended = 0
    for t in range(steps):
        actions = native.action_space.sample()
        result = native.step(actions)
        assert_same(result, sync.step(actions), f"step {t}")
        ended += int((result[2] | result[3]).sum())
    # A second seeded reset, with a list of seeds as SyncVectorEnv takes them.
    assert_same(native.reset(seed=[3, None, 5, 6]), sync.reset(seed=[3, None, 5, 6]), "list reset")
    native.close()
    sync.close()
    return ended
