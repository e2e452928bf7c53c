"""The bump-only cart: a Lego cart that maps and localizes itself with one bump switch and two wheel encoders.

Paper: Ken Dye, "Mapping with only a bumper" (``../shared/seeds/001_*.txt``).

| module | what |
| --- | --- |
| ``odometry`` | the paper's arc odometry from left and right wheel travels, derived in its docstring |
| ``maps`` | polygonal maps: the paper's arena, mazes, user polygons |
| ``cart`` | the batched, closed-form cycle simulator (turn, drive to the bump, back up) |
| ``env``, ``vector`` | ``polyenvs/BumperCartExplore-v0`` and its native vector env |
| ``localizers`` | dead reckoning and the paper's bump-space Monte Carlo localizer (estimators for ``polyenvs localize``) |
| ``rendering`` | top-down frames |
"""

from polyenvs.bumper.env import BumperCartExploreEnv, LocalizationContext
from polyenvs.bumper.maps import MAPS, BumperMap, make_map

__all__ = ["MAPS", "BumperCartExploreEnv", "BumperMap", "LocalizationContext", "make_map"]
