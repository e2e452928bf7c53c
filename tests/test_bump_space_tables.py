"""The bump-space localizer's tables (issue 33): their answers are the exact geometry's, so the filter's estimates
are the same bit for bit with and without them; they stay small and bounded.

The reference geometry here is written apart from the kernels: distances to the polygons' edges and an even-odd
crossing count, in NumPy over every edge at once.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from polyenvs.bumper.bump_space import densest_cluster
from polyenvs.bumper.bump_tables import (
    AXLE_BITS,
    AXLE_FREE,
    AXLE_IN_WALL,
    CLEAR,
    IN_WALL,
    MAX_CELLS,
    NEAR,
    POINT_BITS,
    UNKNOWN,
    BumpSpaceTable,
    cell_code,
)
from polyenvs.bumper.env import BumperCartExploreEnv
from polyenvs.bumper.maps import MAX_EXTENT_CM, make_map, random_room_map
from polyenvs.estimators.bumper import BumpSpaceMCL

TOLERANCE_CM = 1.5
MARGIN_CM = 10.0


def _reference_clearance(points: np.ndarray, polygons) -> np.ndarray:
    """Signed distance from each ``(n, 2)`` point to the nearest edge, positive inside the outline and outside
    every obstacle."""
    edges = np.concatenate([np.concatenate([p, np.roll(p, -1, axis=0)], axis=1) for p in polygons])
    a, b = edges[None, :, :2], edges[None, :, 2:]
    p = points[:, None, :]
    t = np.clip(((p - a) * (b - a)).sum(-1) / ((b - a) ** 2).sum(-1), 0.0, 1.0)
    distance = np.linalg.norm(p - (a + t[..., None] * (b - a)), axis=-1).min(axis=1)
    crossings = np.zeros(len(points), dtype=np.int64)
    for polygon in polygons:
        (x0, y0), (x1, y1) = polygon.T, np.roll(polygon, -1, axis=0).T
        px, py = points[:, :1], points[:, 1:]
        straddles = (y0 > py) != (y1 > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cross = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
        crossings += (straddles & (px < x_cross)).sum(axis=1)
    return np.where(crossings % 2 == 1, distance, -distance)


def _maps():
    rng = np.random.default_rng(5)
    return [make_map(name) for name in ("paper", "obstacles", "maze", "l_room")] + [
        random_room_map(rng, (150.0, 200.0)) for _ in range(2)
    ]


def _points_near_walls(world, rng, n):
    """Points spread over the map and its margin, half of them within a few cm of a wall."""
    x0, y0, x1, y1 = world.bounds
    spread = rng.uniform((x0 - MARGIN_CM, y0 - MARGIN_CM), (x1 + MARGIN_CM, y1 + MARGIN_CM), (n // 2, 2))
    segments = world.segments[rng.integers(0, len(world.segments), n - n // 2)]
    along = rng.random((n - n // 2, 1))
    near = segments[:, :2] + along * (segments[:, 2:] - segments[:, :2]) + rng.normal(0.0, 2.0, (n - n // 2, 2))
    return np.concatenate([spread, near])


def _check_answers(codes, grid, world, seed=1):
    """The table's certain answers at points over ``world`` are the reference geometry's; returns the fractions of
    points whose bumper-point class and axle answer the table knows."""
    points = _points_near_walls(world, np.random.default_rng(seed), 40_000)
    truth = _reference_clearance(points, world.polygons)
    # The thresholds themselves are a set of measure zero: keep the draws off them by more than rounding.
    off = np.min(np.abs(truth[:, None] - [-TOLERANCE_CM, 0.0, TOLERANCE_CM]), axis=1) > 1e-9
    points, truth = points[off], truth[off]
    found = np.array([cell_code(x, y, codes, grid) for x, y in points])
    kind, axle = found & POINT_BITS, found & AXLE_BITS
    expected_kind = np.where(truth < -TOLERANCE_CM, IN_WALL, np.where(truth <= TOLERANCE_CM, NEAR, CLEAR))
    known, known_axle = kind != UNKNOWN, axle != UNKNOWN
    np.testing.assert_array_equal(kind[known], expected_kind[known])
    np.testing.assert_array_equal(axle[known_axle], np.where(truth > 0, AXLE_FREE, AXLE_IN_WALL)[known_axle])
    return known.mean(), known_axle.mean()


@pytest.mark.parametrize("world", _maps(), ids=lambda w: w.name)
def test_every_certain_answer_is_the_exact_geometrys(world):
    table = BumpSpaceTable(world.bounds, TOLERANCE_CM, MARGIN_CM)
    table.install(0, world.walls)
    # And the table answers most of them: only a band about each threshold is left to the exact test.
    assert min(_check_answers(table.codes[0], table.grid, world)) > 0.8


def test_a_point_off_the_grid_is_left_to_the_exact_test():
    world = make_map("paper")
    table = BumpSpaceTable(world.bounds, TOLERANCE_CM, MARGIN_CM)
    table.install(0, world.walls)
    for x, y in ((-MARGIN_CM - 1.0, 10.0), (10.0, 200.0), (math.nan, 10.0)):
        assert cell_code(x, y, table.codes[0], table.grid) == UNKNOWN


def _estimates(world, particles, tables: bool, seed: int = 0, cycles: int = 25):
    """Every estimate, survivor count and particle of BumpSpaceMCL on seeded logs in ``world``, with the map's
    table or with an all-unknown one (every answer from the exact geometry)."""
    env = BumperCartExploreEnv(map=world)
    mcl = BumpSpaceMCL(particles=particles)
    context = env.localization_context()
    out = []
    for run in range(3):
        env.reset(seed=seed + run)
        mcl.reset(context, None, np.random.default_rng(seed + run))
        if not tables:
            mcl.table.codes[:] = UNKNOWN
        turns = np.random.default_rng(100 + run).uniform(-1, 1, (cycles, 1)).astype(np.float32)
        for turn in turns:
            estimate = mcl.update(env.step(turn)[0])
            out.append(np.concatenate([estimate, [mcl.survivors, mcl.empty_sets], mcl.particles.ravel()]))
    mcl._tabled = None  # the zeroed table is not the map's: build it afresh next time
    return np.array(out)


@pytest.mark.parametrize("name", ["paper", "obstacles", "maze"])
def test_the_estimates_are_the_exact_tests_bit_for_bit(name):
    world = make_map(name)
    with_tables, exact = _estimates(world, 500, True), _estimates(world, 500, False)
    np.testing.assert_array_equal(with_tables, exact)


def test_the_localize_task_tabulates_each_rows_own_room():
    import gymnasium as gym

    env = gym.make_vec("polyenvs/BumperCartLocalize-v0", num_envs=2, layouts="test", particles=300)
    rows = env._core  # the batched environment under the vector env
    for seed in range(2):
        env.reset(seed=seed)
        for row in range(2):
            known = _check_answers(rows._tables.codes[row], rows._tables.grid, rows._slot_worlds[row], seed)
            assert min(known) > 0.5


def test_tables_are_bounded_in_memory():
    paper = make_map("paper")
    table = BumpSpaceTable(paper.bounds, TOLERANCE_CM, MARGIN_CM)
    assert table.cell_cm == 0.25 and table.codes.nbytes < 300_000
    largest = BumpSpaceTable((0.0, 0.0, MAX_EXTENT_CM, MAX_EXTENT_CM), TOLERANCE_CM, MARGIN_CM)
    assert largest.codes.nbytes <= MAX_CELLS * 1.01 and largest.cell_cm < 1.0 + 1e-9


def test_the_filters_kernels_read_the_table_not_only_the_geometry():
    """A table saying 'in a wall' everywhere rejects every particle: the kernels do consult it."""
    world = make_map("paper")
    mcl = BumpSpaceMCL(particles=200)
    env = BumperCartExploreEnv(map=world)
    env.reset(seed=0)
    mcl.reset(env.localization_context(), None, np.random.default_rng(0))
    mcl.table.codes[:] = IN_WALL | AXLE_FREE
    mcl.update(env.step(np.zeros(1, dtype=np.float32))[0])
    assert mcl.survivors == 0 and mcl.empty_sets == 1


def test_the_heading_wrap_is_pythons_modulo_bit_for_bit():
    """The filter wraps headings without numba's fmod call where it can: every value, zeros and NaN included,
    comes out as ``v % (2π)`` does."""
    from polyenvs.bumper.bump_space import _turn_modulo

    turn = 2.0 * math.pi
    edges = [0.0, -0.0, turn, -turn, 2 * turn, -2 * turn, np.nextafter(turn, 0), np.nextafter(-turn, 0), 5e-324]
    values = np.concatenate([np.random.default_rng(3).uniform(-3 * turn, 5 * turn, 20_000), edges, [math.nan]])
    wrapped = np.array([_turn_modulo(v) for v in values])
    expected = np.array([v % turn for v in values])
    np.testing.assert_array_equal(wrapped.view(np.int64)[:-1], expected.view(np.int64)[:-1])
    assert math.isnan(wrapped[-1])


def _reference_update(particles, noise, ticks, bump, mcl, world):
    """One update of the paper's filter in plain Python, apart from the kernels: move by the turn and the drive,
    keep the bump-space particles (the reference geometry), duplicate them evenly, move by the back-up. Returns
    ``(survivors, the duplicated survivors, particles)``."""
    tick, base, front, half, tol = (float(v) for v in mcl.params[:5])
    (h0, h1), (f0, f1), (l0, l1) = mcl.heading, mcl.forward, mcl.lateral
    h0 = math.radians(h0)

    def move(pose, stage):
        a, b = ticks[stage, 0] * tick, ticks[stage, 1] * tick
        theta = (b - a) / base
        half_turn = 0.5 * theta
        chord = (
            0.5
            * (a + b)
            * (1.0 - half_turn * half_turn / 6.0 if abs(half_turn) < 1e-4 else math.sin(half_turn) / half_turn)
        )
        nx, ny, nh = chord * math.cos(half_turn), chord * math.sin(half_turn), theta
        dist = math.hypot(nx, ny)
        (x, y, h), z = pose, noise[pose_index[0], stage].astype(np.float64)  # exact: float32 in float64
        forward, lateral = z[0] * (f0 + f1 * dist), z[1] * (l0 + l1 * dist)
        heading = z[2] * (h0 + h1 * abs(theta))
        ch, sh, c, s = math.cos(0.5 * nh), math.sin(0.5 * nh), math.cos(h), math.sin(h)
        gx, gy = nx + forward * ch - lateral * sh, ny + forward * sh + lateral * ch
        return x + gx * c - gy * s, y + gx * s + gy * c, (h + nh + heading + math.pi) % (2.0 * math.pi) - math.pi

    pose_index = [0]
    moved = []
    for i, pose in enumerate(particles):
        pose_index[0] = i
        moved.append(move(move(tuple(pose), 0), 1))
    points = np.array([
        (x + front * math.cos(h) - ly * math.sin(h), y + front * math.sin(h) + ly * math.cos(h))
        for x, y, h in moved
        for ly in (-half, 0.0, half)
    ])  # fmt: skip
    clearance = _reference_clearance(points, world.polygons).reshape(-1, 3)
    axle_free = _reference_clearance(np.array(moved)[:, :2], world.polygons) > 0
    touching = (clearance <= tol).any(axis=1) if bump else True
    kept = [moved[i] for i in np.flatnonzero(axle_free & (clearance >= -tol).all(axis=1) & touching)]
    refilled = np.array([kept[i % len(kept)] for i in range(len(particles))])
    out = []
    for i in range(len(particles)):
        pose_index[0] = i
        out.append(move(kept[i % len(kept)], 2))
    return len(kept), refilled, np.array(out)


def test_an_update_is_the_papers_filter_written_out_in_python():
    world = make_map("obstacles")
    env = BumperCartExploreEnv(map=world)
    mcl = BumpSpaceMCL(particles=150)
    context = env.localization_context()
    env.reset(seed=4)
    mcl.reset(context, None, np.random.default_rng(4))
    turns = np.random.default_rng(5).uniform(-1, 1, (12, 1)).astype(np.float32)
    for turn in turns:
        log = env.step(turn)[0]
        before, state = mcl.particles.copy(), mcl.rng.bit_generator.state
        mcl.update(log)
        if mcl.survivors == 0:
            continue
        noise = np.random.default_rng().standard_normal((150, 3, 3), dtype=np.float32)
        rng = np.random.default_rng()
        rng.bit_generator.state = state
        rng.standard_normal(dtype=np.float32, out=noise)
        ticks = np.asarray(log)[mcl._tick_index].astype(np.float64)
        kept, refilled, expected = _reference_update(before, noise, ticks, log[mcl._bump_index] > 0.5, mcl, world)
        assert mcl.survivors == kept
        np.testing.assert_array_equal(mcl.particles, expected)
        estimate = np.zeros(3)  # the densest cluster of the duplicated survivors, before the back-up
        densest_cluster(refilled, 150, mcl.params, np.zeros_like(mcl.counts), estimate)
        np.testing.assert_array_equal(mcl.estimate, estimate)
