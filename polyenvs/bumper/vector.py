"""Native vector environments: many bumper carts in one process, cycled by the single env's own compiled kernels.

``gym.make_vec("polyenvs/BumperCartExplore-v0", num_envs=1024)`` builds one: :class:`BumperCartExploreEnv`
constructed with 1024 rows behind the shared :class:`polyenvs.core.rows.RowsVectorEnv`, which gives what
``SyncVectorEnv`` over ``gym.make(id)`` gives, bit for bit, in either autoreset mode.
"""

from __future__ import annotations

from polyenvs.bumper.env import BumperCartExploreEnv
from polyenvs.bumper.explore_v1 import BumperCartExploreV1Env
from polyenvs.bumper.explore_v2 import BumperCartExploreV2Env
from polyenvs.bumper.localize import BumperCartLocalizeEnv
from polyenvs.core.rows import RowsVectorEnv

__all__ = [
    "BumperCartExploreV1VectorEnv",
    "BumperCartExploreV2VectorEnv",
    "BumperCartExploreVectorEnv",
    "BumperCartLocalizeVectorEnv",
]


class BumperCartExploreVectorEnv(RowsVectorEnv):
    """Vector form of :class:`~polyenvs.bumper.env.BumperCartExploreEnv` (same arguments and reset options)."""

    env_class = BumperCartExploreEnv


class BumperCartExploreV1VectorEnv(RowsVectorEnv):
    """Vector form of :class:`~polyenvs.bumper.explore_v1.BumperCartExploreV1Env` (same arguments and reset options;
    a row's episode ends at its ``budget_cycles``, as the single env's does, whatever ``max_episode_steps``)."""

    env_class = BumperCartExploreV1Env
    _core: BumperCartExploreV1Env

    def _step_result(self, restart):
        rewards, terminated, truncated = super()._step_result(restart)
        return rewards, terminated, truncated | self._core.budget_spent()


class BumperCartExploreV2VectorEnv(BumperCartExploreV1VectorEnv):
    """Vector form of :class:`~polyenvs.bumper.explore_v2.BumperCartExploreV2Env` (as v1's)."""

    env_class = BumperCartExploreV2Env


class BumperCartLocalizeVectorEnv(RowsVectorEnv):
    """Vector form of :class:`~polyenvs.bumper.localize.BumperCartLocalizeEnv` (same arguments and reset options)."""

    env_class = BumperCartLocalizeEnv
