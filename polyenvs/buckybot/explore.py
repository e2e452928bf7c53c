"""BuckybotExplore: cover an unknown floor plan with the range finders."""

from __future__ import annotations

import numpy as np

from polyenvs.buckybot import simulator as S
from polyenvs.buckybot.env import BuckybotEnv, reset_task, step_task
from polyenvs.buckybot.floor_plans import LAYOUT_SPLIT, RANDOM_ROOM_BOUNDS
from polyenvs.buckybot.mapping import OccupancyGrid, mark_beams_rotated, placement_gaps_rotated
from polyenvs.core.floor_plan import FloorPlan, grid_shape
from polyenvs.core.jit import njit
from polyenvs.core.layouts import documents_layouts
from polyenvs.core.validation import check_in_range

__all__ = ["BuckybotExploreEnv"]

#: The reward terms and the task's own metrics, by name (``info["reward_<term>"]``, ``info["episode_metrics"]``).
REWARD_TERMS = ("coverage", "blocked")
METRICS = ("coverage", "map_error_cm", "steps")
OUT = BuckybotEnv.task_columns(REWARD_TERMS, METRICS)
_R_COVERAGE, _R_BLOCKED = OUT.term_columns("coverage", "blocked")
_M_COVERAGE, _M_MAP_ERROR, _M_STEPS = OUT.metric_columns("coverage", "map_error_cm", "steps")

# Columns of the task state: free cells of the main region observed so far, the map-error sum and its count.
_SEEN, _ERROR_SUM, _POINTS = range(3)
# Per plan slot: grid origin x, y and the number of free cells coverage is measured against.
_ORIGIN_X, _ORIGIN_Y, _FREE_TOTAL = range(3)
_CELL, _GOAL = range(2)
#: Map cells of all the rows together (one byte each): a bound on a vector env's memory.
_MAX_BATCH_CELLS = 500_000_000


@njit(cache=True)
def _observe(b, state, arrays, w):
    """Mark row ``b``'s beams on its grid (plan slot ``w``); returns the fraction of the free area newly observed."""
    task, cells, known_rows, known_cols, free, grids, tp = arrays
    grid = grids[w]
    beams = (state[b, S.READING : S.READING + 6], state[b, S.TOO_CLOSE : S.TOO_CLOSE + 6],
             state[b, S.NO_RETURN : S.NO_RETURN + 6])  # fmt: skip
    true_pose = (state[b, S.X], state[b, S.Y], state[b, S.HEADING_COS], state[b, S.HEADING_SIN])
    fresh = mark_beams_rotated(
        (cells[b], known_rows[b], known_cols[b]), (grid[_ORIGIN_X], grid[_ORIGIN_Y], tp[_CELL]), true_pose, beams,
        free[w],
    )  # fmt: skip
    task[b, _SEEN] += fresh
    # The paper's Figure 8: the same readings placed from the true and from the dead-reckoned pose.
    dead_reckoned_pose = (state[b, S.DR_X], state[b, S.DR_Y], state[b, S.DR_COS], state[b, S.DR_SIN])
    total, count = placement_gaps_rotated(true_pose, dead_reckoned_pose, state[b, S.READING : S.READING + 6])
    task[b, _ERROR_SUM] += total
    task[b, _POINTS] += count
    return fresh / grid[_FREE_TOTAL]


@njit(cache=True)
def _write_metrics(b, state, arrays, w, out):
    """The task's metrics into ``out[b]``; returns whether the coverage goal is reached (the episode's end)."""
    task, grids, tp = arrays[0], arrays[5], arrays[6]
    coverage = task[b, _SEEN] / grids[w, _FREE_TOTAL]
    out[b, _M_COVERAGE] = coverage
    out[b, _M_MAP_ERROR] = task[b, _ERROR_SUM] / max(task[b, _POINTS], 1.0)
    out[b, _M_STEPS] = state[b, S.STEPS]
    return coverage >= tp[_GOAL]


@njit(cache=True)
def _start_row(b, sim, arrays, out):
    """Freshly placed robot ``b``: an unknown map, then what it sees before its first tip (which counts)."""
    state, w = sim[S.A_STATE], S.plan_slot(b, sim)
    task, cells, known_rows, known_cols = arrays[0], arrays[1], arrays[2], arrays[3]
    cells[b, :, :] = 0  # unknown
    known_rows[b, :] = 0
    known_cols[b, :] = 0
    task[b, :] = 0.0
    _observe(b, state, arrays, w)
    return _write_metrics(b, state, arrays, w, out)


@njit(cache=True)
def _score_row(b, sim, arrays, out):
    """Robot ``b`` after its tip: the share of the free area its beams newly observed, blocked tips."""
    state, w = sim[S.A_STATE], S.plan_slot(b, sim)
    out[b, _R_COVERAGE] = 100.0 * _observe(b, state, arrays, w)  # percent newly observed
    out[b, _R_BLOCKED] = -1.0 if state[b, S.BLOCKED] > 0.5 else 0.0
    return _write_metrics(b, state, arrays, w, out)


@njit(cache=True)
def _reset_kernel(rows, kernel):
    reset_task(rows, kernel, _start_row, REWARD_TERMS)


@njit(cache=True)
def _step_kernel(actions, kernel):
    step_task(actions, kernel, _score_row, REWARD_TERMS)


@documents_layouts(LAYOUT_SPLIT)
class BuckybotExploreEnv(BuckybotEnv):
    """Map an unknown floor plan: sweep as much of its free area as possible with the six range finders.

    ## Description
    The Buckybot of :class:`~polyenvs.buckybot.wall_follow.BuckybotWallFollowEnv` (Buckybot paper) is dropped in
    an unknown plan. Every valid beam frees the cells it crosses; the paper's mapping experiment (Figure 8) is
    reproduced by ``info["ground_truth"]``: the true and the dead-reckoned pose (the robot replays the mean tip model on its own
    actuator sequence), and ``map_error_cm``, how far the obstacle points placed from dead reckoning lie from the
    same points placed from the true pose. Baseline: ``baselines.buckybot.WallFollowExplorer``.

    ## Action Space
    ``Discrete(3)`` (:class:`~polyenvs.buckybot.env.BuckybotAction`), tip directions in the resting face's frame
    (see BuckybotWallFollow-v0).

    ## Observation Space
    ``Box(0, 1, (19,), float32)``: the six range readings, too-close and no-return flags and the tip-failed flag,
    exactly as BuckybotWallFollow-v0 (``env.observation_structure``).

    ## Rewards
    ``reward_coverage``: 100 x the fraction of the free area newly observed (from the true pose) by this step's
    beams, so a full sweep sums to 100; ``reward_blocked = -1`` for a blocked tip.

    ## Starting State
    As BuckybotWallFollow-v0; the default plan is the office (three rooms and a corridor).

    ## Episode End
    Terminates when ``coverage >= coverage_goal``; truncated after ``max_episode_steps`` (1000 at registration).
    The metrics (``env.unwrapped.episode_metrics()``; ``info["episode_metrics"]`` at the episode's end, as in
    BuckybotWallFollow-v0): ``coverage`` (fraction of the free area observed), ``map_error_cm`` (mean
    distance between dead-reckoned and true obstacle points), ``steps`` (tips taken, blocked ones included),
    ``blocked_tips``, ``oscillation_events``.

    ## Task score
    ``coverage`` (max, ceiling 1; ties at the ceiling broken by fewer ``steps``). The paper's second application is
    mapping an unknown indoor environment with the range finders (its Figure 8): what such a map is worth is how
    much of the free area the robot has seen, so the score is the fraction of it observed, and between two robots
    that see all of it, the one that took fewer tips did better. ``map_error_cm`` measures dead reckoning, which
    no policy controls, so it is reported beside the score, not part of it.

    ## Arguments
    | argument | default | meaning |
    |----------|---------|---------|
    | floor_plan | "office" | as BuckybotWallFollow-v0 |
    {layouts}
    | coverage_goal | 0.95 | coverage that ends the episode, in [0.01, 1] |
    | cell_cm | 10.0 | occupancy-grid cell size, in [2, 50]; the grid over the plan may hold at most 1,000,000 cells |
    | noise_scale, range_noise_scale, step_*, heading_*, body_radius_cm, render_mode, window_scale, num_rows | | as BuckybotWallFollow-v0 |

    ## Version History
    {version_history}
    """

    out_columns = OUT
    default_floor_plan = "office"

    def __init__(self, *, floor_plan=default_floor_plan, coverage_goal: float = 0.95, cell_cm: float = 10.0, **kwargs):
        self.coverage_goal = check_in_range("coverage_goal", coverage_goal, 0.01, 1.0)
        self.cell_cm = check_in_range("cell_cm", cell_cm, 2.0, 50.0)
        super().__init__(floor_plan=floor_plan, **kwargs)

    def _task_init(self):
        if self.floor_plan is not None:
            self.floor_plan.check_grid(self.cell_cm)
            shape = self.floor_plan.grid(self.cell_cm).shape
        else:
            shape = grid_shape(RANDOM_ROOM_BOUNDS, self.cell_cm)[1]  # every random room's grid fits in this one
        n, slots = self._batch_size, self._n_slots
        if n * shape[0] * shape[1] > _MAX_BATCH_CELLS:
            raise ValueError(
                f"num_envs={n} robots with cell_cm={self.cell_cm:g} need {n * shape[0] * shape[1]:,} map cells "
                f"(at most {_MAX_BATCH_CELLS:,}): use fewer robots or larger cells"
            )
        self._task_state = np.zeros((n, 3))
        self._cells = np.zeros((n, *shape), dtype=np.int8)
        # The same maps as bit planes (:func:`polyenvs.buckybot.mapping.known_bits`): most beams cross only known
        # cells, which these settle a line of cells at a time.
        words = (shape[0] * shape[1] + 63) // 64
        self._known_rows = np.zeros((n, 2 * words), dtype=np.uint64)
        self._known_cols = np.zeros((n, words), dtype=np.uint64)
        self._free = np.zeros((slots, *shape), dtype=np.bool_)  # the free area coverage is measured against
        self._grids = np.zeros((slots, 3))
        self._task_params = np.array([self.cell_cm, self.coverage_goal])

    def _task_arrays(self):
        return (self._task_state, self._cells, self._known_rows, self._known_cols, self._free, self._grids,
                self._task_params)  # fmt: skip

    def _task_install_plan(self, slot: int, plan: FloorPlan) -> None:
        g = plan.grid(self.cell_cm)
        h, w = g.shape
        self._free[slot] = False
        self._free[slot, :h, :w] = g.region == g.main_region
        self._grids[slot] = (*g.origin, max(int(self._free[slot].sum()), 1))

    @property
    def map(self) -> OccupancyGrid:
        """Row 0's occupancy grid, built from the true pose (a read-only view: the kernels keep bit planes of it)."""
        g = self.plan.grid(self.cell_cm)
        h, w = g.shape
        cells = self._cells[0, :h, :w].view()
        cells.flags.writeable = False
        return OccupancyGrid(g.origin, g.shape, self.cell_cm, cells=cells)

    @property
    def coverage(self) -> np.ndarray:
        """Fraction of the free area observed, per row."""
        slots = self._grids[:, _FREE_TOTAL] if self._n_slots > 1 else self._grids[0, _FREE_TOTAL]
        return self._task_state[:, _SEEN] / slots

    _step_kernel = staticmethod(_step_kernel)
    _reset_kernel = staticmethod(_reset_kernel)
