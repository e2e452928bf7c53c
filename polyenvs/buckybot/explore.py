"""BuckybotExplore: cover an unknown floor plan with the range finders."""

from __future__ import annotations

from polyenvs.buckybot.env import BuckybotEnv
from polyenvs.buckybot.mapping import OccupancyGrid, placement_error
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

    def __init__(self, *, floor_plan="office", coverage_goal: float = 0.95, cell_cm: float = 10.0, **kwargs):
        self.coverage_goal = check_in_range("coverage_goal", coverage_goal, 0.0, 1.0)
        self.cell_cm = check_positive("cell_cm", cell_cm)
        if self.cell_cm > 50.0:
            raise ValueError(f"cell_cm must be <= 50 cm to resolve the robot's surroundings, got {cell_cm!r}")
        super().__init__(floor_plan=floor_plan, **kwargs)

    def _reward_names(self):
        return ("coverage", "blocked")

    def _task_reset(self, options):
        g = self.plan.grid(self.cell_cm)
        self._free = g.region == g.main_region  # the free area coverage is measured against
        self._free_total = max(int(self._free.sum()), 1)
        self.map = OccupancyGrid(g.origin, g.shape, g.cell_cm)
        self._seen_count = 0
        self._map_error_sum = 0.0
        self._map_points = 0
        self._observe()

    def _observe(self) -> int:
        sim = self.sim
        reading = self.last_reading
        fresh = self.map.observe(
            sim.position[0], sim.heading[0], reading, self.last_too_close, self.last_no_return, count_in=self._free
        )
        self._seen_count += fresh
        # The paper's Figure 8: the same readings placed from the true and from the dead-reckoned pose.
        x, y = sim.position[0].tolist()
        xd, yd = sim.dr_position[0].tolist()
        total, count = placement_error((x, y, sim.heading[0]), (xd, yd, sim.dr_heading[0]), reading)
        self._map_error_sum += total
        self._map_points += count
        return fresh

    @property
    def coverage(self) -> float:
        return self._seen_count / self._free_total

    def _task_step(self, action, blocked):
        fresh = self._observe()
        return {"coverage": 100.0 * fresh / self._free_total, "blocked": -1.0 if blocked else 0.0}

    def _task_terminated(self):
        return self.coverage >= self.coverage_goal

    def _episode_metrics(self):
        metrics = super()._episode_metrics()
        metrics.update(coverage=self.coverage, map_error_cm=self._map_error_sum / max(self._map_points, 1))
        return metrics
