"""Occupancy mapping (the paper's Figure 8): beam geometry on analytic cases, the grid traversal against brute
force, and the two maps of an exploration run against the floor plan."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from benchmarks.buckybot_analysis import main, paper_explorer
from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot.analysis import Figure8Run, figure8_maps, render_figure8, wall_cells, write_png
from polyenvs.buckybot.mapping import (
    OccupancyGrid,
    known_bits,
    mark_beams,
    mark_beams_rotated,
    obstacle_points,
    placement_error,
)

# Beam geometry written out independently of the package: a sensor at the centre of an upper hexagon, 11.95 cm from
# the body centre along the face normal, which points asin(1/3) = 19.47° above the horizon.
_ELEVATION = math.asin(1.0 / 3.0)
_INRADIUS = 11.95
_REACH = 182.88  # the sensor's longest valid slant reading


def _beam(heading, i):
    """Horizontal unit direction of beam ``i`` and the horizontal part of its unit 3-D direction."""
    az = heading + geo.SENSOR_AZIMUTHS_RAD[i]
    u = np.array([math.cos(az), math.sin(az)])
    return u, math.cos(_ELEVATION) * u


# --- obstacle points and placement error ----------------------------------------------------------------------


def test_obstacle_points_land_on_the_wall_the_beam_meets():
    """A robot facing the wall x = 300 cm: the slant distance at which each beam's 3-D ray meets the wall, read as a
    reading, must be placed on the wall, at the height-independent point the ray crosses."""
    rng = np.random.default_rng(0)
    wall_x = 300.0
    for _ in range(200):
        position = np.array([rng.uniform(0, 200), rng.uniform(-100, 100)])
        heading = rng.uniform(0, 2 * np.pi)
        reading = np.full(6, np.nan)
        expected = np.full((6, 2), np.nan)
        for i in range(6):
            _, n = _beam(heading, i)
            if n[0] < 0.2:
                continue  # this beam does not face the wall
            sensor = position + _INRADIUS * n
            slant = (wall_x - sensor[0]) / n[0]
            reading[i] = slant
            expected[i] = sensor + slant * n
        points = obstacle_points(position, heading, reading)
        np.testing.assert_allclose(points, expected, atol=1e-9)  # nan rows stay nan
        assert np.allclose(points[~np.isnan(reading), 0], wall_x)


def test_placement_error_of_a_pure_heading_error_is_the_chord():
    """Same position, heading off by delta: every obstacle point swings about the centre by the chord
    2 r sin(delta / 2), r its horizontal distance (reading + 11.95 cm) cos 19.47°."""
    rng = np.random.default_rng(1)
    for _ in range(100):
        x, y, heading = rng.uniform(-500, 500), rng.uniform(-500, 500), rng.uniform(-np.pi, np.pi)
        delta = rng.uniform(-0.5, 0.5)
        reading = rng.uniform(30.48, 182.88, 6)
        reading[rng.random(6) < 0.3] = np.nan
        valid = ~np.isnan(reading)
        r = (reading[valid] + _INRADIUS) * math.cos(_ELEVATION)
        total, count = placement_error((x, y, heading), (x, y, heading + delta), reading)
        assert count == valid.sum()
        assert total == pytest.approx(np.sum(2 * r * abs(math.sin(delta / 2))), rel=1e-9, abs=1e-9)


def test_placement_error_of_a_pure_shift_and_of_a_general_pose_error():
    rng = np.random.default_rng(2)
    reading = np.array([40.0, np.nan, 100.0, 182.88, np.nan, 30.48])
    total, count = placement_error((10.0, 20.0, 1.0), (13.0, 16.0, 1.0), reading)
    assert (total, count) == (pytest.approx(4 * 5.0), 4)  # every point moves by the 3-4-5 shift
    for _ in range(100):
        true_pose = rng.uniform(-300, 300, 3)
        dr_pose = true_pose + rng.normal(0, [50, 50, 0.3])
        moved = obstacle_points(true_pose[:2], true_pose[2], reading) - obstacle_points(
            dr_pose[:2], dr_pose[2], reading
        )
        total, count = placement_error(true_pose, dr_pose, reading)
        assert count == 4
        assert total == pytest.approx(np.nansum(np.hypot(*moved.T)), rel=1e-9)


# --- the occupancy grid on analytic cases -----------------------------------------------------------------------


def _facing_plus_x(i):
    """Heading that points beam ``i`` exactly along +x."""
    return -geo.SENSOR_AZIMUTHS_RAD[i]


def test_observe_frees_up_to_half_a_cell_short_of_the_hit_and_marks_the_hit():
    """One beam along +x from a known pose (the others too close, so they mark nothing): the cells from the
    sensor's to the one holding the hit minus half a cell are freed, then the hit's cell is marked occupied (it may
    be the last one freed), and nothing else changes."""
    cell = 10.0
    grid = OccupancyGrid(origin=(0.0, 0.0), shape=(20, 40), cell_cm=cell)
    too_close = np.ones(6, dtype=bool)
    too_close[2] = False
    reading = np.full(6, np.nan)
    # The hit in the second half of its cell (which the free part then reaches), in the first half (which it must
    # not), at the shortest and at the longest valid reading.
    cases = ((52.0, 73.0, 121.92), (45.0, 73.0, 121.92), (5.5, 73.0, 33.02), (5.5, 73.0, 182.88))
    for x, y, slant in cases:
        grid.cells[:] = OccupancyGrid.UNKNOWN
        reading[2] = slant
        fresh = grid.observe((x, y), _facing_plus_x(2), reading, too_close, np.zeros(6, dtype=bool))
        sensor_x = x + _INRADIUS * math.cos(_ELEVATION)
        hit_x = sensor_x + slant * math.cos(_ELEVATION)  # the beam climbs: only the cosine is horizontal
        freed = range(int(sensor_x // cell), int((hit_x - cell / 2) // cell) + 1)
        expected = np.zeros((20, 40), dtype=np.int8)
        expected[7, freed] = OccupancyGrid.FREE
        expected[7, int(hit_x // cell)] = OccupancyGrid.OCCUPIED
        np.testing.assert_array_equal(grid.cells, expected)
        assert fresh == len(freed)
    # Counting only where asked; occupied cells are never freed again by a later beam through them.
    count_in = np.ones((20, 40), dtype=bool)
    count_in[7, freed[0]] = False
    grid.cells[:] = OccupancyGrid.UNKNOWN
    grid.cells[7, freed[2]] = OccupancyGrid.OCCUPIED
    fresh = grid.observe((x, y), _facing_plus_x(2), reading, too_close, np.zeros(6, dtype=bool), count_in)
    assert grid.cells[7, freed[2]] == OccupancyGrid.OCCUPIED
    assert fresh == len(freed) - 2


def test_no_return_frees_the_full_reach_and_too_close_marks_nothing():
    cell = 5.0
    grid = OccupancyGrid(origin=(0.0, 0.0), shape=(10, 80), cell_cm=cell)
    x, y = 3.0, 26.0
    no_return = np.zeros(6, dtype=bool)
    no_return[4] = True
    too_close = ~no_return
    grid.observe((x, y), _facing_plus_x(4), np.full(6, np.nan), too_close, no_return)
    sensor_x = x + _INRADIUS * math.cos(_ELEVATION)
    end_x = sensor_x + _REACH * math.cos(_ELEVATION)
    expected = np.zeros((10, 80), dtype=np.int8)
    expected[5, int(sensor_x // cell) : int(end_x // cell) + 1] = OccupancyGrid.FREE
    np.testing.assert_array_equal(grid.cells, expected)
    grid.cells[:] = 0
    assert grid.observe((x, y), 0.3, np.full(6, 50.0), np.ones(6, dtype=bool), np.zeros(6, dtype=bool)) == 0
    assert not grid.cells.any()


# --- the exact traversal against brute force --------------------------------------------------------------------


def _reference_mark(cells, origin, cell, x, y, heading, reading, too_close, no_return, count_in):
    """Brute force: clip every beam against every cell's square; a cell is crossed where a positive length of the
    free part lies in it."""
    rows, cols = cells.shape
    lo_x = origin[0] + np.arange(cols) * cell
    lo_y = origin[1] + np.arange(rows) * cell
    fresh = 0
    for i in range(6):
        if too_close[i]:
            continue
        u, _ = _beam(heading, i)
        sx, sy = np.array([x, y]) + _INRADIUS * math.cos(_ELEVATION) * u
        length = (_REACH if no_return[i] else reading[i]) * math.cos(_ELEVATION)
        free = length if no_return[i] else max(length - cell / 2, 0.0)
        with np.errstate(divide="ignore"):
            tx = np.sort(np.stack([(lo_x - sx) / u[0], (lo_x + cell - sx) / u[0]]), axis=0)
            ty = np.sort(np.stack([(lo_y - sy) / u[1], (lo_y + cell - sy) / u[1]]), axis=0)
        enter = np.maximum(np.maximum(ty[0][:, None], tx[0][None, :]), 0.0)
        leave = np.minimum(np.minimum(ty[1][:, None], tx[1][None, :]), free)
        crossed = (leave > enter) & (cells == 0)
        cells[crossed] = OccupancyGrid.FREE
        fresh += int((crossed & count_in).sum())
        if not no_return[i]:
            col = math.floor((sx + length * u[0] - origin[0]) / cell)
            row = math.floor((sy + length * u[1] - origin[1]) / cell)
            if 0 <= row < rows and 0 <= col < cols:
                cells[row, col] = OccupancyGrid.OCCUPIED
    return fresh


def test_grid_traversal_matches_brute_force_on_random_beams():
    """Random poses inside and around the grid (beams entering it from outside too), random readings and flags,
    one grid marked step after step: the same cells as the brute force, and the same count of newly freed ones."""
    rng = np.random.default_rng(3)
    cell, origin, shape = 7.5, np.array([-33.3, 12.7]), (30, 40)
    cells = np.zeros(shape, dtype=np.int8)
    reference = np.zeros(shape, dtype=np.int8)
    count_in = rng.random(shape) < 0.7
    span = np.array([shape[1], shape[0]]) * cell
    for _ in range(400):
        x, y = origin + rng.uniform(-0.5, 1.5, 2) * span
        heading = rng.uniform(-np.pi, np.pi)
        reading = rng.uniform(30.48, 182.88, 6)
        too_close = rng.random(6) < 0.15
        no_return = (rng.random(6) < 0.2) & ~too_close
        reading[too_close | no_return] = np.nan
        args = (heading, reading, too_close, no_return, count_in)
        fresh = mark_beams(
            cells, (origin[0], origin[1], cell), (x, y, heading), (reading, too_close, no_return), count_in
        )
        assert fresh == _reference_mark(reference, origin, cell, x, y, *args)
        np.testing.assert_array_equal(cells, reference)
    assert (cells == OccupancyGrid.FREE).mean() > 0.5 and (cells == OccupancyGrid.OCCUPIED).any()


def test_grid_traversal_never_writes_outside_the_grid():
    """Poses near, far and absurdly far outside, huge readings and non-finite poses: the grid (a window into a
    larger buffer) changes only as the brute force says, and the buffer around it is untouched."""
    rng = np.random.default_rng(5)
    rows, cols, cell = 12, 15, 10.0
    pad = 3 * cols
    buffer = np.full(rows * cols + 2 * pad, 7, dtype=np.int8)
    cells = buffer[pad : pad + rows * cols].reshape(rows, cols)
    cells[:] = 0
    reference = np.zeros((rows, cols), dtype=np.int8)
    everywhere = np.ones((rows, cols), dtype=bool)
    flags = np.zeros(6, dtype=bool)
    poses = [(rng.uniform(-200, 350), rng.uniform(-200, 320), rng.uniform(-4, 4)) for _ in range(300)]
    poses += [(s * 1e6, 60.0, 0.0) for s in (-1, 1)] + [(75.0, s * 1e300, 1.0) for s in (-1, 1)]
    for x, y, heading in poses:
        for reading in (rng.uniform(30.48, 182.88, 6), np.full(6, 1e300)):
            fresh = mark_beams(cells, (0.0, 0.0, cell), (x, y, heading), (reading, flags, flags), everywhere)
            assert fresh == _reference_mark(
                reference, (0.0, 0.0), cell, x, y, heading, reading, flags, flags, everywhere
            )
            np.testing.assert_array_equal(cells, reference)
    for x, y, heading in ((np.nan, 50.0, 0.0), (50.0, np.inf, 0.0), (50.0, 50.0, np.nan)):
        assert mark_beams(cells, (0.0, 0.0, cell), (x, y, heading), (np.full(6, 90.0), flags, flags), everywhere) == 0
    np.testing.assert_array_equal(cells, reference)
    assert (buffer[:pad] == 7).all() and (buffer[-pad:] == 7).all()


def test_bit_planes_that_skip_known_beams_change_nothing_even_on_degenerate_beams():
    """A map marked step after step with its kept bit planes (which skip the walk along beams over known cells)
    against the walk alone (planes cleared before every call, so it always walks): beams along the axes and the
    diagonals, from grid points and cell corners, grazing the grid's edges, on odd cell sizes. The same cells, the
    same counts, and the kept planes always those of the cells."""
    rng = np.random.default_rng(9)
    for cell, origin, shape in (
        (10.0, (0.0, 0.0), (24, 31)),
        (7.3, (-20.0, 3.1), (17, 70)),
        (2.0, (0.0, 0.0), (70, 9)),
    ):
        cells = np.zeros(shape, dtype=np.int8)
        walked = np.zeros(shape, dtype=np.int8)
        known_rows, known_cols = known_bits(cells)
        count_in = rng.random(shape) < 0.7
        span = np.array([shape[1], shape[0]]) * cell
        skipped = 0
        for _ in range(500):
            x, y = np.array(origin) + rng.uniform(-0.2, 1.2, 2) * span
            if rng.random() < 0.4:  # a grid point
                x, y = np.array(origin) + np.round((np.array([x, y]) - origin) / cell) * cell
            heading = -geo.SENSOR_AZIMUTHS_RAD[rng.integers(6)] + rng.integers(8) * np.pi / 4  # one beam on an axis
            if rng.random() < 0.3:
                heading = rng.uniform(-np.pi, np.pi)
            reading = rng.uniform(0.0, 200.0, 6)
            too_close = rng.random(6) < 0.1
            no_return = (rng.random(6) < 0.3) & ~too_close
            reading[too_close | no_return] = np.nan
            args = ((origin[0], origin[1], cell), (x, y, math.cos(heading), math.sin(heading)),
                    (reading, too_close, no_return), count_in)  # fmt: skip
            before = cells.copy()
            fresh = mark_beams_rotated((cells, known_rows, known_cols), *args)
            cleared = [np.zeros_like(plane) for plane in (known_rows, known_cols)]
            assert fresh == mark_beams_rotated((walked, *cleared), *args)
            np.testing.assert_array_equal(cells, walked)
            skipped += fresh == 0 and np.array_equal(before, cells)
            for kept, rebuilt in zip((known_rows, known_cols), known_bits(cells), strict=True):
                np.testing.assert_array_equal(kept, rebuilt)
        assert (cells != 0).mean() > 0.3 and skipped > 100  # the map filled up and known beams were skipped


# --- Figure 8: both maps from an exploration run ----------------------------------------------------------------


@pytest.fixture(scope="module")
def runs() -> list[Figure8Run]:
    """The explorer baseline in the office with the paper's noise, twelve seeds, 600 tips (up to 56 m) each."""
    return [
        figure8_maps(paper_explorer(), seed=seed, floor_plan="office", max_steps=600, noise_scale=1.0)
        for seed in range(12)
    ]


def test_the_runs_use_only_what_the_environment_publishes(runs):
    for run in runs:
        n = len(run.readings)
        assert 300 < n <= 601  # an episode may end early on reaching its coverage goal
        assert run.true_poses.shape == run.dead_reckoned_poses.shape == (n, 3)
        np.testing.assert_allclose(run.dead_reckoned_poses[0], run.true_poses[0])  # the robot knows its start
        steps = np.diff(run.distance_cm)
        assert np.all((steps == 0) | (np.abs(steps - 9.29) < 1.0))  # a tip (about 9.3 cm) or a blocked one
        valid = ~(run.too_close | run.no_return)
        assert np.array_equal(valid, ~np.isnan(run.readings))
        assert np.all((run.readings[valid] >= 30.48) & (run.readings[valid] <= 182.88))


def _sampled_wall_cells(grid, plan):
    """Cells holding a point of a wall, sampling every wall each 0.1 cm; points nudged by 1e-6 cm both ways so a
    wall end on a cell boundary counts for the cells on both sides."""
    points = []
    for x1, y1, x2, y2 in plan.segments:
        t = np.linspace(0.0, 1.0, int(np.hypot(x2 - x1, y2 - y1) / 0.1) + 2)[:, None]
        points.append(np.array([x1, y1]) + t * np.array([x2 - x1, y2 - y1]))
    points = np.concatenate(points)
    mask = np.zeros(grid.shape, dtype=bool)
    for nudge in ([0, 0], [1e-6, 0], [-1e-6, 0], [0, 1e-6], [0, -1e-6]):
        col, row = np.floor((points + nudge - grid.origin) / grid.cell_cm).astype(int).T
        mask[row, col] = True
    return mask


def _dilate(mask):
    padded = np.pad(mask, 1)
    rows, cols = mask.shape
    return np.any([padded[r : r + rows, c : c + cols] for r in range(3) for c in range(3)], axis=0)


def test_true_pose_map_matches_the_floor_plan_within_a_cell(runs):
    """From the true poses: every occupied cell is a wall's cell or next to one, and nine in ten are a wall's own
    cell (cells are centred on the office's walls); free cells reach at most one cell past the outer walls; wall
    cells the map calls free are rare (a beam grazing a wall crosses its cell before the hit)."""
    for run in runs:
        grid = run.true_map
        cell = grid.cell_cm
        walls = _sampled_wall_cells(grid, run.plan)
        np.testing.assert_array_equal(wall_cells(grid, run.plan), walls)
        occupied = grid.cells == OccupancyGrid.OCCUPIED
        free = grid.cells == OccupancyGrid.FREE
        assert occupied.sum() > 150
        assert _dilate(walls)[occupied].all()
        assert walls[occupied].mean() >= 0.9
        assert run.map_fit(grid) == (pytest.approx(walls[occupied].mean()), 1.0)
        x, y = grid.centres()[..., 0], grid.centres()[..., 1]
        xmin, ymin, xmax, ymax = run.plan.bounds
        # Cells at least one cell wholly outside the building. The cell next to an outer wall may be freed: a wall
        # about 175 cm off can read as "no return" through noise, and such a beam frees its full 172 cm reach.
        beyond = 1.5 * cell
        outside = (x < xmin - beyond) | (x > xmax + beyond) | (y < ymin - beyond) | (y > ymax + beyond)
        assert not (free & outside).any()
        assert (free & walls).sum() < 0.1 * (walls & (grid.cells != OccupancyGrid.UNKNOWN)).sum()
        inside = (x > xmin) & (x < xmax) & (y > ymin) & (y < ymax)
        interior = inside & ~_dilate(walls)
        assert free[interior].mean() > 0.5  # and the map has actually been made


def test_dead_reckoned_map_degrades_with_distance_travelled(runs):
    """The same readings placed from dead reckoning: the obstacle points drift further from where the true pose
    puts them the further the robot has travelled (a random walk, so judged over the seeds), and the map matches
    the plan far worse than the true one."""
    gaps = [run.placement_gaps_cm() for run in runs]
    assert all(g[0] == 0.0 or np.isnan(g[0]) for g in gaps)  # the robot knows where it starts
    thirds = np.array([[np.nanmean(part) for part in np.array_split(g, 3)] for g in gaps])
    first, middle, last = thirds.mean(axis=0)
    assert first < middle < last
    assert last > 2.5 * first
    assert (thirds[:, 2] > thirds[:, 0]).sum() >= len(runs) - 2
    near_wall = np.array([[run.map_fit(run.true_map)[1], run.map_fit(run.dead_reckoned_map)[1]] for run in runs])
    assert (near_wall[:, 1] < near_wall[:, 0] - 0.2).all()
    assert near_wall[:, 1].mean() < 0.7


def test_figure8_renders_both_maps_and_writes_a_png(runs, tmp_path, monkeypatch):
    run = runs[0]
    image = render_figure8(run, panel_width=300, gap_px=10)
    assert image.dtype == np.uint8 and image.shape[1] == 610
    left, right = image[:, :300], image[:, 310:]
    for panel in (left, right):
        assert (panel == 0).all(axis=-1).any() and (panel == 255).all(axis=-1).any()  # occupied and free cells
    assert not np.array_equal(left, right)
    iio = pytest.importorskip("imageio.v3")
    write_png(tmp_path / "with_imageio.png", image)
    np.testing.assert_array_equal(iio.imread(tmp_path / "with_imageio.png"), image)
    monkeypatch.setitem(sys.modules, "imageio.v3", None)  # the fallback encoder, as without imageio
    write_png(tmp_path / "fallback.png", image)
    monkeypatch.undo()
    np.testing.assert_array_equal(iio.imread(tmp_path / "fallback.png"), image)
    assert main(["figure8", "--output", str(tmp_path / "cli.png"), "--steps", "30"]) == 0
    assert iio.imread(tmp_path / "cli.png").shape[2] == 3
