"""The paper's localization claims (spec: bumper.md, "What tests must reproduce"), measured on seeded logs in the
paper's arena, with margins under the values the project's defaults give (100 runs of 15 bumps, seed 0):

| particles | runs with an empty set | never converged | median position error at bump 10 (cm) | within 10 cm and 30° at bump 10 |
| --- | --- | --- | --- | --- |
| 100 | 0.83 | 0.54 | 54 | 0.21 |
| 300 | 0.52 | 0.50 | 55 | 0.25 |
| 500 | 0.29 | 0.39 | 33 | 0.33 |
| 700 | 0.15 | 0.40 | 35 | 0.34 |
| 1,000 | 0.12 | 0.31 | 13 | 0.46 |
| 3,000 | 0.02 | 0.17 | 5 | 0.61 |

Dead reckoning from the true start: median 1.4 cm at bump 1, 18 cm at bump 10, 26 cm at bump 15.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the ids)
from polyenvs.bumper.odometry import odometry_step
from polyenvs.estimators.bumper import BumpSpaceMCL, DeadReckoning
from polyenvs.evaluation.localization import rollout_logs, score_estimator, summarize

ENV_ID = "polyenvs/BumperCartExplore-v0"
RUNS, BUMPS = 100, 15


@pytest.fixture(scope="module")
def logs():
    return rollout_logs(ENV_ID, RUNS, BUMPS, seed=0)


@pytest.fixture(scope="module")
def scores(logs):
    context, runs = logs
    out = {"dead_reckoning": summarize(score_estimator("dead_reckoning", {}, context, runs, BUMPS))}
    for n in (100, 300, 700, 1000):
        out[n] = summarize(score_estimator("mcl", {"particles": n}, context, runs, BUMPS))
    return out


def test_logs_are_seeded_and_complete(logs):
    context, runs = logs
    assert len(runs) == RUNS and all(run.bumped.sum() == BUMPS for run in runs)
    again = rollout_logs(ENV_ID, 2, BUMPS, seed=0)[1]
    np.testing.assert_array_equal(again[1].logs, runs[1].logs)
    np.testing.assert_array_equal(again[1].truth, runs[1].truth)


def test_empty_particle_sets_fall_steeply_with_the_particle_count(scores):
    few, many = scores[100]["failure_rates"], scores[1000]["failure_rates"]
    assert few["empty_particle_set"] >= 0.7
    assert many["empty_particle_set"] <= 0.2
    assert few["never_converged"] > many["never_converged"]


def test_error_against_the_truth_falls_with_the_particle_count(scores):
    for k in (9, 14):  # after bumps 10 and 15
        assert scores[1000]["position_error_cm"]["median"][k] < 0.5 * scores[100]["position_error_cm"]["median"][k]
        assert scores[1000]["converged_fraction"][k] > scores[100]["converged_fraction"][k] + 0.2


def test_dead_reckoning_drifts_and_the_localizer_beats_it_by_bump_15(scores):
    dr = scores["dead_reckoning"]["position_error_cm"]["median"]
    assert dr[0] < 3.0 and dr[14] > 3 * dr[0] and dr[14] > 10.0
    assert scores[1000]["position_error_cm"]["median"][14] < 0.6 * dr[14]


def test_the_papers_5_to_10_bumps_claim_is_only_half_true(scores):
    """ "Converges within about 5 to 10 bumps with 700 or more particles": about half the runs are within 10 cm and
    30° by bump 10 at 1,000 particles, as the feasibility study found; a quarter stay locked on a wrong pose."""
    converged = scores[1000]["converged_fraction"]
    assert 0.3 <= converged[9] <= 0.8
    assert converged[4] < converged[9]
    assert scores[1000]["failure_rates"]["never_converged"] >= 0.1


def test_the_papers_700_particle_threshold_is_where_empty_sets_level_off(scores):
    """ "Results were only good for 700 or more particles. Less than that and some runs of the algorithm would not
    converge at all, meaning a movement resulted in no particles in the bump-space." The rate of runs with an
    empty particle set falls steeply up to 700 (0.83 / 0.52 / 0.15 at 100 / 300 / 700) and barely after it (0.12
    at 1,000): the paper's knee. Position error is another matter: the median at bump 10 is still 35 cm at 700
    against 13 cm at 1,000 (``test_the_papers_5_to_10_bumps_claim_is_only_half_true``)."""
    empty = {n: scores[n]["failure_rates"]["empty_particle_set"] for n in (100, 300, 700, 1000)}
    assert empty[300] - empty[700] >= 0.25 and empty[300] >= 2.5 * empty[700], empty
    assert empty[700] <= 0.25 and empty[700] - empty[1000] <= 0.08, empty


def test_mcl_is_deterministic_for_a_seed_and_estimates_a_dense_cluster(logs):
    context, runs = logs
    estimates = []
    for _ in range(2):
        mcl = BumpSpaceMCL(particles=500)
        mcl.reset(context, runs[0].start_pose, np.random.default_rng(3))
        estimates.append(np.array([mcl.update(log) for log in runs[0].logs]))
    np.testing.assert_array_equal(*estimates)
    # The estimate is where the particles are densest: most particles lie within 15 cm of it once converged.
    near = np.hypot(*(mcl.particles[:, :2] - estimates[1][-1][:2]).T) < 15.0
    assert near.mean() > 0.3


def test_mcl_bump_space_keeps_only_poses_facing_a_wall(logs):
    context, runs = logs
    exact = dict(heading_sd_deg=0, heading_sd_frac=0, forward_sd_cm=0, forward_sd_frac=0, lateral_sd_cm=0,
                 lateral_sd_frac=0)  # fmt: skip
    mcl = BumpSpaceMCL(particles=2000, **exact)
    mcl.reset(context, runs[0].start_pose, np.random.default_rng(0))
    log = runs[0].logs[0].copy()
    log[4:6] = 0  # no back-up: the particles stay where the bump-space test left them
    mcl.update(log)  # the first bump
    x, y, h = mcl.particles.T
    front = np.stack([x + context.bumper_offset_cm * np.cos(h), y + context.bumper_offset_cm * np.sin(h)], -1)
    assert (context.world.clearance(front) < context.bumper_width_cm / 2 + mcl.tolerance_cm + 0.01).all()
    assert context.world.free(mcl.particles[:, :2]).all()


NO_MOTION_ERROR = dict(heading_sd_deg=0, heading_sd_frac=0, forward_sd_cm=0, forward_sd_frac=0, lateral_sd_cm=0,
                       lateral_sd_frac=0)  # fmt: skip


#: Three stages a cycle (turn, drive, back-up), each with its own draws: a fixed sd acts three times (root 3), one
#: proportional to the distance only in the drive (here the only stage that moves).
THREE_STAGES = math.sqrt(3.0)


@pytest.mark.parametrize(
    "error,spread",
    [({"forward_sd_frac": 0.06}, (3.0, 0.0, 0.0)), ({"lateral_sd_frac": 0.06}, (0.0, 3.0, 0.0)),
     ({"forward_sd_cm": 0.6}, (0.6 * THREE_STAGES, 0.0, 0.0)), ({"lateral_sd_cm": 0.6}, (0.0, 0.6 * THREE_STAGES, 0.0)),
     # the turn's heading error sends the 50 cm drive off sideways
     ({"heading_sd_deg": 2.0}, (0.0, 50.0 * math.radians(2.0), 2.0 * THREE_STAGES))],
)  # fmt: skip
def test_each_motion_error_spreads_the_particles_along_its_own_axis(logs, error, spread):
    """One 50 cm straight drive east without a bump, every particle from one pose: ``(sd of x along the drive,
    sd of y across it, sd of the heading in degrees)``. The forward error spreads the particles along the drive,
    the lateral one across it, the heading one (``heading_sd_deg``, in degrees) turns them."""
    context, _ = logs
    mcl = BumpSpaceMCL(particles=20_000, **{**NO_MOTION_ERROR, **error})
    mcl.reset(context, None, np.random.default_rng(0))
    mcl.particles[:] = (30.0, 45.0, 0.0)
    ticks = round(50.0 / context.tick_cm)
    log = np.zeros(7)
    log[slice(*context.observation_structure["drive_ticks"])] = ticks
    mcl.update(log)
    x, y, heading = mcl.particles.T
    np.testing.assert_allclose([x.std(), y.std()], spread[:2], rtol=0.05, atol=0.1)
    assert np.degrees(heading.std()) == pytest.approx(spread[2], rel=0.05, abs=1e-9)
    assert abs(x.mean() - (30.0 + ticks * context.tick_cm)) < 0.1 and abs(y.mean() - 45.0) < 0.1


def test_dead_reckoning_matches_the_odometry(logs):
    context, runs = logs
    run = runs[0]
    dr = DeadReckoning()
    dr.reset(context, run.start_pose, None)
    first = dr.update(run.logs[0])
    x, y, h = run.start_pose
    for k in range(2):
        left, right = run.logs[0][2 * k : 2 * k + 2] * context.tick_cm
        x, y, h = odometry_step(x, y, h, left, right, context.wheel_base_cm)
    np.testing.assert_allclose(first, (x, y, h))


@pytest.mark.parametrize(
    "kwargs,name",
    [({"particles": 5}, "particles"), ({"particles": 100.0}, "particles"), ({"tolerance_cm": -1}, "tolerance_cm"),
     ({"heading_sd_deg": float("nan")}, "heading_sd_deg"), ({"forward_sd_frac": True}, "forward_sd_frac")],
)  # fmt: skip
def test_bad_mcl_parameters_name_themselves(kwargs, name):
    with pytest.raises(ValueError, match=name):
        BumpSpaceMCL(**kwargs)


def test_heading_error_is_wrapped():
    assert math.isclose(
        abs(math.degrees((math.radians(179) - math.radians(-179) + math.pi) % (2 * math.pi) - math.pi)), 2.0
    )
