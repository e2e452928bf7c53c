"""Native vector environments: many Buckybots in one process, stepped by the single env's own compiled kernels.

``gym.make_vec("polyenvs/BuckybotWallFollow-v0", num_envs=1024)`` builds one: the task class itself, constructed
with 1024 rows (see :mod:`polyenvs.buckybot.env`), behind Gymnasium's ``VectorEnv`` API through the shared
:class:`polyenvs.core.rows.RowsVectorEnv`.

It gives what ``SyncVectorEnv`` over ``gym.make(id)`` gives, bit for bit, in either of Gymnasium's autoreset modes
(``autoreset_mode=AutoresetMode.NEXT_STEP``, the default, or ``SAME_STEP``, with ``info["final_obs"]`` and
``info["final_info"]``, which Stable-Baselines3-style training needs): row ``i`` reset with seed ``s`` draws from the
generator a single env reset with seed ``s + i`` would have (:mod:`polyenvs.core.streams`), through autoresets;
``info`` carries the single env's keys in the vector convention (an array per key, with its ``_key`` mask;
``episode_metrics`` is a dict of arrays); ``floor_plan="random"`` draws a room per row. Only the speed differs.
"""

from __future__ import annotations

from polyenvs.buckybot.env import BuckybotEnv
from polyenvs.buckybot.explore import BuckybotExploreEnv
from polyenvs.buckybot.goal import BuckybotGoalEnv
from polyenvs.buckybot.wall_follow import BuckybotWallFollowEnv
from polyenvs.core.rows import RowsVectorEnv

__all__ = ["BuckybotExploreVectorEnv", "BuckybotGoalVectorEnv", "BuckybotVectorEnv", "BuckybotWallFollowVectorEnv"]


class BuckybotVectorEnv(RowsVectorEnv):
    """``num_envs`` robots of one Buckybot task (arguments: :class:`polyenvs.core.rows.RowsVectorEnv`'s and the
    task's)."""

    env_class: type[BuckybotEnv] = BuckybotEnv


class BuckybotWallFollowVectorEnv(BuckybotVectorEnv):
    """Vector form of :class:`~polyenvs.buckybot.wall_follow.BuckybotWallFollowEnv` (same arguments)."""

    env_class = BuckybotWallFollowEnv


class BuckybotExploreVectorEnv(BuckybotVectorEnv):
    """Vector form of :class:`~polyenvs.buckybot.explore.BuckybotExploreEnv` (same arguments)."""

    env_class = BuckybotExploreEnv


class BuckybotGoalVectorEnv(BuckybotVectorEnv):
    """Vector form of :class:`~polyenvs.buckybot.goal.BuckybotGoalEnv` (same arguments and reset options)."""

    env_class = BuckybotGoalEnv
