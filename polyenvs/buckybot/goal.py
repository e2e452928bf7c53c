"""BuckybotGoal: reach a goal given by dead-reckoned bearing and distance, without hitting walls."""

from __future__ import annotations

import math

import numpy as np

from polyenvs.buckybot.env import BuckybotEnv
from polyenvs.buckybot.geometry import STEP_LENGTH_CM
from polyenvs.core.jit import njit
from polyenvs.core.validation import check_positive

__all__ = ["BuckybotGoalEnv", "GOAL_DISTANCE_SCALE_CM"]

#: The goal distance is observed as tanh(distance / 200 cm): bounded, and most sensitive where steps matter.
GOAL_DISTANCE_SCALE_CM = 200.0


class BuckybotGoalEnv(BuckybotEnv):
    """Reach a goal cell known only through dead reckoning, without bumping into walls.

    ## Description
    The Buckybot of BuckybotWallFollow-v0 (Buckybot paper) is told where a goal lies relative to its start. It
    knows its pose only by dead reckoning (replaying the mean tip model on its actuator sequence, as the paper's
    mapping does), so the goal it observes drifts from the true one as it walks. Success is judged on the true
    position. Baseline: ``baselines.buckybot.GoalSeeker``.

    ## Action Space
    ``Discrete(3)``, tip directions in the resting face's frame (see BuckybotWallFollow-v0).

    ## Observation Space
    ``Box((22,), float32)``: the 19 sensor entries of BuckybotWallFollow-v0, then ``goal`` (indices 19-21): the
    cosine and sine of the goal's bearing in the resting face's frame and tanh(distance / 200 cm), all from the
    dead-reckoned pose.

    ## Rewards
    ``reward_progress``: decrease of the true distance to the goal, in units of the 9.129 cm lattice step;
    ``reward_goal = +10`` on reaching the goal; ``reward_blocked = -1`` for a blocked tip.

    ## Starting State
    As BuckybotWallFollow-v0; the goal is a seeded point of the same room, between ``goal_distance_cm`` apart
    and at least ``goal_radius_cm`` + 13 cm from every wall. ``reset(options={"goal": (x_cm, y_cm)})`` sets it.

    ## Episode End
    Terminates when the true centre is within ``goal_radius_cm`` of the goal; truncated after
    ``max_episode_steps`` (300 at registration). ``info["episode_metrics"]``: ``success`` (0/1),
    ``final_distance_cm`` (true), ``blocked_tips``, ``oscillation_events``.

    ## Arguments
    | argument | default | meaning |
    |----------|---------|---------|
    | floor_plan | "l_room" | as BuckybotWallFollow-v0 |
    | goal_radius_cm | 15.0 | success radius (a lattice step is 9.13 cm) |
    | goal_distance_cm | (100.0, 400.0) | range of start-to-goal distances |
    | noise_scale, range_noise_scale, step_*, heading_*, body_radius_cm, render_mode | | as BuckybotWallFollow-v0 |

    ## Version History
    * v0: initial version.
    """

    reward_names = ("progress", "goal", "blocked")
    task_observation_sizes = {"goal": 3}
    task_observation_low = (-1.0, -1.0, 0.0)
    task_observation_high = (1.0, 1.0, 1.0)

    def __init__(self, *, floor_plan="l_room", goal_radius_cm: float = 15.0, goal_distance_cm=(100.0, 400.0), **kwargs):
        self.goal_radius_cm = check_positive("goal_radius_cm", goal_radius_cm)
        try:
            low, high = (float(v) for v in goal_distance_cm)
        except (TypeError, ValueError):
            raise ValueError(f"goal_distance_cm must be a (min, max) pair in cm, got {goal_distance_cm!r}") from None
        if not 0 <= low <= high or not np.isfinite(high):
            raise ValueError(f"goal_distance_cm must satisfy 0 <= min <= max, got {goal_distance_cm!r}")
        self.goal_distance_cm = (low, high)
        super().__init__(floor_plan=floor_plan, **kwargs)
        n = self._batch_size
        self._goal = np.zeros((n, 2))
        self._distance = np.zeros(n)  # true distance to the goal after the last step
        self._success = np.zeros(n, dtype=bool)
        self._goal_observation = np.zeros((n, 3))

    @property
    def goal(self) -> np.ndarray:
        """Row 0's goal (cm)."""
        return self._goal[0]

    def _task_option_names(self):
        return ("goal",)

    def _task_reset(self, rows, options):
        self._goal[rows] = self._option_goal(options) if "goal" in options else self._sample_goals(rows)
        position = self.sim.position[rows]
        self._distance[rows] = np.hypot(self._goal[rows, 0] - position[:, 0], self._goal[rows, 1] - position[:, 1])
        self._success[rows] = False

    def _option_goal(self, options) -> np.ndarray:
        try:
            goal = np.array([float(v) for v in options["goal"]])
        except (TypeError, ValueError):
            raise ValueError("reset option 'goal' must be (x_cm, y_cm)") from None
        if (
            goal.shape != (2,)
            or not np.isfinite(goal).all()
            or float(self.plan.clearance(goal)) < self.body_radius_cm
            or not self.plan.in_main_region(goal)
        ):
            raise ValueError(f"reset option 'goal' {options['goal']!r} is not a free point of the plan")
        return goal

    def _sample_goals(self, rows: np.ndarray) -> np.ndarray:
        """A goal per row: a uniform point of the room ``goal_distance_cm`` from the robot (or, in a room too
        small for that, from the farthest quarter of it), clear of the walls by the goal radius plus the body."""
        g = self.plan.grid()
        clearance = self.goal_radius_cm + self.body_radius_cm
        centres = g.centres()[(g.region == g.main_region) & (g.clearance >= clearance + g.cell_cm)]
        position = self.sim.position[rows]
        distance = np.hypot(centres[None, :, 0] - position[:, None, 0], centres[None, :, 1] - position[:, None, 1])
        low, high = self.goal_distance_cm
        pool = (distance >= low) & (distance <= high)
        empty = ~pool.any(axis=1)
        if empty.any():
            pool[empty] = distance[empty] >= np.quantile(distance[empty], 0.75, axis=1, keepdims=True)
        pick = self.np_random.integers(pool.sum(axis=1))  # the pick-th candidate of each row's pool
        index = np.argmax(np.cumsum(pool, axis=1) > pick[:, None], axis=1)
        return centres[index] + self.np_random.uniform(-0.5, 0.5, (len(rows), 2)) * g.cell_cm

    def _task_observation(self):
        sim = self.sim
        _goal_bearing(sim.dr_position, sim.dr_heading, self._goal, self._goal_observation)
        return self._goal_observation

    def _task_step(self, actions, blocked, active):
        _goal_step(
            active,
            blocked,
            self.sim.position,
            self._goal,
            self.goal_radius_cm,
            self._distance,
            self._success,
            self._rewards,
        )

    def _task_terminated(self):
        return self._success

    def _episode_metrics(self, row):
        metrics = super()._episode_metrics(row)
        metrics.update(success=float(self._success[row]), final_distance_cm=float(self._distance[row]))
        return metrics

    def _get_info(self, row):
        info = super()._get_info(row)
        info["goal"] = self._goal[row].copy()
        return info


@njit(cache=True)
def _goal_bearing(dr_position, dr_heading, goal, out):
    """The goal as the robot believes it: bearing (cos, sin) in the motion frame and tanh(distance / 200 cm)."""
    for b in range(goal.shape[0]):
        dx, dy = goal[b, 0] - dr_position[b, 0], goal[b, 1] - dr_position[b, 1]
        bearing = math.atan2(dy, dx) - dr_heading[b]
        out[b, 0], out[b, 1] = math.cos(bearing), math.sin(bearing)
        out[b, 2] = math.tanh(math.hypot(dx, dy) / GOAL_DISTANCE_SCALE_CM)


@njit(cache=True)
def _goal_step(active, blocked, position, goal, radius, distance, success, rewards):
    for b in range(active.shape[0]):
        if not active[b]:
            rewards[b, :] = 0.0
            continue
        d = math.hypot(goal[b, 0] - position[b, 0], goal[b, 1] - position[b, 1])
        rewards[b, 0] = (distance[b] - d) / STEP_LENGTH_CM  # progress towards the goal, in lattice steps
        distance[b] = d
        success[b] = d <= radius
        rewards[b, 1] = 10.0 if success[b] else 0.0
        rewards[b, 2] = -1.0 if blocked[b] else 0.0
