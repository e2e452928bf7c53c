"""``obstacle_field_v0``: robots cross an outdoor obstacle field to a goal (the paper's Maxelbot experiment).

``from polyenvs.swarm import obstacle_field_v0; env = obstacle_field_v0.parallel_env()`` (3 robots; ``n_robots=8``
for eight).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from polyenvs.core.layouts import LayoutSplit, SplitParameter, documents_layouts
from polyenvs.core.parameters import documents_arguments, parameter
from polyenvs.swarm.env import Episode, Layout, SwarmEnv, SwarmParams, module_constructors
from polyenvs.swarm.layouts import (
    WALL_MARGIN_M,
    ObstacleFieldEpisodes,
    box_walls,
    layout_obstacle_slots,
    random_obstacles,
    start_block,
)

__all__ = ["MAX_CYCLES", "N_ROBOTS", "ObstacleFieldEnv", "env", "parallel_env", "raw_env"]

#: Defaults: what ``parallel_env()`` builds and what the commands evaluate (the registry row adds nothing).
N_ROBOTS = 3
MAX_CYCLES = 1000
#: The open field of the feasibility study (10 x 6 m); it grows with the start block for large swarms.
FIELD_LENGTH_M = 10.0
FIELD_WIDTH_M = 6.0
START_SPACING_M = 0.5
#: Obstacles (*ours*): radius 0.15-0.35 m, at least GAP_M apart rim to rim and from the goal and the starts.
OBSTACLE_RADIUS_M = (0.15, 0.35)
GAP_M = 0.6
N_OBSTACLES = 5
#: Held-out layouts (*ours*): 3-7 obstacles and the goal anywhere in the middle three fifths of the far end; the
#: radius splits them: train 0.15-0.35 m (the default's), test 0.38-0.5 m (larger rocks than any default field).
LAYOUT_SPLIT = LayoutSplit(
    (SplitParameter("obstacle radius", "m", train=OBSTACLE_RADIUS_M, test=(0.38, 0.5)),),
    varies="3-7 obstacles placed as in the default field, the goal anywhere in the middle three fifths of the far end",
)
LAYOUT_GOAL_SPAN = (0.2, 0.8)


@dataclass(frozen=True)
class ObstacleFieldParams(SwarmParams):
    """The swarm's parameters, with the obstacle field's rougher ground and wider arrival distance."""

    terrain_noise: float = parameter(
        0.1, 0.0, 0.3, "", "ours: sd of the per-wheel speed factor per step (rough ground: twice the corridor's)"
    )
    goal_radius_m: float = parameter(0.5, 0.1, 1.5, "m", "ours: a robot this close to the light has arrived")


@documents_layouts(LAYOUT_SPLIT)
@documents_arguments(ObstacleFieldParams)
class ObstacleFieldEnv(ObstacleFieldEpisodes, SwarmEnv):
    """N Maxelbot-like robots cross an open field with obstacles at seeded random places to a goal light.

    ## Description
    Hettiarachchi and Spears, "Physicomimetics for mobile robot obstacle avoidance" (``seeds/004``), Section 4:
    outdoors on grass "of average height 8 cm [...] the ground slope can change rapidly [...] by up to 20°", with
    "large obstacles at random locations in the path of the Maxelbot". The terrain is wheel-speed noise: every
    step each wheel's speed is multiplied by ``1 + terrain_noise * N(0, 1) + drift``, where the per-episode drift
    (half the sd) pulls the robot to one side as a slope does. The field is 10 x 6 m with walls around it (the
    feasibility study); larger swarms start in a square block and the field grows to hold it.

    ## Action Space
    ``Box(-1, 1, (2,), float32)`` per robot: left and right motor power as fractions of full power.

    ## Observation Space
    As in ``corridor_v0`` (``env.observation_structure``): ``ir`` (4, Maxelbot raw / 550, 0 = nothing seen),
    ``light`` (bearing / pi, intensity), ``neighbours`` (range, bearing, mask for the nearest robots in
    communication range), ``powers`` (2).

    ## Rewards
    ``reward_progress`` (10 per metre closer to the goal), ``reward_collision`` (-1 per step in contact),
    ``reward_arrival`` (+10).

    ## Starting State
    Robots in a square block (0.5 m spacing) centred 1 m from the left wall, headings towards +x ± 10° (sd); the
    goal 1 m from the right wall at a height drawn uniformly in the middle third; ``n_obstacles`` discs placed
    uniformly between, at least 0.6 m apart and from the starts and the goal.

    ## Episode End
    A robot terminates (leaving ``env.agents``) within ``goal_radius_m`` of the goal, or on contact if
    ``terminate_on_collision``; all are truncated after ``max_cycles`` steps.

    ## Info
    As in ``corridor_v0``: ``pose``, ``collisions``, ``distance_to_goal_m``, ``nearest_obstacle_cm``,
    ``motor_powers``, ``turning_angle_deg``, ``stopped``, reward terms and ``episode_metrics``.

    ## Task score
    ``success_rate`` (max, ceiling 1; ties at the ceiling broken by the lower ``time_to_goal_s``): the fraction of
    the robots that reached the goal light. The paper's outdoor experiment asks the Maxelbots to cross the field to
    the light, and its failure mode is the halt short of it (the potential-field trap, counted by ``stopped``),
    which success measures directly.

    ## Arguments
    ``n_robots`` (default 3) and ``n_obstacles`` (default 5, 0-200; ``layouts="train"`` and ``"test"`` draw their own
    count and refuse another), then every keyword of ``corridor_v0`` with ``platform="maxelbot"`` and
    ``max_cycles=1000`` as defaults, and its physical and sensing parameters:

    | keyword | default | meaning (range) |
    | --- | --- | --- |
    {layouts}
    {arguments}

    ## Version History
    {version_history}
    """

    metadata = {**SwarmEnv.metadata, "name": "obstacle_field_v0"}
    default_platform = "maxelbot"

    params_class = ObstacleFieldParams
    default_radius_m = OBSTACLE_RADIUS_M
    layout_goal_span = LAYOUT_GOAL_SPAN

    def __init__(self, *, n_robots: int = N_ROBOTS, n_obstacles: int = N_OBSTACLES, max_cycles: int = MAX_CYCLES,
                 layouts: str = "default", **kwargs):  # fmt: skip
        self.n_obstacles = layout_obstacle_slots(n_obstacles, layouts, N_OBSTACLES)
        super().__init__(n_robots=n_robots, max_cycles=max_cycles, layouts=layouts, **kwargs)

    def _block(self) -> tuple[int, float]:
        columns = math.ceil(math.sqrt(self.n_robots))
        return columns, (columns - 1) * START_SPACING_M

    def _fixed_layout(self) -> Layout:
        _, side = self._block()
        length, width = FIELD_LENGTH_M + side, max(FIELD_WIDTH_M, side + 3.0)
        return Layout(walls=box_walls(0.0, 0.0, length, width), bounds=(0.0, 0.0, length, width))

    def _field(self, rng: np.random.Generator, count: int, goal_span, radii, margin: float = WALL_MARGIN_M) -> Episode:
        """Starts in their block, the goal at a height drawn in ``goal_span`` (fractions of the width; ``None``: the
        middle third) and ``count`` obstacles of radii in ``radii`` between them."""
        n = self.n_robots
        columns, side = self._block()
        _, _, length, width = self.layout.bounds
        xy = start_block(n, columns, START_SPACING_M) + np.array([1.0, 0.5 * (width - side)])
        heading = np.radians(10.0 * rng.standard_normal(n))
        if goal_span is None:  # the default field's own expression, bit for bit
            goal = np.array([length - 1.0, width / 3.0 + (width / 3.0) * rng.random()])
        else:
            low, high = goal_span[0] * width, goal_span[1] * width
            goal = np.array([length - 1.0, low + (high - low) * rng.random()])
        keep_out = [(goal[0], goal[1], self.goal_radius_m), (1.0 + side / 2, width / 2, side / 2 + 0.7 * 1.5)]
        region = (2.0 + side, margin, length - 1.5, width - margin)
        circles = random_obstacles(rng, count, region, radii, GAP_M, keep_out)
        return Episode(circles=circles, starts=np.column_stack([xy, heading]), goal=goal)


parallel_env, raw_env, env = module_constructors(ObstacleFieldEnv)
