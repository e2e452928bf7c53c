"""Estimators for the bumper cart's logs: dead reckoning (the paper's Part 2) and the paper's bump-space Monte
Carlo localizer (Part 3). Both follow :class:`polyenvs.estimators.Estimator`.

The bump-space localizer is the paper's filter of :mod:`polyenvs.bumper.bump_space` (its kernels live on the
family's floor, where the localization task runs them too) behind the estimator interface.
"""

from __future__ import annotations

import numpy as np

from polyenvs.bumper.bump_space import BumpSpaceFilter, densest_cluster, log_index, mcl_update
from polyenvs.bumper.odometry import dead_reckon

__all__ = ["BumpSpaceMCL", "DeadReckoning"]


class DeadReckoning:
    """The paper's Part 2: the logged odometry of every stage added end to end from the true start pose.

    Returns the pose at the end of each cycle's drive. Without any correction it drifts: the wheel base is only
    known approximately, the wheels slip, and large slips at bumps are never seen.
    """

    def reset(self, context, start_pose, rng=None) -> None:
        self.context = context
        self.pose = np.array(start_pose, dtype=np.float64)

    def update(self, log) -> np.ndarray:
        ticks = np.asarray(log, dtype=np.float64)[log_index(self.context)[0]]
        poses = dead_reckon(self.pose, ticks, self.context.wheel_base_cm, self.context.tick_cm)
        self.pose = poses[3]
        return poses[2]  # after the turn and the drive: at the bump


class BumpSpaceMCL(BumpSpaceFilter):
    """The paper's bump-space Monte Carlo localizer (Part 3), vectorised over particles in one compiled call.

    Global localization: the start pose is not used; particles start uniform over the free space.

    Arguments: :class:`~polyenvs.bumper.bump_space.BumpSpaceFilter`'s (the particle count, the motion errors, the
    bump-space tolerance, the bumper, the estimate's cell).

    After an update that leaves no particle in the bump space (the paper's failure: "a movement resulted in no
    particles in the bump-space"), ``empty_sets`` counts one and the particles are seeded afresh over the map.
    """

    _tabled = None  # the map self.table was built for

    def reset(self, context, start_pose, rng: np.random.Generator) -> None:
        self.configure(context)
        if self._tabled is not context.world:  # the bump-space table: once per map, not per reset
            self.table = self.make_table(context.world.bounds)
            self.table.install(0, context.world.walls)
            self._tabled = context.world
        self.rng = rng
        self.particles = self.seed_particles(rng)
        self.spare = np.empty((self.n, 5))  # the survivors and their headings' cos and sin
        self.noise = np.empty((self.n, 3, 3), dtype=np.float32)  # float32 draws: half the generator's time
        self.estimate = np.zeros(3)
        self.survivors = self.n
        self.empty_sets = 0

    def update(self, log) -> np.ndarray:
        log = np.asarray(log)
        ticks, bump = log[self._tick_index].astype(np.float64), bool(log[self._bump_index] > 0.5)
        self.rng.standard_normal(dtype=np.float32, out=self.noise)
        cloud = (self.particles, self.spare, self.counts)
        model = (self.params, self.walls, (self.table.codes[0], self.table.grid))
        kept = mcl_update(cloud, (ticks, bump), self.noise, model, self.estimate)
        self.survivors = kept
        if kept == 0:
            self.empty_sets += 1
            self.particles = self.seed_particles(self.rng)
            densest_cluster(self.particles, self.n, self.params, self.counts, self.estimate)
        return self.estimate.copy()
