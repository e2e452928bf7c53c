"""The paper's dead-reckoning Monte Carlo ("Simulation and Results"), on the same simulator core as the envs.

The paper reports, after 100 tips (about 929 cm), a position sd of 90.42 cm and a heading sd of 11.5°. With the
paper's own per-tip numbers (heading sd 0.44°) the heading sd after 100 tips is 0.44 sqrt(100) = 4.4° whatever
the path, and a straight-ish walk spreads about 35 cm; the paper's pair comes back only with about 1.15° per tip
(``geometry-checks.md`` A3). :func:`dead_reckoning_monte_carlo` reports what a model gives, it is not tuned.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from polyenvs.buckybot.simulator import BuckybotSimulator, TipModel
from polyenvs.core.geometry2d import SegmentTable

__all__ = ["MonteCarloResult", "PAPER_MONTE_CARLO", "dead_reckoning_monte_carlo"]

#: The paper's reported spread after 100 steps: (position sd cm, heading sd deg).
PAPER_MONTE_CARLO = (90.42, 11.5)


@dataclass(frozen=True)
class MonteCarloResult:
    position_sd_cm: float  # sqrt(var x + var y) of the true end point about its mean
    heading_sd_deg: float
    distance_travelled_cm: float  # mean path length
    dead_reckoning_error_cm: float  # RMS distance between true and dead-reckoned end points


def dead_reckoning_monte_carlo(
    n_runs: int = 2000,
    n_tips: int = 100,
    walk: str = "zigzag",
    tip_model: TipModel | None = None,
    seed: int = 0,
) -> MonteCarloResult:
    """Replay one actuator sequence ``n_runs`` times with tipping noise, in open space.

    Args:
        walk: ``"zigzag"``, the straight-ish armchair walk (alternating forward-right and forward-left tips,
            as a wall follower walks), or ``"random"`` (uniform among the two forward tips, never back).
        tip_model: the per-tip model (default: the paper's measurements).
    """
    model = tip_model or TipModel()
    rng = np.random.default_rng(seed)
    if walk == "zigzag":
        actions = np.where(np.arange(n_tips) % 2 == 0, 1, 2)
    elif walk == "random":
        actions = rng.integers(1, 3, size=n_tips)
    else:
        raise ValueError(f"walk must be 'zigzag' or 'random', got {walk!r}")
    sim = BuckybotSimulator(n_runs, model, range_noise_scale=0.0, body_radius_cm=13.0)
    far = 1e7  # a single wall far away: nothing is ever blocked
    sim.set_walls(SegmentTable(np.array([[far, -1.0, far, 1.0]])))
    sim.place(slice(None), np.zeros(2), 0, 0.0)
    sim.tip_allowed[:] = True
    travelled = np.zeros(n_runs)
    for action in actions:
        before = sim.position.copy()
        sim.tip(np.full(n_runs, action), rng.standard_normal((n_runs, 3)))
        travelled += np.hypot(*(sim.position - before).T)
    spread = sim.position - sim.position.mean(axis=0)
    heading_error = (sim.heading - sim.dr_heading + np.pi) % (2 * np.pi) - np.pi
    return MonteCarloResult(
        position_sd_cm=float(np.sqrt((spread**2).sum(axis=1).mean())),
        heading_sd_deg=float(np.degrees(heading_error.std())),
        distance_travelled_cm=float(travelled.mean()),
        dead_reckoning_error_cm=float(np.sqrt(((sim.position - sim.dr_position) ** 2).sum(axis=1).mean())),
    )
