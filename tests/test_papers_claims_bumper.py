"""The bump-only cart paper's remaining claims (``seeds/001``): the heavy-tailed slip at bumps, and the bump-space
localizer's split into symmetric clusters and its reconvergence."""

from __future__ import annotations

import math

import numpy as np

from polyenvs.bumper import cart as C
from polyenvs.bumper.env import BumperCartExploreEnv
from polyenvs.bumper.localizers import BumpSpaceMCL
from polyenvs.bumper.maps import make_map


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


def _share_near(particles, pose, cm=12.0, deg=25.0) -> float:
    close = np.hypot(particles[:, 0] - pose[0], particles[:, 1] - pose[1]) < cm
    turned = np.abs((particles[:, 2] - pose[2] + math.pi) % (2 * math.pi) - math.pi)
    return float((close & (turned < math.radians(deg))).mean())


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
