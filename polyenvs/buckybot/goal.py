"""BuckybotGoal: reach a goal given by dead-reckoned bearing and distance, without hitting walls."""

from __future__ import annotations

import math

import numpy as np

from polyenvs.buckybot import simulator as S
from polyenvs.buckybot.env import BuckybotEnv, reset_task, step_task
from polyenvs.buckybot.floor_plans import LAYOUT_SPLIT
from polyenvs.buckybot.geometry import STEP_LENGTH_CM
from polyenvs.core.floor_plan import FloorPlan
from polyenvs.core.jit import njit
from polyenvs.core.layouts import documents_layouts
from polyenvs.core.validation import check_finite, check_in_range, show

__all__ = ["BuckybotGoalEnv", "GOAL_DISTANCE_SCALE_CM"]

#: The goal distance is observed as tanh(distance / 200 cm): bounded, and most sensitive where steps matter.
GOAL_DISTANCE_SCALE_CM = 200.0
#: The farthest start-to-goal distance accepted (the widest plan is 50 m).
MAX_GOAL_DISTANCE_CM = 5000.0
#: The reward terms and the task's own metrics, by name (``info["reward_<term>"]``, ``info["episode_metrics"]``).
REWARD_TERMS = ("progress", "goal", "blocked")
METRICS = ("success", "final_distance_cm", "steps_to_goal")
OUT = BuckybotEnv.task_columns(REWARD_TERMS, METRICS)
_R_PROGRESS, _R_GOAL, _R_BLOCKED = OUT.term_columns("progress", "goal", "blocked")
_M_SUCCESS, _M_FINAL_DISTANCE, _M_STEPS = OUT.metric_columns("success", "final_distance_cm", "steps_to_goal")
#: The observation's part after the sensors: the goal's bearing (cos, sin) and tanh(distance / 200 cm).
OBSERVATION_PARTS = {"goal": 3}
_GOAL_COS, _GOAL_SIN, _GOAL_DISTANCE = range(*BuckybotEnv.observation_parts(OBSERVATION_PARTS)["goal"])

# Columns of the task state: the goal, the true distance to it after the last step, success.
_GOAL_X, _GOAL_Y, _DISTANCE, _SUCCESS = range(4)
_RADIUS = 0


@njit(cache=True)
def _goal_observation(b, state, task, obs):
    """The goal as the robot believes it: bearing (cos, sin) in the motion frame and tanh(distance / 200 cm)."""
    dx, dy = task[b, _GOAL_X] - state[b, S.DR_X], task[b, _GOAL_Y] - state[b, S.DR_Y]
    distance = math.sqrt(dx * dx + dy * dy)
    if distance > 0.0:  # rotate the direction into the frame with the kept cosine and sine of the heading
        c, s = state[b, S.DR_COS], state[b, S.DR_SIN]
        obs[b, _GOAL_COS] = (dx * c + dy * s) / distance
        obs[b, _GOAL_SIN] = (dy * c - dx * s) / distance
    else:
        obs[b, _GOAL_COS], obs[b, _GOAL_SIN] = 1.0, 0.0
    obs[b, _GOAL_DISTANCE] = math.tanh(distance / GOAL_DISTANCE_SCALE_CM)


@njit(cache=True)
def _write_metrics(b, state, task, out):
    out[b, _M_SUCCESS] = task[b, _SUCCESS]
    out[b, _M_FINAL_DISTANCE] = task[b, _DISTANCE]
    out[b, _M_STEPS] = state[b, S.STEPS]  # the episode ends at the goal: its steps are the steps to it


@njit(cache=True)
def _start_row(b, sim, task_arrays, out):
    """Freshly placed robot ``b``: its distance to the goal and its first goal observation."""
    state, task = sim[S.A_STATE], task_arrays[0]
    task[b, _DISTANCE] = math.hypot(task[b, _GOAL_X] - state[b, S.X], task[b, _GOAL_Y] - state[b, S.Y])
    task[b, _SUCCESS] = 0.0
    _goal_observation(b, state, task, sim[S.A_OBS])
    _write_metrics(b, state, task, out)
    return False


@njit(cache=True)
def _score_row(b, sim, task_arrays, out):
    """Robot ``b`` after its tip: progress towards the goal, success (which ends the episode), blocked tips."""
    state, (task, tp) = sim[S.A_STATE], task_arrays
    d = math.hypot(task[b, _GOAL_X] - state[b, S.X], task[b, _GOAL_Y] - state[b, S.Y])
    out[b, _R_PROGRESS] = (task[b, _DISTANCE] - d) / STEP_LENGTH_CM  # progress towards the goal, in steps
    task[b, _DISTANCE] = d
    task[b, _SUCCESS] = 1.0 if d <= tp[_RADIUS] else 0.0
    out[b, _R_GOAL] = 10.0 * task[b, _SUCCESS]
    out[b, _R_BLOCKED] = -1.0 if state[b, S.BLOCKED] > 0.5 else 0.0
    _goal_observation(b, state, task, sim[S.A_OBS])
    _write_metrics(b, state, task, out)
    return task[b, _SUCCESS] > 0.5


@njit(cache=True)
def _reset_kernel(rows, kernel):
    reset_task(rows, kernel, _start_row, REWARD_TERMS)


@njit(cache=True)
def _step_kernel(actions, kernel):
    step_task(actions, kernel, _score_row, REWARD_TERMS)


@documents_layouts(LAYOUT_SPLIT)
class BuckybotGoalEnv(BuckybotEnv):
    """Reach a goal cell known only through dead reckoning, without bumping into walls.

    ## Description
    The Buckybot of BuckybotWallFollow-v0 (Buckybot paper) is told where a goal lies relative to its start. It
    knows its pose only by dead reckoning (replaying the mean tip model on its actuator sequence, as the paper's
    mapping does), so the goal it observes drifts from the true one as it walks. Success is judged on the true
    position. Baseline: ``baselines.buckybot.GoalSeeker``.

    ## Action Space
    ``Discrete(3)`` (:class:`~polyenvs.buckybot.env.BuckybotAction`), tip directions in the resting face's frame
    (see BuckybotWallFollow-v0).

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
    ``max_episode_steps`` (300 at registration). The metrics (``env.unwrapped.episode_metrics()``;
    ``info["episode_metrics"]`` at the episode's end, as in BuckybotWallFollow-v0): ``success`` (0/1),
    ``final_distance_cm`` (true), ``steps_to_goal`` (the steps taken: to the goal if it was reached, else the
    whole episode), ``blocked_tips``, ``oscillation_events``.

    ## Task score
    ``success`` (max, ceiling 1; ties at the ceiling broken by fewer ``steps_to_goal``). The paper's robot moves by
    tips and knows its pose only by dead reckoning; the task is to get there, judged on the true position, and a
    robot that gets there in fewer 9.13 cm tips (each tip costs the paper's robot seconds and drifts its dead
    reckoning) did better. Blocked tips are charged in the reward, not the score: arriving is what counts.

    ## Arguments
    | argument | default | meaning |
    |----------|---------|---------|
    | floor_plan | "l_room" | as BuckybotWallFollow-v0 |
    {layouts}
    | goal_radius_cm | 15.0 | success radius (a lattice step is 9.13 cm), in [5, 50]; the plan must have room for a goal this size |
    | goal_distance_cm | (100.0, 400.0) | range of start-to-goal distances, 0 <= min <= max <= 5000 |
    | noise_scale, range_noise_scale, step_*, heading_*, body_radius_cm, render_mode, window_scale, num_rows | | as BuckybotWallFollow-v0 |

    ## Version History
    {version_history}
    """

    out_columns = OUT
    default_floor_plan = "l_room"
    task_option_names = ("goal",)
    task_observation_sizes = OBSERVATION_PARTS
    task_observation_low = (-1.0, -1.0, 0.0)
    task_observation_high = (1.0, 1.0, 1.0)

    def __init__(
        self, *, floor_plan=default_floor_plan, goal_radius_cm: float = 15.0, goal_distance_cm=(100.0, 400.0), **kwargs
    ):
        self.goal_radius_cm = check_in_range("goal_radius_cm", goal_radius_cm, 5.0, 50.0)
        if isinstance(goal_distance_cm, str) or not hasattr(goal_distance_cm, "__len__") or len(goal_distance_cm) != 2:
            raise ValueError(f"goal_distance_cm must be a (min, max) pair in cm, got {show(goal_distance_cm)}")
        low, high = (check_finite("goal_distance_cm", v) for v in goal_distance_cm)
        if not 0 <= low <= high <= MAX_GOAL_DISTANCE_CM:
            raise ValueError(
                f"goal_distance_cm must satisfy 0 <= min <= max <= {MAX_GOAL_DISTANCE_CM:g}, got ({low:g}, {high:g})"
            )
        self.goal_distance_cm = (low, high)
        super().__init__(floor_plan=floor_plan, **kwargs)
        if self.floor_plan is not None and not self._task_plan_usable(self.floor_plan):
            raise ValueError(
                f"goal_radius_cm={self.goal_radius_cm:g} leaves no room for a goal in this floor_plan (a goal needs "
                f"{self._goal_clearance():g} cm from every wall); use a smaller radius or a larger plan"
            )

    def _task_init(self):
        self._task_state = np.zeros((self._batch_size, 4))
        self._task_params = np.array([self.goal_radius_cm])

    def _task_arrays(self):
        return (self._task_state, self._task_params)

    @property
    def goal(self) -> np.ndarray:
        """Row 0's goal (cm)."""
        return self._task_state[0, _GOAL_X : _GOAL_Y + 1].copy()

    def _goal_clearance(self) -> float:
        return self.goal_radius_cm + self.body_radius_cm

    def _goal_candidates(self, plan: FloorPlan) -> np.ndarray:
        """Centres of the plan's grid cells a goal may be drawn around (cached per plan)."""
        key = ("goal_candidates", self._goal_clearance())
        if key not in plan._cache:
            g = plan.grid()
            eligible = (g.region == g.main_region) & (g.clearance >= self._goal_clearance() + g.cell_cm)
            plan._cache[key] = np.ascontiguousarray(g.centres()[eligible])
        return plan._cache[key]

    def _task_plan_usable(self, plan: FloorPlan) -> bool:
        return len(self._goal_candidates(plan)) > 0

    def _task_sample(self, plan, position, rng, options):
        if "goal" in options:
            return self._option_goal(plan, options["goal"])
        return self._sample_goal(plan, position, rng)

    def _task_commit(self, row, goal):
        self._task_state[row, _GOAL_X : _GOAL_Y + 1] = goal

    def _option_goal(self, plan: FloorPlan, value) -> np.ndarray:
        try:
            goal = np.array([float(v) for v in value])
        except (TypeError, ValueError):
            raise ValueError(f"reset option 'goal' must be (x_cm, y_cm), got {show(value)}") from None
        if (
            goal.shape != (2,)
            or not np.isfinite(goal).all()
            or float(plan.clearance(goal)) < self.body_radius_cm
            or not plan.in_main_region(goal)
        ):
            raise ValueError(f"reset option 'goal' {show(value)} is not a free point of the plan")
        return goal

    def _sample_goal(self, plan: FloorPlan, position: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A uniform point of the room ``goal_distance_cm`` from the robot (or, in a room too small for that, from
        the farthest quarter of it), clear of the walls by the goal radius plus the body.

        A uniform candidate cell is drawn until one lies in range (usually the first or second), which is the same
        distribution as drawing from the cells in range; after 16 misses the range is computed for every cell."""
        centres = self._goal_candidates(plan)
        low, high = self.goal_distance_cm
        x, y = float(position[0]), float(position[1])
        for _ in range(16):
            cx, cy = centres[int(rng.random() * len(centres))].tolist()
            if low * low <= (cx - x) ** 2 + (cy - y) ** 2 <= high * high:
                break
        else:
            distance_sq = (centres[:, 0] - x) ** 2 + (centres[:, 1] - y) ** 2
            pool = np.flatnonzero((distance_sq >= low * low) & (distance_sq <= high * high))
            if pool.size == 0:
                pool = np.flatnonzero(distance_sq >= np.quantile(distance_sq, 0.75))
            cx, cy = centres[pool[rng.integers(pool.size)]].tolist()
        u = rng.random(2)
        cell = plan.grid().cell_cm
        return np.array([cx + (u[0] - 0.5) * cell, cy + (u[1] - 0.5) * cell])

    def _get_info(self, row):
        info = super()._get_info(row)
        info["goal"] = self._task_state[row, _GOAL_X : _GOAL_Y + 1].copy()
        return info

    def _vector_task_info(self):
        return {"goal": self._task_state[:, _GOAL_X : _GOAL_Y + 1].copy()}

    _step_kernel = staticmethod(_step_kernel)
    _reset_kernel = staticmethod(_reset_kernel)
