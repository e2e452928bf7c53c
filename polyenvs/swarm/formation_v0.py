"""``formation_v0``: a leader and followers keep a lattice formation (physicomimetics) across an obstacle field.

``from polyenvs.swarm import formation_v0; env = formation_v0.parallel_env()`` (7 robots: a hexagon around the leader).
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.jit import njit
from polyenvs.core.validation import check_in_range, check_int
from polyenvs.swarm.env import DEFAULT_COMM_RANGE_M, PARAMETER_RANGES, Episode, Layout, SwarmEnv, module_constructors
from polyenvs.swarm.layouts import box_walls, hex_lattice, lattice_pairs, random_obstacles

__all__ = ["FormationEnv", "MAX_CYCLES", "N_ROBOTS", "env", "parallel_env", "raw_env"]

#: Defaults: what ``parallel_env()`` builds and what the commands evaluate (the registry row adds nothing).
N_ROBOTS = 7
MAX_CYCLES = 1500
FIELD_LENGTH_M = 14.0
FIELD_WIDTH_M = 8.0
OBSTACLE_RADIUS_M = (0.15, 0.3)
#: Obstacles keep this gap rim to rim: wide enough for a robot, narrow enough to bend the formation.
GAP_M = 0.8
#: The lattice spacing R (m) a formation accepts.
SPACING_RANGE_M = (0.5, 3.0)


def default_goal_radius(spacing_m: float) -> float:
    """``goal_radius_m`` when not given: 2 R (the feasibility study's "within 2 R of the goal"), at most the 3 m
    every swarm task accepts (so from R = 1.5 m on it is 3 m)."""
    return min(2.0 * spacing_m, PARAMETER_RANGES["goal_radius_m"][1])


def default_comm_range(spacing_m: float) -> float:
    """``comm_range_m`` when not given: the swarm's 3 m, or the springs' reach 1.5 R where that is farther
    (R above 2 m), so every accepted spacing works with the defaults."""
    return max(DEFAULT_COMM_RANGE_M, 1.5 * spacing_m)


class FormationEnv(SwarmEnv):
    """N Maxelbot-like robots in a hexagonal lattice of spacing R (``robot_0``, the leader, at its centre) cross an
    obstacle field to a goal light while keeping formation.

    ## Description
    The physicomimetics framework of the paper's Section 2 (Spears et al. 2004): robots hold a lattice by virtual
    Hooke's-law springs between neighbours. AP-lite is a leader-follower scheme: only the leader broadcasts, and
    followers sense range and bearing to the leader and to their neighbours by trilateration. Formation error is
    the mean of ``|r - R| / R`` over the lattice's neighbouring pairs (robots one R apart at the start) still in
    the episode. The 7-robot default is a hexagon around the leader with R = 0.9 m (the feasibility study).

    ## Action Space
    ``Box(-1, 1, (2,), float32)`` per robot: left and right motor power as fractions of full power.

    ## Observation Space
    As in ``corridor_v0`` (``env.observation_structure``: ``ir``, ``light``, ``neighbours``, ``powers``) plus
    ``leader`` (range / comm_range, bearing / pi and a mask: the leader's broadcast, if in range) and
    ``is_leader`` (1 for ``robot_0``).

    ## Rewards
    ``reward_progress`` (10 per metre closer to the goal), ``reward_collision`` (-1 per step in contact),
    ``reward_arrival`` (+10) and ``reward_formation`` (-0.1 x the robot's own formation error: the mean
    ``|r - R| / R`` over its lattice neighbours still in the episode).

    ## Starting State
    The lattice centred 1.5 m + its radius from the left wall at mid-height, each robot jittered by 5 cm and
    headed towards +x ± 5° (sd); the goal 1.5 m from the right wall at mid-height; ``n_obstacles`` discs placed
    uniformly between, at least 0.8 m apart.

    ## Episode End
    A robot terminates (leaving ``env.agents``) within ``goal_radius_m`` (default 2R, at most 3 m) of the goal, or
    on contact if ``terminate_on_collision``; all are truncated after ``max_cycles`` steps.

    ## Info
    As in ``corridor_v0`` plus ``formation_error`` (the robot's own, now); its ``episode_metrics`` add the
    robot's mean ``formation_error``, and ``env.episode_metrics()`` the swarm's mean over steps.

    ## Arguments
    ``n_robots`` (default 7), ``spacing_m`` (R, default 0.9, 0.5-3 m), ``n_obstacles`` (default 5, 0-200),
    ``goal_radius_m`` (default 2R up to 3 m, i.e. 3 m for R >= 1.5 m; 0.1-3 m), ``comm_range_m`` (default 3 m,
    or 1.5 R for R > 2 m: the springs reach 1.5 R, and a ``comm_range_m`` below 1.5 R is refused), then every
    keyword of ``corridor_v0`` with ``platform="maxelbot"`` and ``max_cycles=1500`` as defaults.

    ## Version History
    - v0: initial version.
    """

    metadata = {**SwarmEnv.metadata, "name": "formation_v0"}
    default_platform = "maxelbot"
    formation = True
    reward_names = ("progress", "collision", "arrival", "formation")
    metric_names = (*SwarmEnv.metric_names, "formation_error")

    def __init__(self, *, n_robots: int = N_ROBOTS, spacing_m: float = 0.9, n_obstacles: int = 5,
                 goal_radius_m: float | None = None, comm_range_m: float | None = None, max_cycles: int = MAX_CYCLES,
                 **kwargs):  # fmt: skip
        self.spacing_m = check_in_range("spacing_m", spacing_m, *SPACING_RANGE_M)
        self.n_obstacles = check_int("n_obstacles", n_obstacles, 0, 200)
        goal_radius_m = default_goal_radius(self.spacing_m) if goal_radius_m is None else goal_radius_m
        comm_range_m = default_comm_range(self.spacing_m) if comm_range_m is None else comm_range_m
        super().__init__(n_robots=n_robots, goal_radius_m=goal_radius_m, comm_range_m=comm_range_m,
                         max_cycles=max_cycles, **kwargs)  # fmt: skip

    def _task_init(self) -> None:
        if 1.5 * self.spacing_m > self.comm_range_m:
            raise ValueError(
                f"spacing_m {self.spacing_m:g} needs comm_range_m >= 1.5 R = {1.5 * self.spacing_m:g} (the springs' reach)"
            )
        self.lattice = hex_lattice(self.n_robots, self.spacing_m)
        self.pairs = lattice_pairs(self.lattice, self.spacing_m)
        self._lattice_radius = float(np.hypot(*self.lattice.T).max())
        self._per_robot = np.zeros(self.n_robots)
        self._pair_count = np.zeros(self.n_robots)

    def _fixed_layout(self) -> Layout:
        extent = self._lattice_radius
        length, width = FIELD_LENGTH_M + 2 * extent, max(FIELD_WIDTH_M, 2 * extent + 4.0)
        return Layout(walls=box_walls(0.0, 0.0, length, width), bounds=(0.0, 0.0, length, width))

    def _sample_episode(self, rng: np.random.Generator) -> Episode:
        n = self.n_robots
        _, _, length, width = self.layout.bounds
        centre = np.array([1.5 + self._lattice_radius, width / 2])
        xy = centre + self.lattice + 0.05 * (2 * rng.random((n, 2)) - 1)
        heading = np.radians(5.0 * rng.standard_normal(n))
        goal = np.array([length - 1.5, width / 2])
        keep_out = [(goal[0], goal[1], self.goal_radius_m), (centre[0], centre[1], self._lattice_radius + 1.0)]
        region = (centre[0] + self._lattice_radius + 1.0, 0.6, length - 2.0, width - 0.6)
        circles = random_obstacles(rng, self.n_obstacles, region, OBSTACLE_RADIUS_M, GAP_M, keep_out)
        return Episode(circles=circles, starts=np.column_stack([xy, heading]), goal=goal)

    def _formation_error(self):
        swarm = np.zeros(1)
        formation_error(self.pose, self.active, self.pairs, self.spacing_m, self._per_robot, self._pair_count, swarm)
        return self._per_robot, float(swarm[0])


@njit(cache=True)
def formation_error(pose, active, pairs, spacing, per_robot, count, swarm):
    """``|r - R| / R`` over the lattice pairs whose robots are both still in the episode, for E environments of
    N robots (``pairs`` index one environment's robots): the mean per robot over its pairs (``per_robot``,
    ``(E * N,)``) and each environment's mean over its pairs (``swarm``, ``(E,)``; 0 without such pairs)."""
    n_envs = swarm.shape[0]
    per = pose.shape[0] // n_envs
    per_robot[:] = 0.0
    count[:] = 0.0
    for e in range(n_envs):
        base = e * per
        total, pairs_in = 0.0, 0
        for p in range(pairs.shape[0]):
            i, j = base + pairs[p, 0], base + pairs[p, 1]
            if active[i] and active[j]:
                err = abs(math.hypot(pose[i, 0] - pose[j, 0], pose[i, 1] - pose[j, 1]) - spacing) / spacing
                per_robot[i] += err
                per_robot[j] += err
                count[i] += 1.0
                count[j] += 1.0
                total += err
                pairs_in += 1
        swarm[e] = total / pairs_in if pairs_in else 0.0
    for i in range(per_robot.shape[0]):
        if count[i] > 0:
            per_robot[i] /= count[i]


parallel_env, raw_env, env = module_constructors(FormationEnv)
