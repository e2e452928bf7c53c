"""``corridor_v0``: robots pass a corridor with obstacles to a light (the paper's X80Pro experiment).

``from polyenvs.swarm import corridor_v0; env = corridor_v0.parallel_env()`` (3 robots; ``n_robots=`` for more).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from polyenvs.core.layouts import LayoutSplit, SplitParameter, documents_layouts
from polyenvs.core.parameters import documents_arguments, parameter
from polyenvs.swarm.env import Episode, Layout, SwarmEnv, SwarmParams, module_constructors
from polyenvs.swarm.layouts import box_walls, start_block

__all__ = ["CorridorEnv", "MAX_CYCLES", "N_ROBOTS", "env", "parallel_env", "raw_env"]

#: Defaults: what ``parallel_env()`` builds and what the commands evaluate (the registry row adds nothing).
N_ROBOTS = 3
MAX_CYCLES = 600
#: Corridor (feasibility study, spec/swarm.md): walls 1.8 m apart, 6.5 m long; four obstacles of radius 0.2 m
#: reaching 0.55 m from their wall, alternating right and left; the light near the far end on the left.
CORRIDOR_WIDTH_M = 1.8
CORRIDOR_LENGTH_M = 6.5
OBSTACLE_RADIUS_M = 0.2
OBSTACLE_Y_M = (1.5, 2.7, 3.9, 5.1)
OBSTACLE_JITTER_M = 0.1
GOAL_M = (0.45, 6.1)
#: Start slots: three across the corridor, rows 0.5 m apart, the first behind the first obstacle on the right.
START_M = (1.40, 0.35)
START_SPACING_M = 0.5
START_JITTER_M = 0.05
START_HEADING_SD_DEG = 5.0
#: Held-out layouts (*ours*): four obstacles on random sides, each up to 0.3 m off its default place along the
#: corridor, its rim 2-25 cm from its wall (less than a robot's width: it is passed on the open side), and the light
#: anywhere across the far end. The radius splits them: train 0.12-0.19 m, test 0.21-0.28 m (the default's 0.2 m in
#: neither).
LAYOUT_SPLIT = LayoutSplit(
    (SplitParameter("obstacle radius", "m", train=(0.12, 0.19), test=(0.21, 0.28)),),
    varies="four obstacles on random sides, each within 0.3 m of its default place along the corridor and 2-25 cm "
    "from its wall, the light anywhere across the far end",
)
LAYOUT_Y_SHIFT_M = 0.3
LAYOUT_WALL_GAP_M = (0.02, 0.25)
LAYOUT_GOAL_X_M = (0.45, 1.35)


@dataclass(frozen=True)
class CorridorParams(SwarmParams):
    """The swarm's parameters, with the corridor's arrival distance: narrower than the light's clearance from the
    walls."""

    goal_radius_m: float = parameter(0.4, 0.1, 1.0, "m", "ours: a robot this close to the light has arrived")


@documents_layouts(LAYOUT_SPLIT)
@documents_arguments(CorridorParams)
class CorridorEnv(SwarmEnv):
    """N X80Pro-like robots drive up a corridor past four obstacles to a light at its far end.

    ## Description
    Hettiarachchi and Spears, "Physicomimetics for mobile robot obstacle avoidance" (``seeds/004``), Section 4:
    "two parallel walls and four obstacles in between with sufficient space for the robot to navigate. The goal, a
    light source, is kept at the far end [...] The robot is initially positioned at the bottom right corner [...]
    behind the first obstacle to the right." The dimensions are the feasibility study's (the paper gives none):
    walls 1.8 m apart and 6.5 m long, obstacles of radius 0.2 m reaching at most 0.55 m from their wall, light at
    (0.45, 6.1) m. More robots start in rows of three below the first, and the corridor grows backwards to hold them.

    ## Action Space
    ``Box(-1, 1, (2,), float32)`` per robot: left and right motor power as fractions of full power
    (``full_speed_mps`` of wheel speed; AP-lite's MAX_SPEED = 70 is 0.7). Negative drives backwards.

    ## Observation Space
    ``Box(float32)`` per robot, its own sensors only (``env.observation_structure`` names the slices):
    ``ir`` (4) the GP2D12 readings S0 (right-most) .. S3 (left-most) on the platform's scale, normalised to [0, 1]
    (X80Pro: reading / 80, 1 = nothing seen; Maxelbot: raw / 550, 0 = nothing seen); ``light`` (2) the light's
    bearing / pi (counter-clockwise from the heading) and intensity 1 / (1 + d^2) (d in m); ``neighbours``
    (3 x n_neighbours) range / comm_range, bearing / pi and a mask for the nearest robots in communication range
    (trilateration); ``powers`` (2) the last motor powers applied.

    ## Rewards
    Per robot, the sum of ``reward_progress`` (10 per metre closer to the light), ``reward_collision`` (-1 per step
    in contact) and ``reward_arrival`` (+10 on arrival); each term is in ``info``.

    ## Starting State
    Robots at their start slots with 5 cm of position jitter and headings 90° ± 5° (sd); obstacles shifted along
    the corridor by up to 10 cm.

    ## Episode End
    A robot terminates (and leaves ``env.agents``) when within ``goal_radius_m`` of the light, or on a contact if
    ``terminate_on_collision``. All robots are truncated after ``max_cycles`` steps.

    ## Info
    Per robot: ``pose`` (x m, y m, heading rad), ``collisions`` (contact events), ``distance_to_goal_m``,
    ``nearest_obstacle_cm`` (true distance along each beam, 80 = nothing within reach), ``motor_powers`` (0..100
    scale), ``turning_angle_deg`` (this step), ``stopped`` (still for 1 s short of the goal: AP-lite's halt),
    the reward terms and ``episode_metrics`` (``success_rate``, ``collisions``, ``time_to_goal_s``,
    ``min_clearance_cm``, ``stopped``); ``env.episode_metrics()`` aggregates them over the swarm. With
    ``flat_info=True`` the metrics are the keys ``episode_success_rate``, ``episode_collisions``, ... of every
    info instead (from the reset on: fixed keys of numbers only, which TorchRL's ``PettingZooWrapper`` needs; the
    nested dict, which it cannot take, is the default for the PettingZoo and Stable-Baselines3 paths).

    ## Task score
    ``success_rate`` (max, ceiling 1; ties at the ceiling broken by the lower ``time_to_goal_s``): the fraction of
    the robots that reached the light at the corridor's far end. The paper's indoor experiment is exactly that
    (ten runs, all reached the light); collisions and clearance are what AP-lite trades for it and are reported
    beside the score. Between swarms that all arrive, the faster one did better.

    ## Arguments
    | keyword | default | meaning (range) |
    | --- | --- | --- |
    {layouts}
    | ``n_robots`` | 3 | robots (1-1024) |
    | ``platform`` | "x80pro" | "x80pro" or "maxelbot" (body size, IR scale) |
    | ``max_cycles`` | 600 | steps before truncation |
    | ``n_neighbours`` | 6 | trilateration slots (1-32) |
    {arguments}
    | ``sensor_angles_deg`` | (-60, -15, 15, 60) | virtual sensor angles, increasing (-90..90; *ours*) |
    | ``terminate_on_collision`` | False | a contact ends that robot's episode |
    | ``flat_info`` | False | episode metrics as keys ``episode_<metric>`` of every info, not a nested dict (TorchRL) |
    | ``render_mode`` | None | "rgb_array" or "human" |
    | ``window_scale`` | 1.0 | with render_mode="human", the window shows each frame zoomed by this factor, in [0.25, 8]; rgb_array frames are unchanged |

    ## Version History
    {version_history}
    """

    metadata = {**SwarmEnv.metadata, "name": "corridor_v0"}
    default_platform = "x80pro"
    n_obstacles = len(OBSTACLE_Y_M)

    params_class = CorridorParams

    def __init__(self, *, n_robots: int = N_ROBOTS, max_cycles: int = MAX_CYCLES, **kwargs):
        super().__init__(n_robots=n_robots, max_cycles=max_cycles, **kwargs)

    def _rows(self) -> int:
        return -(-self.n_robots // 3)

    def _fixed_layout(self) -> Layout:
        bottom = START_M[1] - (self._rows() - 1) * START_SPACING_M - 0.35
        walls = np.vstack([
            [[0.0, bottom, 0.0, CORRIDOR_LENGTH_M], [CORRIDOR_WIDTH_M, bottom, CORRIDOR_WIDTH_M, CORRIDOR_LENGTH_M]],
            box_walls(0.0, bottom, CORRIDOR_WIDTH_M, CORRIDOR_LENGTH_M)[[0, 2]],
        ])  # fmt: skip
        return Layout(walls=walls, bounds=(0.0, bottom, CORRIDOR_WIDTH_M, CORRIDOR_LENGTH_M))

    def _starts(self, rng: np.random.Generator) -> np.ndarray:
        """``(N, 3)`` start poses: the slots, jittered, headed up the corridor."""
        n = self.n_robots
        slots = start_block(n, 3, START_SPACING_M)
        xy = np.array(START_M) - slots
        xy += START_JITTER_M * (2 * rng.random((n, 2)) - 1)
        heading = np.radians(90.0 + START_HEADING_SD_DEG * rng.standard_normal(n))
        return np.column_stack([xy, heading])

    def sample_episode(self, rng: np.random.Generator) -> Episode:
        starts = self._starts(rng)
        side = np.array([1, 0, 1, 0])  # right, left, right, left
        ys = np.array(OBSTACLE_Y_M) + OBSTACLE_JITTER_M * (2 * rng.random(4) - 1)
        reach = 0.55 - OBSTACLE_RADIUS_M
        xs = np.where(side == 1, CORRIDOR_WIDTH_M - reach, reach)
        circles = np.column_stack([xs, ys, np.full(4, OBSTACLE_RADIUS_M)])
        return Episode(circles=circles, starts=starts, goal=np.array(GOAL_M))

    def sample_layout_episode(self, rng: np.random.Generator, layouts: str) -> Episode:
        starts = self._starts(rng)
        radius = LAYOUT_SPLIT.parameters[0].draw(rng, layouts, 4)
        right = rng.random(4) < 0.5
        ys = np.array(OBSTACLE_Y_M) + LAYOUT_Y_SHIFT_M * (2 * rng.random(4) - 1)
        low, high = LAYOUT_WALL_GAP_M
        inset = radius + low + (high - low) * rng.random(4)  # centre to its wall
        xs = np.where(right, CORRIDOR_WIDTH_M - inset, inset)
        goal_x = LAYOUT_GOAL_X_M[0] + (LAYOUT_GOAL_X_M[1] - LAYOUT_GOAL_X_M[0]) * rng.random()
        return Episode(circles=np.column_stack([xs, ys, radius]), starts=starts, goal=np.array([goal_x, GOAL_M[1]]))


parallel_env, raw_env, env = module_constructors(CorridorEnv)
