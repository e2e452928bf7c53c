"""The bump-only cart: a Lego cart that maps and localizes itself with one bump switch and two wheel encoders.

Paper: Ken Dye, "Mapping with only a bumper" (``../shared/seeds/001_*.txt``).

| module | what |
| --- | --- |
| ``odometry`` | the paper's arc odometry from left and right wheel travels, derived in its docstring |
| ``maps`` | polygonal maps: the paper's arena, mazes, user polygons |
| ``cart`` | the batched, closed-form cycle simulator (turn, drive to the bump, back up) |
| ``env`` | the family base (:class:`~polyenvs.bumper.env.BumperCartEnv`: cycle, log, resets) and ``polyenvs/BumperCartExplore-v0`` |
| ``explore_v1`` | ``polyenvs/BumperCartExplore-v1``: a budget of cycles, coverage against its upper bound |
| ``explore_v2`` | ``polyenvs/BumperCartExplore-v2``: v1 with each bump credited to the wall its bumper touched |
| ``localize`` | ``polyenvs/BumperCartLocalize-v0``: active localization with the paper's filter inside the environment |
| ``bump_space`` | the paper's bump-space filter as compiled kernels (the estimator and the localization task run it) |
| ``rendering`` | top-down frames |
"""

from polyenvs.bumper.env import BumperCartExploreEnv, LocalizationContext
from polyenvs.bumper.maps import MAPS, BumperMap, make_map

__all__ = ["MAPS", "BumperCartExploreEnv", "BumperMap", "LocalizationContext", "make_map"]
