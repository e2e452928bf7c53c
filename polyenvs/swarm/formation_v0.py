"""``formation_v0``: a leader and followers keep a lattice formation (physicomimetics) across an obstacle field.

``from polyenvs.swarm import formation_v0; env = formation_v0.parallel_env()`` (7 robots: a hexagon around the leader).
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.jit import njit
from polyenvs.core.layouts import LayoutSplit, SplitParameter, documents_layouts
from polyenvs.core.validation import check_in_range
from polyenvs.swarm.batch import INFO_REWARD, TASK_NORMALS, TaskTerms, step_kernel
from polyenvs.swarm.env import DEFAULT_COMM_RANGE_M, PARAMETER_RANGES, Episode, Layout, SwarmEnv, module_constructors
from polyenvs.swarm.layouts import (
    WALL_MARGIN_M,
    ObstacleFieldEpisodes,
    box_walls,
    hex_lattice,
    lattice_pairs,
    layout_obstacle_slots,
    random_obstacles,
)
from polyenvs.swarm.sensors import wrap_angle

__all__ = [
    "FORMATION_HOLDS_ERROR",
    "FORMATION_PENALTY",
    "FormationEnv",
    "FormationTerms",
    "LEADER",
    "MAX_CYCLES",
    "N_ROBOTS",
    "OBSERVATION_PARTS",
    "env",
    "centroid_distances",
    "formation_error",
    "formation_step",
    "parallel_env",
    "raw_env",
    "write_leader",
]

#: Defaults: what ``parallel_env()`` builds and what the commands evaluate (the registry row adds nothing).
N_ROBOTS = 7
MAX_CYCLES = 1500
FIELD_LENGTH_M = 14.0
FIELD_WIDTH_M = 8.0
OBSTACLE_RADIUS_M = (0.15, 0.3)
#: Obstacles keep this gap rim to rim: wide enough for a robot, narrow enough to bend the formation.
GAP_M = 0.8
#: Held-out layouts (*ours*): 3-7 obstacles and the goal at 35-65 % of the field's width; the radius splits them:
#: train 0.15-0.3 m (the default's), test 0.33-0.45 m.
LAYOUT_SPLIT = LayoutSplit(
    (SplitParameter("obstacle radius", "m", train=OBSTACLE_RADIUS_M, test=(0.33, 0.45)),),
    varies="3-7 obstacles placed as in the default field, the goal at 35-65 % of the field's width",
)
LAYOUT_GOAL_SPAN = (0.35, 0.65)
N_OBSTACLES = 5
#: The lattice spacing R (m) a formation accepts.
SPACING_RANGE_M = (0.5, 3.0)
#: Reward weight (*ours*): per unit of a robot's own formation error, per step.
FORMATION_PENALTY = 0.1
#: The swarm's formation error (mean |r - R| / R over the lattice pairs) up to which the formation holds (*ours*):
#: a quarter of R keeps neighbours on average within 0.75-1.25 R, short of the springs' 1.5 R reach, and above the
#: feasibility study's worst held formation (0.17). ``formation_progress_m`` counts progress only while it holds.
FORMATION_HOLDS_ERROR = 0.25
#: The robot of each environment that broadcasts (AP-lite's leader-follower form): ``robot_0``.
LEADER = 0
#: The formation's observation parts (name -> lower bounds; upper bounds 1), between the family's ``neighbours``
#: and ``powers``: ``leader`` (range / comm_range, bearing / pi, mask: the leader's broadcast, if in range) and
#: ``is_leader`` (1 for the leader).
OBSERVATION_PARTS = {"leader": (0.0, -1.0, 0.0), "is_leader": (0.0,)}


def default_goal_radius(spacing_m: float) -> float:
    """``goal_radius_m`` when not given: 2 R (the feasibility study's "within 2 R of the goal"), at most the 3 m
    every swarm task accepts (so from R = 1.5 m on it is 3 m)."""
    return min(2.0 * spacing_m, PARAMETER_RANGES["goal_radius_m"][1])


def default_comm_range(spacing_m: float) -> float:
    """``comm_range_m`` when not given: the swarm's 3 m, or the springs' reach 1.5 R where that is farther
    (R above 2 m), so every accepted spacing works with the defaults."""
    return max(DEFAULT_COMM_RANGE_M, 1.5 * spacing_m)


@njit(cache=True)
def write_leader(pose, active, todo, normals, per, params, at, out):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """The formation's observation parts of every row in ``todo``: ``leader`` at columns ``at .. at + 2`` (range
    / comm_range, bearing / pi, mask: the leader's broadcast, if within comm_range) and ``is_leader`` at ``at + 3``
    (the family has zeroed them). ``normals``: ``(N, 2)`` the bearing's and the range's noise draws; ``params``:
    ``[range_noise_m, bearing_noise_rad, comm_range_m]``; ``per``: robots per environment, whose leader is its
    row :data:`LEADER`. A compiled-kernel boundary: its arrays are positional, as numba takes them."""
    range_noise, bearing_noise, comm = params[0], params[1], params[2]
    for i in range(out.shape[0]):
        if not todo[i] or not active[i]:
            continue
        leader = (i // per) * per + LEADER
        if i == leader:
            out[i, at + 3] = 1.0
        elif active[leader]:
            x, y, h = pose[i, 0], pose[i, 1], pose[i, 2]
            lx, ly = pose[leader, 0], pose[leader, 1]
            d = math.hypot(lx - x, ly - y)
            if d <= comm:
                bearing = math.atan2(ly - y, lx - x) - h + bearing_noise * normals[i, 0]
                out[i, at] = min(max(d + range_noise * normals[i, 1], 0.0), comm) / comm
                out[i, at + 1] = wrap_angle(bearing) / math.pi
                out[i, at + 2] = 1.0


@njit(cache=True)
def formation_error(pose, active, pairs, spacing, per_robot, count, swarm):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
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


@njit(cache=True)
def centroid_distances(pose, goals, per, out):
    """Each environment's distance from the centroid of its ``per`` robots (all of them, in the episode or not) to
    its goal, into ``out`` ``(E,)``: the sum over the robots in row order divided by N, as numpy's ``mean`` over
    them gives it."""
    for e in range(out.shape[0]):
        x, y = 0.0, 0.0
        for i in range(e * per, (e + 1) * per):
            x += pose[i, 0]
            y += pose[i, 1]
        out[e] = math.hypot(x / per - goals[e, 0], y / per - goals[e, 1])


@njit(cache=True)
def score_formation(pose, live, todo, goals, stepping, arrays, rewards):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """After a step of the rows in ``todo`` (``live``: the robots that took it) of the environments in
    ``stepping``: each robot's formation error and ``formation`` reward term (its column of ``rewards``), the
    running sums and the centroid's progress while the formation holds (``arrays``:
    :meth:`FormationTerms.kernel_arrays`). Rows and environments outside the step are left as they are."""
    pairs, params, columns, leader_params, state, scratch = arrays
    per_robot_now, robot_sum, swarm_sum, centroid_distance, progress_sum = state
    per_robot, count, swarm, distance = scratch
    spacing, holds, column, per = params[0], params[1], columns[1], columns[2]
    formation_error(pose, live, pairs, spacing, per_robot, count, swarm)
    centroid_distances(pose, goals, per, distance)
    for i in range(pose.shape[0]):
        if todo[i]:
            per_robot_now[i] = per_robot[i]
            rewards[i, column] = -FORMATION_PENALTY * per_robot[i] if live[i] else 0.0
            robot_sum[i] += per_robot[i] if live[i] else 0.0
    for e in range(swarm.shape[0]):
        if stepping[e]:
            swarm_sum[e] += swarm[e]
            progress_sum[e] += centroid_distance[e] - distance[e] if swarm[e] <= holds else 0.0
            centroid_distance[e] = distance[e]


@njit(cache=True)
def formation_step(kernel):
    """The formation's compiled step (:attr:`FormationTerms.compiled_step`): the family's
    (:func:`polyenvs.swarm.batch.step_kernel`), then the leader's broadcast in the observations of the rows it
    sensed (:func:`write_leader`, on the sensors' last ``TASK_NORMALS`` draws), :func:`score_formation` and the
    ``formation`` term added to the info table's reward, in one call."""
    step_kernel(kernel)
    robots, draws, scratch = kernel.sim[0], kernel.sim[3], kernel.sim[4]
    pose, goals = robots[0], robots[4]
    stepping, todo, live = scratch[1], scratch[2], scratch[3]
    normals = draws[3]
    observations, rewards = kernel.out[0], kernel.out[2]
    arrays = kernel.task[7]
    columns, leader_params = arrays[2], arrays[3]
    own = normals[:, normals.shape[1] - TASK_NORMALS :]
    write_leader(pose, live, todo, own, columns[2], leader_params, columns[0], observations)
    score_formation(pose, live, todo, goals, stepping, arrays, rewards)
    table, column = kernel.out[4][0], columns[1]
    for i in range(rewards.shape[0]):
        table[i, INFO_REWARD] += rewards[i, column]  # the reward: every term, summed in column order


class FormationTerms(TaskTerms):
    """What the formation adds to the family, for a whole batch: the leader's broadcast in the observation, the
    ``formation`` reward term (-0.1 x a robot's own error), the ``formation_error`` metric (per robot: its mean
    error over the steps; per environment: the mean over the steps of the swarm's error) and info key (a robot's
    own error now). The first readings after a reset count as a step of the sums, not of the reward. The
    ``formation_progress_m`` metric (per environment, and the same for each of its robots) sums the decrease of
    the distance from the centroid of all N robots (those that arrived stay where they left) to the goal over the
    steps where the swarm's error is at most :data:`FORMATION_HOLDS_ERROR`."""

    compiled_step = staticmethod(formation_step)
    observation_parts = OBSERVATION_PARTS
    reward_names = ("formation",)
    metric_names = ("formation_error", "formation_progress_m")
    info_names = ("formation_error",)

    def __init__(self, task: FormationEnv, batch):
        super().__init__(task, batch)
        rows, envs = batch.n_rows, batch.n_envs
        self.pairs, self.spacing_m = task.pairs, task.spacing_m
        self.leader_at = batch.structure["leader"][0]
        self.leader_params = np.array([task.range_noise_m, math.radians(task.bearing_noise_deg), task.comm_range_m])
        #: Each robot's error now, its sum over the steps, and each environment's sum of the swarm's error.
        self.per_robot, self.robot_sum, self.swarm_sum = np.zeros(rows), np.zeros(rows), np.zeros(envs)
        #: Each environment's centroid-to-goal distance after the last step, and its progress while in formation.
        self.centroid_distance, self.progress_sum = np.zeros(envs), np.zeros(envs)
        # Per robot, pairs per robot, swarm, centroid to goal.
        self._scratch = np.zeros(rows), np.zeros(rows), np.zeros(envs), np.zeros(envs)
        self._reward_column = batch.reward_column("formation")

    def kernel_arrays(self) -> tuple:
        """What :func:`formation_step` reads and writes besides the batch's arrays: the lattice pairs,
        ``[R, FORMATION_HOLDS_ERROR]``, ``[leader observation's column, formation reward's column, robots per
        environment]``, the leader's noise and reach, the running state and scratch."""
        state = self.per_robot, self.robot_sum, self.swarm_sum, self.centroid_distance, self.progress_sum
        columns = np.array([self.leader_at, self._reward_column, self.batch.n_robots], dtype=np.int64)
        # The threshold travels as a value, not a constant frozen into the kernel's cached code.
        params = np.array([self.spacing_m, FORMATION_HOLDS_ERROR])
        return self.pairs, params, columns, self.leader_params, state, self._scratch

    def observe(self, live, todo, normals, out) -> None:
        own = normals[:, -TASK_NORMALS:]
        write_leader(self.batch.pose, live, todo, own, self.batch.n_robots, self.leader_params, self.leader_at, out)

    def _errors(self, live) -> tuple[np.ndarray, np.ndarray]:
        per_robot, count, swarm, _ = self._scratch
        formation_error(self.batch.pose, live, self.pairs, self.spacing_m, per_robot, count, swarm)
        return per_robot, swarm

    def _centroid_distance(self) -> np.ndarray:
        """Each environment's distance from the centroid of its N robots to its goal, ``(E,)``."""
        distance = np.zeros(self.batch.n_envs)
        centroid_distances(self.batch.pose, self.batch.goals, self.batch.n_robots, distance)
        return distance

    def restart(self, rows, envs) -> None:
        active = self.batch.active
        per_robot, swarm = self._errors(active)
        self.per_robot[rows] = per_robot[rows]
        self.robot_sum[rows] = np.where(active, per_robot, 0.0)[rows]
        self.swarm_sum[envs] = swarm[envs]
        self.centroid_distance[envs] = self._centroid_distance()[envs]
        self.progress_sum[envs] = 0.0

    def env_metrics(self) -> dict[str, np.ndarray]:
        return {
            "formation_error": self.swarm_sum / (self.batch.cycles + 1),
            "formation_progress_m": self.progress_sum.copy(),
        }

    def robot_metrics(self) -> dict[str, np.ndarray]:
        cycles = self.batch.cycles
        progress = np.repeat(self.progress_sum, self.batch.n_robots)
        if len(cycles) == 1:  # the common case of a PettingZoo step, in one division
            return {"formation_error": self.robot_sum / max(int(cycles[0]), 1), "formation_progress_m": progress}
        errors = self.robot_sum / np.maximum(np.repeat(cycles, self.batch.n_robots), 1)
        return {"formation_error": errors, "formation_progress_m": progress}

    def robot_info(self) -> dict[str, np.ndarray]:
        return {"formation_error": self.per_robot.copy()}


@documents_layouts(LAYOUT_SPLIT)
class FormationEnv(ObstacleFieldEpisodes, SwarmEnv):
    """N Maxelbot-like robots in a hexagonal lattice of spacing R (``robot_0``, the leader, at its centre) cross an
    obstacle field to a goal light while keeping formation.

    ## Description
    The physicomimetics framework of the paper's Section 2 (Spears et al. 2004): robots hold a lattice by virtual
    Hooke's-law springs between neighbours. AP-lite is a leader-follower scheme: only the leader broadcasts, and
    followers sense range and bearing to the leader and to their neighbours by trilateration. Formation error is
    the mean of ``|r - R| / R`` over the lattice's neighbouring pairs (robots one R apart at the start) still in
    the episode. The 7-robot default is a hexagon around the leader with R = 0.9 m (the feasibility study). The
    ``formation`` baseline springs every robot to all it senses and does not read ``leader``, a deviation from the
    paper's leader-follower wording whose reason and measurements are in ``baselines.swarm.FormationController``.

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
    robot's mean ``formation_error``, and ``env.episode_metrics()`` the swarm's mean over steps; both add
    ``formation_progress_m``, the metres the centroid of the N robots came closer to the goal during steps in
    which the formation held (the swarm's error at most ``FORMATION_HOLDS_ERROR`` = 0.25).

    ## Task score
    ``formation_progress_m`` (max). The paper's task is to reach the goal *while keeping the formation*
    (physicomimetics springs hold the lattice; AP-lite steers it past obstacles). Success alone ignores the
    formation, and the mean formation error rewards standing still (a swarm that never moves keeps its start
    lattice). Counting the centroid's progress to the goal only while the lattice holds asks for both: standing
    still scores 0, and so does a swarm that scatters to the goal.

    ## Arguments
    ``n_robots`` (default 7), ``spacing_m`` (R, default 0.9, 0.5-3 m), ``n_obstacles`` (default 5, 0-200;
    ``layouts="train"`` and ``"test"`` draw their own count and refuse another),
    ``goal_radius_m`` (default 2R up to 3 m, i.e. 3 m for R >= 1.5 m; 0.1-3 m), ``comm_range_m`` (default 3 m,
    or 1.5 R for R > 2 m: the springs reach 1.5 R, and a ``comm_range_m`` below 1.5 R is refused), then every
    keyword of ``corridor_v0`` with ``platform="maxelbot"`` and ``max_cycles=1500`` as defaults, and

    | keyword | default | meaning (range) |
    | --- | --- | --- |
    {layouts}

    ## Version History
    {version_history}
    """

    metadata = {**SwarmEnv.metadata, "name": "formation_v0"}
    default_platform = "maxelbot"
    terms_class = FormationTerms
    #: The robot that broadcasts (drawn in its own colour).
    leader = LEADER
    default_radius_m = OBSTACLE_RADIUS_M
    layout_goal_span = LAYOUT_GOAL_SPAN

    def __init__(self, *, n_robots: int = N_ROBOTS, spacing_m: float = 0.9, n_obstacles: int = N_OBSTACLES,
                 goal_radius_m: float | None = None, comm_range_m: float | None = None, max_cycles: int = MAX_CYCLES,
                 layouts: str = "default", **kwargs):  # fmt: skip
        self.spacing_m = check_in_range("spacing_m", spacing_m, *SPACING_RANGE_M)
        self.n_obstacles = layout_obstacle_slots(n_obstacles, layouts, N_OBSTACLES)
        goal_radius_m = default_goal_radius(self.spacing_m) if goal_radius_m is None else goal_radius_m
        comm_range_m = default_comm_range(self.spacing_m) if comm_range_m is None else comm_range_m
        super().__init__(n_robots=n_robots, goal_radius_m=goal_radius_m, comm_range_m=comm_range_m,
                         max_cycles=max_cycles, layouts=layouts, **kwargs)  # fmt: skip

    def _task_init(self) -> None:
        if 1.5 * self.spacing_m > self.comm_range_m:
            raise ValueError(
                f"spacing_m {self.spacing_m:g} needs comm_range_m >= 1.5 R = {1.5 * self.spacing_m:g} (the springs' reach)"
            )
        self.lattice = hex_lattice(self.n_robots, self.spacing_m)
        self.pairs = lattice_pairs(self.lattice, self.spacing_m)
        self._lattice_radius = float(np.hypot(*self.lattice.T).max())

    def _fixed_layout(self) -> Layout:
        extent = self._lattice_radius
        length, width = FIELD_LENGTH_M + 2 * extent, max(FIELD_WIDTH_M, 2 * extent + 4.0)
        return Layout(walls=box_walls(0.0, 0.0, length, width), bounds=(0.0, 0.0, length, width))

    def _field(self, rng: np.random.Generator, count: int, goal_span, radii, margin: float = WALL_MARGIN_M) -> Episode:
        """The lattice at the start, the goal at a height drawn in ``goal_span`` (fractions of the width; ``None``:
        mid-height) and ``count`` obstacles of radii in ``radii`` between them."""
        n = self.n_robots
        _, _, length, width = self.layout.bounds
        centre = np.array([1.5 + self._lattice_radius, width / 2])
        xy = centre + self.lattice + 0.05 * (2 * rng.random((n, 2)) - 1)
        heading = np.radians(5.0 * rng.standard_normal(n))
        if goal_span is None:
            goal = np.array([length - 1.5, width / 2])
        else:
            goal = np.array([length - 1.5, width * (goal_span[0] + (goal_span[1] - goal_span[0]) * rng.random())])
        keep_out = [(goal[0], goal[1], self.goal_radius_m), (centre[0], centre[1], self._lattice_radius + 1.0)]
        region = (centre[0] + self._lattice_radius + 1.0, margin, length - 2.0, width - margin)
        circles = random_obstacles(rng, count, region, radii, GAP_M, keep_out)
        return Episode(circles=circles, starts=np.column_stack([xy, heading]), goal=goal)


parallel_env, raw_env, env = module_constructors(FormationEnv)
