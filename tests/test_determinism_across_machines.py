"""Same seed, same episode on another machine: numpy and OpenBLAS pick CPU-specific kernels at run time (AVX-512 or
AVX2 SIMD for sines and square roots, a GEMM kernel per core type), and these differ in the last bit. An episode
must not depend on that choice. Each run below forces other kernels in a fresh process (``OPENBLAS_CORETYPE``,
``NPY_DISABLE_CPU_FEATURES``), as another machine would pick them, and compares digests of whole rollouts of
every registry row, a hand baseline and a committed trained agent included, bit for bit.

What this cannot show on a machine without AVX-512: numpy's float64 transcendental ufuncs (``np.arctan2``,
``np.arcsin``, ``np.power``, ``np.log``, ...) run SVML or AVX-512 kernels only where the CPU has AVX-512, and the
C library elsewhere, so switching features off here changes nothing. A Buckybot episode through them differed between
an AVX-512 machine and an AVX2 one; tests/test_libm_only.py refuses them in the families' and baselines' modules,
which use polyenvs.core.libm (the C library) instead."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

_ROLLOUTS = r"""
import hashlib, importlib
import gymnasium as gym, numpy as np, polyenvs
from baselines import make_policy
from polyenvs.registry import REGISTRY

def digest_gymnasium(env_id, policy=None, seeds=range(4), steps=120):
    env, h = gym.make(env_id), hashlib.sha256()
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(seed)
        state, start = None, True
        h.update(obs.tobytes())
        for _ in range(steps):
            if policy is None:
                action = env.action_space.sample()
            else:
                action, state = policy.predict(obs, state=state, episode_start=[start])
            start = False
            obs, reward, terminated, truncated, _ = env.step(action)
            h.update(obs.tobytes() + np.float64(reward).tobytes())
            if terminated or truncated:
                break
    return h.hexdigest()[:16]

def digest_parallel(module, seeds=range(3), cycles=80):
    env, h = importlib.import_module(module).parallel_env(), hashlib.sha256()
    for seed in seeds:
        observations, _ = env.reset(seed=seed)
        for cycle in range(cycles):
            if not env.agents:
                break
            actions = {}
            for i, agent in enumerate(env.agents):
                space = env.action_space(agent)
                space.seed(seed * 100_003 + cycle * 101 + i)
                actions[agent] = space.sample()
            observations, *_ = env.step(actions)
            h.update(b"".join(observations[a].tobytes() for a in sorted(observations)))
    return h.hexdigest()[:16]

for entry in REGISTRY:
    digest = digest_gymnasium if entry.kind == "gymnasium" else digest_parallel
    print(entry.id, digest(entry.id))
env = gym.make("polyenvs/BeastTumble-v0")
for name in ("paper", "benchmarks/agents/polyenvs__BeastTumble-v0/ppo/seed0"):
    policy = make_policy(name, "polyenvs/BeastTumble-v0", env.observation_space, env.action_space)
    print(name, digest_gymnasium("polyenvs/BeastTumble-v0", policy, seeds=(1015, 1016, 1017), steps=600))
"""

#: Kernel choices another machine could make: OpenBLAS's oldest and an AVX-512 core type, and numpy without its
#: AVX-512 kernels (a no-op on a CPU that has none, where the default run already uses the AVX2 ones).
_MACHINES = {
    "openblas-prescott": {"OPENBLAS_CORETYPE": "Prescott"},
    "openblas-skylakex": {"OPENBLAS_CORETYPE": "SkylakeX"},
    "numpy-without-avx512": {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"},
}


def _digests(extra_env: dict) -> str:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), **extra_env}
    run = subprocess.run(
        [sys.executable, "-c", _ROLLOUTS], capture_output=True, text=True, env=env, timeout=600, check=False,
        cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout


@pytest.fixture(scope="module")
def here() -> str:
    return _digests({})


#: Kernel choices this CPU must have to run at all: OpenBLAS's SkylakeX kernels are AVX-512 code (SIGILL without it).
_NEEDS = {"openblas-skylakex": "AVX512F"}


def _cpu_has(feature: str) -> bool:
    from numpy._core._multiarray_umath import __cpu_features__

    return bool(__cpu_features__.get(feature, False))


@pytest.mark.slow
@pytest.mark.parametrize("machine", list(_MACHINES))
def test_episodes_do_not_depend_on_the_cpu_kernels(here, machine):
    if machine in _NEEDS and not _cpu_has(_NEEDS[machine]):
        pytest.skip(f"this CPU has no {_NEEDS[machine]}: {_MACHINES[machine]} cannot run here")
    there = _digests(_MACHINES[machine])
    differing = [a.split()[0] for a, b in zip(here.splitlines(), there.splitlines(), strict=True) if a != b]
    assert not differing, f"with {_MACHINES[machine]} these episodes differ: {differing}"


def test_start_states_are_rounded_so_last_bits_cannot_differ():
    """The mechanism the test above guards for the beasts: a drawn start state lies on the 1e-9 grid."""
    import gymnasium as gym

    import polyenvs  # noqa: F401

    env = gym.make("polyenvs/BeastRecover-v0").unwrapped
    env.reset(seed=3)
    qpos = env.data.qpos  # after mj_forward MuJoCo leaves qpos as set (it normalises the quaternion only in use)
    assert np.array_equal(qpos[7:], np.round(qpos[7:], 9))
