"""The bump-only cart paper's remaining claims (``seeds/001``): the arc that unmatched motors drive, the
heavy-tailed slip at bumps, the bump-space localizer's split into symmetric clusters and its reconvergence in "3 or
4 more iterations", its sensitivity to the lateral error and the bumper it assumes, and BumperCartLocalize-v0's
termination tolerances in their units."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the ids)
from baselines.base import RandomPolicy
from polyenvs.bumper import cart as C
from polyenvs.bumper.bump_space import densest_cluster
from polyenvs.bumper.env import BumperCartExploreEnv
from polyenvs.bumper.maps import make_map
from polyenvs.bumper.odometry import TICK_CM, odometry_step
from polyenvs.estimators.bumper import BumpSpaceMCL
from polyenvs.evaluation.localization import rollout_logs, score_estimator, summarize

LOGS_ID = "polyenvs/BumperCartExplore-v0"


# --- Part 2: "the robot will follow an arc instead of a straight line" ---------------------------------------------
#: Facing east (heading 0, in degrees and radians alike) from the west end of the paper's arena, the drive crosses
#: the room before it bumps.
ARC_START = (15.0, 45.0, 0.0)
WHEEL_BASE_CM = C.CartModel().wheel_base_cm


def _straight_drives(seeds, **cart) -> np.ndarray:
    """One cycle with no turn (equal power to both motors) per seed: the drive's left and right ticks and the true
    pose at the bump, ``(seeds, 5)``. No wheel slip and the nominal wheel base, so only the motors' mismatch acts."""
    env = BumperCartExploreEnv(map="paper", slip_sd=0.0, wheel_base_sd=0.0, snap_prob=0.0, slide_prob=0.0, **cart)
    drive = slice(*env.observation_structure["drive_ticks"])
    rows = []
    for seed in seeds:
        env.reset(seed=seed, options={"pose": ARC_START})
        obs, _, _, _, info = env.step(np.zeros(1, np.float32))
        assert info["bumped"]
        rows.append([*obs[drive], *info["pose_at_bump"]])
    return np.array(rows)


def test_equal_power_drives_an_arc_whose_geometry_the_two_encoders_give():
    """The paper: the Lego motors "are not terribly well matched", so at equal power "the robot will follow an arc
    instead of a straight line", and "combining the readings from the two sensors makes it possible to determine
    the exact geometry of the path". Over 200 episodes of the default cart (a 2% sd mismatch, *ours*), a drive with
    no turn ends turned by -47° to +50° (82% by more than 5°), its bump point a median 10.7 cm off the start's
    line; the arc from the logged ticks (Part 2's odometry) lands within 1.3 cm and 1.5° of the truth (the ticks'
    rounding), turned the way the faster wheel says; the curvature times the wheel base, the relative mismatch,
    has an sd of 0.019. With matched motors the drive is straight and the ticks equal."""
    drives = _straight_drives(range(200))
    left, right, x, y, heading_deg = drives.T
    ends = np.array(
        [odometry_step(*ARC_START, a * TICK_CM, b * TICK_CM, WHEEL_BASE_CM) for a, b in zip(left, right, strict=True)]
    )
    assert np.hypot(ends[:, 0] - x, ends[:, 1] - y).max() < 2.0
    assert np.abs(np.degrees(ends[:, 2]) - heading_deg).max() < 1.7  # one tick of wheel difference is 1.64°
    unequal = np.abs(right - left) >= 2
    assert (np.sign(heading_deg[unequal]) == np.sign(right - left)[unequal]).all() and unequal.mean() > 0.7
    assert (np.abs(heading_deg) > 5).mean() > 0.6 and np.median(np.abs(y - ARC_START[1])) > 5.0
    mismatch = np.radians(heading_deg) * WHEEL_BASE_CM / (0.5 * (left + right) * TICK_CM)
    assert 0.016 <= mismatch.std() <= 0.024
    matched = _straight_drives(range(5), mismatch_sd=0.0)
    assert (matched[:, 0] == matched[:, 1]).all() and (matched[:, 3] == ARC_START[1]).all()
    assert (matched[:, 4] == 0.0).all()


# --- "the errors between bumps tend to be either very small or very large" ---------------------------------------
def _unseen_turns_at_bumps(model: C.CartModel, cycles: int = 2000) -> np.ndarray:
    """Degrees the cart turned at each bump between the drive's end and the back-up (the bump's slip, which the
    encoders never see), over a random bounce in the paper's arena."""
    world, params = make_map("paper"), model.packed()
    rng = np.random.default_rng(0)
    row = np.zeros(C.N_STATE)
    C.place_row(row, world.sample_pose(rng, model.circumradius_cm + 0.5), *model.draw_episode(rng))
    turns = []
    for _ in range(cycles):
        C.cycle_row(row, rng.uniform(-math.pi, math.pi), rng.standard_normal(C.DRAWS_PER_CYCLE), params, world.walls)
        if row[C.BUMP]:
            turned = (row[C.SLIP_HEADING] - row[C.BUMP_HEADING] + math.pi) % (2 * math.pi) - math.pi
            turns.append(math.degrees(turned))
    return np.array(turns)


def test_the_slip_at_a_bump_is_mostly_nothing_and_sometimes_large():
    """The paper's hit 6: the bumper flattened against the wall and the cart turned, unseen; "the errors between
    bumps tend to be either very small or very large". With the default cart, over 2,000 bumps of a random bounce:
    81% of bumps turn the cart not at all, 19% slip (``BIG_SLIP``), 13% by more than 5° and up to 30° (the slide's
    bound); the kurtosis of the unseen turn is 12.7, where a normal distribution's is 3."""
    turns = _unseen_turns_at_bumps(C.CartModel())
    size = np.abs(turns)
    assert len(turns) > 1500
    assert 0.7 <= (size == 0).mean() <= 0.9
    assert 0.07 <= (size > 5).mean() <= 0.25 and size.max() > 20
    assert (size <= C.CartModel().slide_max_deg + 1e-9).all()
    assert np.mean(turns**4) / np.mean(turns**2) ** 2 > 6


def test_the_slip_comes_from_the_snap_and_the_slide_parameters():
    """Both mechanisms off, no bump turns the cart; the snap alone (near head-on hits) squares it to the wall, so
    its turns stay within ``snap_max_deg``."""
    assert (_unseen_turns_at_bumps(C.CartModel(snap_prob=0.0, slide_prob=0.0), 400) == 0).all()
    snap_only = np.abs(_unseen_turns_at_bumps(C.CartModel(slide_prob=0.0), 400))
    assert (snap_only > 0).mean() > 0.05 and snap_only.max() <= 20.0 + 1e-9


# --- the symmetric map: the particle cluster splits, and reconverges on an asymmetric feature ---------------------
#: Turns (fractions of pi) from (60, 45) facing north: bumps on the north, south, west and south walls, the
#: north wall diagonally and then twice into the west end of the north wall's line, where the paper's arena has
#: its cut; the last bump is the north wall again. In the rectangle every one of them has a 180° image; in the
#: paper's arena the cut does not (its image is the open south-east corner).
SCRIPT_START = (60.0, 45.0, 90.0)
SCRIPT_TURNS = (0.0, 1.0, -0.5, 0.5, 0.75, 0.75, 1.0, 1.0, -0.5)
#: A noise-free cart, so that the logs are the geometry's and only the localizer's motion noise spreads it.
EXACT_CART = {"mismatch_sd": 0.0, "wheel_base_sd": 0.0, "slip_sd": 0.0, "snap_prob": 0.0, "slide_prob": 0.0}


def _near(particles, pose, cm=12.0, deg=25.0) -> np.ndarray:
    close = np.hypot(particles[:, 0] - pose[0], particles[:, 1] - pose[1]) < cm
    turned = np.abs((particles[:, 2] - pose[2] + math.pi) % (2 * math.pi) - math.pi)
    return close & (turned < math.radians(deg))


def _share_near(particles, pose, cm=12.0, deg=25.0) -> float:
    return float(_near(particles, pose, cm, deg).mean())


def _cluster_shares(map_name: str, seed: int, particles: int = 5000) -> np.ndarray:
    """After each bump of the script: the share of particles near the true pose and near its image under the
    map's half turn about its centre (x, y, h) -> (x0 + x1 - x, y0 + y1 - y, h + pi). ``(bumps, 2)``."""
    env = BumperCartExploreEnv(map=map_name, **EXACT_CART)
    obs, info = env.reset(seed=0, options={"pose": SCRIPT_START})
    context = env.localization_context()
    mcl = BumpSpaceMCL(particles=particles)
    mcl.reset(context, None, np.random.default_rng(seed))
    x0, y0, x1, y1 = context.world.bounds
    shares = []
    for turn in SCRIPT_TURNS:
        obs, _, _, _, info = env.step(np.array([turn], np.float32))
        assert info["bumped"]
        mcl.update(obs)
        x, y, heading = info["pose_at_bump"]
        truth = (x, y, math.radians(heading))
        image = (x0 + x1 - x, y0 + y1 - y, truth[2] + math.pi)
        shares.append((_share_near(mcl.particles, truth), _share_near(mcl.particles, image)))
    assert mcl.empty_sets == 0
    return np.array(shares)


def test_on_a_symmetric_map_the_belief_splits_into_two_clusters_and_reconverges_on_the_cut():
    """The paper: on a map that looks "pretty close to symmetric" the cluster splits ("two smaller clusters arose
    [...] because of the large uncertainties") and, once the cart bumps what breaks the symmetry, reconverges.
    Six localizer seeds, 5,000 particles, the same bumps in the symmetric rectangle and in the paper's arena.

    In the rectangle both the true pose and its 180° image keep a cluster to the end in every seed (shares here:
    truth 0.06-0.45, image 0.16-0.70), since no bump can tell them apart. In the paper's arena the image holds a
    cluster too before the cut is bumped (mean share 0.15 after bump 5), and after the cut's bumps it is gone
    (at most 0.04) while the truth holds 0.62-0.72 of the particles."""
    rectangle = np.array([_cluster_shares("rectangle", seed)[-1] for seed in range(6)])
    assert (rectangle.min(axis=1) >= 0.03).all() and (rectangle.sum(axis=1) >= 0.4).all(), rectangle
    assert (rectangle.mean(axis=0) >= 0.15).all(), rectangle
    paper = np.array([_cluster_shares("paper", seed) for seed in range(6)])
    assert paper[:, 4, 1].mean() >= 0.08, paper[:, 4]  # split before the cut is bumped
    assert (paper[:, -1, 1] <= 0.06).all() and (paper[:, -1, 0] >= 0.5).all(), paper[:, -1]


# "When this happens it usually takes 3 or 4 more iterations for the location to reconverge." A split, in random-
# bounce runs of the paper's arena: after the belief was one cluster (half the particles near the truth, within 12 cm
# and 25°, and under a tenth in the densest cluster away from it, beyond 30 cm or 60°), a cluster away from the truth
# holds a fifth of the particles while the truth keeps a tenth. It has reconverged at the next bump where the belief
# is one cluster again.
RECONVERGE_RUNS, RECONVERGE_BUMPS = 100, 40
ONE_CLUSTER, STRAY_AT_MOST = 0.5, 0.1
SPLIT_STRAY, SPLIT_TRUTH = 0.2, 0.1
#: A split counts only if it has this many bumps of its run left to reconverge in.
FOLLOW_BUMPS = 10


def _stray_cluster_share(mcl: BumpSpaceMCL, truth: np.ndarray) -> float:
    """The share of the particles in the densest cluster of those beyond 30 cm or 60° of ``truth``."""
    away = np.ascontiguousarray(mcl.particles[~_near(mcl.particles, truth, 30.0, 60.0)])
    return densest_cluster(away, len(away), mcl.params, mcl.counts, np.zeros(3)) / mcl.n if len(away) else 0.0


def _belief_after_each_bump(particles: int) -> list[np.ndarray]:
    """Per run: ``(bumps, 2)``, the share near the truth and the stray cluster's share after each bump."""
    context, runs = rollout_logs(LOGS_ID, RECONVERGE_RUNS, RECONVERGE_BUMPS, seed=0)
    out = []
    for r, run in enumerate(runs):
        mcl = BumpSpaceMCL(particles)
        mcl.reset(context, None, np.random.default_rng([0, r]))
        shares = []
        for log, truth, bumped in zip(run.logs, run.truth, run.bumped, strict=True):
            mcl.update(log)
            if bumped:
                shares.append((_share_near(mcl.particles, truth), _stray_cluster_share(mcl, truth)))
        out.append(np.array(shares))
    return out


def _reconvergence_times(runs: list[np.ndarray]) -> tuple[list[int], int]:
    """The iterations from each split to the next single cluster, and how many splits never reconverged."""
    times, never = [], 0
    for shares in runs:
        coalesced, split_at = False, None
        for k, (truth, stray) in enumerate(shares):
            one_cluster = truth >= ONE_CLUSTER and stray < STRAY_AT_MOST
            if split_at is not None and one_cluster:
                times.append(k - split_at)
                split_at = None
            elif split_at is None and coalesced and stray >= SPLIT_STRAY and truth >= SPLIT_TRUTH:
                split_at = k if k + FOLLOW_BUMPS <= len(shares) else None
            coalesced = coalesced or one_cluster
        never += split_at is not None
    return times, never


@pytest.mark.slow
def test_a_split_belief_reconverges_in_a_median_of_3_or_4_iterations():
    """The paper, after a split at its hit 10: "it usually takes 3 or 4 more iterations for the location to
    reconverge". The paper's localizer at 1,000 particles (the benchmark's default), 100 random-bounce runs of 40
    bumps in its arena (seed 0): 52 splits, 2 never reconverged; the others took a median of 4 iterations (3 on
    seeds 100-199, and 3 on both with 3,000 particles). "Usually" does not hold: 1 to 22 iterations, 18 of the 50
    after one, only 7 after 3 or 4 (docs/papers/bumper.md, "What it does not reproduce")."""
    times, never = _reconvergence_times(_belief_after_each_bump(1000))
    assert len(times) >= 30 and never <= 0.1 * (len(times) + never)
    assert 3 <= np.median(times) <= 4, np.bincount(times)


# --- BumperCartLocalize-v0: "localized" is judged in the tolerances' own units -------------------------------------
def _localize_cycles(seeds, **task) -> list[tuple[float, float, int, bool]]:
    """Every cycle of random-turn episodes: the estimate's position (cm) and heading (deg) error against the pose at
    the bump, from ``info`` alone, and the environment's ``localized_for`` count and ``terminated``."""
    env = gym.make("polyenvs/BumperCartLocalize-v0", **task)
    cycles = []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        policy = RandomPolicy(env.observation_space, env.action_space, seed=seed)
        terminated = truncated = False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
            truth, estimate = info["pose_at_bump"], info["estimate"]
            turned = abs((estimate[2] - truth[2] + 180.0) % 360.0 - 180.0)
            cycles.append((math.hypot(*(estimate[:2] - truth[:2])), turned, info["localized_for"], terminated))
    return cycles


def test_localize_tolerances_are_read_in_centimetres_and_degrees():
    """``position_tolerance_cm`` and ``heading_tolerance_deg`` judge the estimate in cm and degrees: a cycle counts
    towards ``hold_cycles`` exactly when both errors are within them. At the defaults (10 cm, 30°) almost no cycle
    has its position within and its heading outside (none of 80 in six default episodes), so a heading tolerance
    read as radians (30 rad: every heading) would pass them; at 5 cm and 5° (``hold_cycles`` 50, so that episodes
    run their 60 cycles) six random episodes have 103 such cycles out of 360, 107 within both and 12 within 12.7 cm
    (5 inches) but not 5 cm."""
    cycles = _localize_cycles(range(6), position_tolerance_cm=5.0, heading_tolerance_deg=5.0, hold_cycles=50)
    run = 0
    for position_cm, heading_deg, localized_for, terminated in cycles:
        run = run + 1 if position_cm <= 5.0 and heading_deg <= 5.0 else 0
        assert localized_for == run and terminated == (run >= 50)
    position, heading = np.array([c[:2] for c in cycles]).T
    assert ((position <= 5.0) & (heading > 5.0)).sum() >= 40  # a heading tolerance in radians would count these
    assert ((position <= 5.0) & (heading <= 5.0)).sum() >= 40
    assert ((position > 5.0) & (position <= 12.7) & (heading <= 5.0)).sum() >= 5  # ... and one in inches these


# --- Part 3: "very sensitive to [...] the uncertainty in forward and lateral movement, the size of the bumper" ---------
SENSITIVITY_RUNS, SENSITIVITY_BUMPS = 200, 15
#: The localizer's lateral error per stage (cm + fraction of the distance): none, the default, three and five times it.
LATERAL = {"none": (0.0, 0.0), "default": (0.6, 0.06), "3x": (1.8, 0.18), "5x": (3.0, 0.3)}


@pytest.fixture(scope="module")
def sensitivity_logs():
    return rollout_logs(LOGS_ID, SENSITIVITY_RUNS, SENSITIVITY_BUMPS, seed=0)


def _mcl_summary(logs, **kwargs) -> dict:
    context, runs = logs
    return summarize(score_estimator("mcl", {"particles": 1000, **kwargs}, context, runs, SENSITIVITY_BUMPS))


@pytest.fixture(scope="module")
def lateral_scores(sensitivity_logs):
    return {name: _mcl_summary(sensitivity_logs, lateral_sd_cm=cm, lateral_sd_frac=frac)
            for name, (cm, frac) in LATERAL.items()}  # fmt: skip


@pytest.mark.slow
def test_the_lateral_error_trades_empty_particle_sets_against_a_blurred_map(lateral_scores):
    """The paper: the bump space must be "large enough to account for the error [...] in the lego sensors, but small
    enough that some asymmetry is preserved"; "if the uncertainties [...] are too high, a more or less coalesced
    patch of particles will diverge into two quite easily". The paper gives no sizes. 1,000 particles, 200 runs of
    15 bumps in its arena, lateral error none / default / 3x / 5x: runs with an empty set 0.20 / 0.13 / 0.03 / 0.01;
    within 10 cm and 30° at bump 15 0.49 / 0.49 / 0.40 / 0.36, median position error there 10.2 / 10.4 / 14.4 /
    27.5 cm. Below the default the set empties more often and convergence gains nothing; above it the set never
    empties but the error grows."""
    empty = [lateral_scores[name]["failure_rates"]["empty_particle_set"] for name in LATERAL]
    assert empty == sorted(empty, reverse=True) and empty[0] >= 1.3 * empty[1] and empty[3] <= 0.25 * empty[1]
    converged = {name: s["converged_fraction"][-1] for name, s in lateral_scores.items()}
    assert converged["5x"] <= converged["default"] - 0.08 and converged["3x"] < converged["default"]
    assert converged["none"] <= converged["default"] + 0.05
    error = {name: s["position_error_cm"]["median"][-1] for name, s in lateral_scores.items()}
    assert error["5x"] >= 2.0 * error["default"] and error["3x"] > error["default"]


@pytest.mark.slow
def test_a_bumper_twice_too_wide_blurs_the_bump_space(sensitivity_logs, lateral_scores):
    """The paper: "very sensitive to [...] the size of the bumper" (no sizes given). The localizer's bumper of
    twice the cart's 3 inches (15.24 cm) widens the bump space: at bump 15 0.42 of the runs are within 10 cm and
    30° against 0.49 with the true bumper, and the median position error is 15.3 cm against 10.4 (1,000
    particles, 200 runs). Narrower bumpers change little (see docs/papers/bumper.md, "What it does not
    reproduce")."""
    wide = _mcl_summary(sensitivity_logs, bumper_width_cm=2 * C.CartModel().bumper_width_cm)
    true = lateral_scores["default"]
    assert wide["converged_fraction"][-1] <= true["converged_fraction"][-1] - 0.04
    assert wide["position_error_cm"]["median"][-1] >= 1.25 * true["position_error_cm"]["median"][-1]
