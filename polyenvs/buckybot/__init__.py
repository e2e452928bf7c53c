"""Buckybot: the truncated-icosahedron robot that tips from face to face on a honeycomb lattice.

Paper: "Buckybot: preliminary control and mapping algorithms" (``../shared/seeds/000_*.txt``).

| module | what |
| --- | --- |
| ``geometry`` | the icosahedron: faces 1-20, actuators A-L, the tipping table, sensor directions |
| ``simulator`` | the batched core: tipping with the Vicon noise model, wall contact, range sensing |
| ``sensors`` | the LV-MaxSonar-EZ model (eq. 6) and the paper's wall identification (Heron) |
| ``floor_plans`` | built-in rooms, the seeded room generator |
| ``mapping`` | occupancy grids from true or dead-reckoned poses (the paper's Figure 8) |
| ``env``, ``wall_follow``, ``explore``, ``goal`` | the Gymnasium environments |
| ``rendering`` | top-down frames |
| ``analysis`` | the paper's dead-reckoning Monte Carlo and Figure 8 (``python -m polyenvs.buckybot.analysis``) |
"""

from polyenvs.buckybot.env import BuckybotAction
from polyenvs.buckybot.explore import BuckybotExploreEnv
from polyenvs.buckybot.goal import BuckybotGoalEnv
from polyenvs.buckybot.wall_follow import BuckybotWallFollowEnv

__all__ = ["BuckybotAction", "BuckybotExploreEnv", "BuckybotGoalEnv", "BuckybotWallFollowEnv"]
