"""Native vector environments: many bumper carts in one process, cycled by the single env's own compiled kernels.

``gym.make_vec("polyenvs/BumperCartExplore-v0", num_envs=1024)`` builds one: :class:`BumperCartExploreEnv`
constructed with 1024 rows behind the shared :class:`polyenvs.core.rows.RowsVectorEnv`, which gives what
``SyncVectorEnv`` over ``gym.make(id)`` gives, bit for bit, in either autoreset mode.
"""

from __future__ import annotations

from polyenvs.bumper.env import BumperCartExploreEnv
from polyenvs.bumper.explore_v1 import BumperCartExploreV1Env
from polyenvs.bumper.localize import BumperCartLocalizeEnv
from polyenvs.core.rows import RowsVectorEnv

__all__ = ["BumperCartExploreV1VectorEnv", "BumperCartExploreVectorEnv", "BumperCartLocalizeVectorEnv"]


class BumperCartExploreVectorEnv(RowsVectorEnv):
    """Vector form of :class:`~polyenvs.bumper.env.BumperCartExploreEnv` (same arguments and reset options)."""

    env_class = BumperCartExploreEnv


class BumperCartExploreV1VectorEnv(RowsVectorEnv):
    """Vector form of :class:`~polyenvs.bumper.explore_v1.BumperCartExploreV1Env` (same arguments and reset options)."""

    env_class = BumperCartExploreV1Env


class BumperCartLocalizeVectorEnv(RowsVectorEnv):
    """Vector form of :class:`~polyenvs.bumper.localize.BumperCartLocalizeEnv` (same arguments and reset options)."""

    env_class = BumperCartLocalizeEnv
