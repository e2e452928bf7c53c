"""The bump-only cart: a Lego cart that maps and localizes itself with one bump switch and two wheel encoders.

Paper: Ken Dye, "Mapping with only a bumper" (``../shared/seeds/001_*.txt``).

| module | what |
| --- | --- |
| ``odometry`` | the paper's arc odometry from left and right wheel travels, derived in its docstring |
| ``maps`` | polygonal maps: the paper's arena, mazes, user polygons |
| ``cart`` | the batched, closed-form cycle simulator (turn, drive to the bump, back up) |
| ``env`` | ``polyenvs/BumperCartExplore-v0`` |
| ``localizers`` | dead reckoning and the paper's bump-space Monte Carlo localizer (estimators for ``polyenvs localize``) |
| ``rendering`` | top-down frames |
"""
