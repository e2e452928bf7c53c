"""What a beast policy reads off an observation and its space: the sensor parts by name, the beast, its joint limits.

The layout is the environment's (:func:`polyenvs.beast.sensors.observation_layout_of`): encoder angles, tilt
switches, foot contacts, then any task part (a command) or privileged tail, which the policies ignore.
"""

from __future__ import annotations

import numpy as np

from polyenvs.beast import kinematics as K
from polyenvs.beast.sensors import observation_layout_of

__all__ = ["joint_ranges_of", "n_limbs_of", "polyhedron_of", "split_observation"]


def split_observation(obs: np.ndarray) -> dict[str, np.ndarray]:
    """A beast observation by part name (``sensors.observation_layout``), as float64 views."""
    obs = np.asarray(obs, dtype=np.float64)
    return {name: obs[part] for name, part in observation_layout_of(obs.shape[-1]).items()}


def n_limbs_of(obs_dim: int) -> int:
    """The number of limbs of a beast whose observations have this length."""
    part = observation_layout_of(obs_dim)["foot_contact"]
    return part.stop - part.start


def joint_ranges_of(observation_space) -> np.ndarray:
    """The joint limits (3, 2) in radians, rows joint 1, 2, 3, from a beast observation space: the encoder angles'
    bounds are the limits, the same for every limb (the actions scale to them)."""
    n_limbs = n_limbs_of(int(np.prod(observation_space.shape)))
    nj = 3 * n_limbs
    low = np.asarray(observation_space.low, dtype=np.float64).ravel()[:nj].reshape(n_limbs, 3)
    high = np.asarray(observation_space.high, dtype=np.float64).ravel()[:nj].reshape(n_limbs, 3)
    if not (np.isfinite(low).all() and np.isfinite(high).all() and (low == low[0]).all() and (high == high[0]).all()):
        raise ValueError("observation_space must bound the encoder angles by joint limits shared by every limb")
    return np.stack([low[0], high[0]], axis=1)


def polyhedron_of(n_limbs: int) -> str:
    return {v: k for k, v in K.N_LIMBS.items()}[n_limbs]
