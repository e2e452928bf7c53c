"""BuckybotExplore: cover an unknown floor plan with the range finders."""

from __future__ import annotations

import numpy as np

from polyenvs.buckybot.env import BuckybotEnv
from polyenvs.buckybot.mapping import OccupancyGrid, mark_beams, placement_gaps
from polyenvs.core.jit import njit
from polyenvs.core.validation import check_in_range, check_positive

__all__ = ["BuckybotExploreEnv"]


class BuckybotExploreEnv(BuckybotEnv):
    """Map an unknown floor plan: sweep as much of its free area as possible with the six range finders.

    ## Description
    The Buckybot of :class:`~polyenvs.buckybot.wall_follow.BuckybotWallFollowEnv` (Buckybot paper) is dropped in
    an unknown plan. Every valid beam frees the cells it crosses; the paper's mapping experiment (Figure 8) is
    reproduced by ``info``: the true and the dead-reckoned pose (the robot replays the mean tip model on its own
    actuator sequence), and ``map_error_cm``, how far the obstacle points placed from dead reckoning lie from the
    same points placed from the true pose. Baseline: ``baselines.buckybot.WallFollowExplorer``.

    ## Action Space
    ``Discrete(3)``, tip directions in the resting face's frame (see BuckybotWallFollow-v0).

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
    ``info["episode_metrics"]``: ``coverage`` (fraction of the free area observed), ``map_error_cm`` (mean
    distance between dead-reckoned and true obstacle points), ``blocked_tips``, ``oscillation_events``.

    ## Arguments
    | argument | default | meaning |
    |----------|---------|---------|
    | floor_plan | "office" | as BuckybotWallFollow-v0 |
    | coverage_goal | 0.95 | coverage that ends the episode |
    | cell_cm | 10.0 | occupancy-grid cell size |
    | noise_scale, range_noise_scale, step_*, heading_*, body_radius_cm, render_mode | | as BuckybotWallFollow-v0 |

    ## Version History
    * v0: initial version.
    """

    reward_names = ("coverage", "blocked")

    def __init__(self, *, floor_plan="office", coverage_goal: float = 0.95, cell_cm: float = 10.0, **kwargs):
        self.coverage_goal = check_in_range("coverage_goal", coverage_goal, 0.0, 1.0)
        self.cell_cm = check_positive("cell_cm", cell_cm)
        if self.cell_cm > 50.0:
            raise ValueError(f"cell_cm must be <= 50 cm to resolve the robot's surroundings, got {cell_cm!r}")
        super().__init__(floor_plan=floor_plan, **kwargs)
        n = self._batch_size
        self._seen = np.zeros(n, dtype=np.int64)  # free cells of the main region observed so far
        self._map_error_sum = np.zeros(n)
        self._map_points = np.zeros(n, dtype=np.int64)
        self._grid_plan = None

    @property
    def map(self) -> OccupancyGrid:
        """Row 0's occupancy grid, built from the true pose."""
        return OccupancyGrid(self._grid.origin, self._grid.shape, self._grid.cell_cm, cells=self._cells[0])

    @property
    def coverage(self) -> np.ndarray:
        """Fraction of the free area observed, per row."""
        return self._seen / self._free_total

    def _task_reset(self, rows, options):
        if self._grid_plan is not self.plan:
            g = self._grid = self.plan.grid(self.cell_cm)
            self._free = g.region == g.main_region  # the free area coverage is measured against
            self._free_total = max(int(self._free.sum()), 1)
            self._cells = np.zeros((self._batch_size, *g.shape), dtype=np.int8)
            self._grid_plan = self.plan
        self._cells[rows] = OccupancyGrid.UNKNOWN
        self._seen[rows] = 0
        self._map_error_sum[rows] = 0.0
        self._map_points[rows] = 0
        active = np.zeros(self._batch_size, dtype=bool)
        active[rows] = True
        nothing_blocked = np.zeros(self._batch_size, dtype=bool)
        self._task_step(None, nothing_blocked, active)  # what the robot sees before its first tip counts too

    def _task_step(self, actions, blocked, active):
        sim, g = self.sim, self._grid
        _explore_step(
            active, blocked, self._cells, g.origin[0], g.origin[1], g.cell_cm, sim.position, sim.heading,
            sim.dr_position, sim.dr_heading, sim.reading, sim.too_close, sim.no_return, self._free,
            float(self._free_total), self._seen, self._map_error_sum, self._map_points, self._rewards,
        )  # fmt: skip

    def _task_terminated(self):
        return self.coverage >= self.coverage_goal

    def _episode_metrics(self, row):
        metrics = super()._episode_metrics(row)
        metrics.update(
            coverage=int(self._seen[row]) / self._free_total,
            map_error_cm=float(self._map_error_sum[row]) / max(int(self._map_points[row]), 1),
        )
        return metrics


@njit(cache=True)
def _explore_step(
    active, blocked, cells, ox, oy, cell, position, heading, dr_position, dr_heading, reading, too_close, no_return,
    free, free_total, seen, map_error_sum, map_points, rewards,
):  # fmt: skip
    for b in range(active.shape[0]):
        if not active[b]:
            rewards[b, :] = 0.0
            continue
        fresh = mark_beams(
            cells[b], ox, oy, cell, position[b, 0], position[b, 1], heading[b], reading[b], too_close[b],
            no_return[b], free,
        )  # fmt: skip
        seen[b] += fresh
        rewards[b, 0] = 100.0 * fresh / free_total  # percent of the free area newly observed
        rewards[b, 1] = -1.0 if blocked[b] else 0.0
        # The paper's Figure 8: the same readings placed from the true and from the dead-reckoned pose.
        total, count = placement_gaps(
            position[b, 0], position[b, 1], heading[b], dr_position[b, 0], dr_position[b, 1], dr_heading[b], reading[b]
        )
        map_error_sum[b] += total
        map_points[b] += count
