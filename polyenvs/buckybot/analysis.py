"""The paper's dead-reckoning experiments ("Simulation and Results"): the Monte Carlo and Figure 8's maps.

The paper reports, after 100 tips (about 929 cm), a position sd of 90.42 cm and a heading sd of 11.5°. With the
paper's own per-tip numbers (heading sd 0.44°) the heading sd after 100 tips is 0.44 sqrt(100) = 4.4° whatever
the path, and a straight-ish walk spreads about 35 cm; the paper's pair comes back only with about 1.15° per tip
(``geometry-checks.md`` A3). :func:`dead_reckoning_monte_carlo` reports what a model gives, it is not tuned.

Figure 8 replays the actuator sequence without noise to place the sensed obstacles and shows the result beside
the true positions. :func:`figure8_maps` runs the explorer baseline in BuckybotExplore-v0 and builds both
occupancy grids from what the environment publishes (the observation, the ``pose`` and ``dead_reckoned_pose``
parts of ``info["ground_truth"]``); :func:`render_figure8` draws them side by side. The policy is passed in (an
environment package imports no policy); the command that runs the paper's explorer is on top, in benchmarks::

    python -m benchmarks.buckybot_analysis figure8 --output docs/buckybot_figure8.png
"""

from __future__ import annotations

import struct
import sys
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from polyenvs.buckybot.env import ground_truth_parts
from polyenvs.buckybot.floor_plans import make_floor_plan
from polyenvs.buckybot.mapping import OccupancyGrid, placement_error
from polyenvs.buckybot.sensors import RANGE_MAX_CM, RANGE_QUANTUM_CM
from polyenvs.buckybot.simulator import BuckybotParams, BuckybotSimulator
from polyenvs.core.floor_plan import FloorPlan
from polyenvs.core.geometry2d import SegmentTable

__all__ = [
    "EXPLORE_ENV_ID",
    "Figure8Run",
    "MonteCarloResult",
    "PAPER_MONTE_CARLO",
    "dead_reckoning_monte_carlo",
    "decode_observation",
    "figure8_maps",
    "figure8_summary",
    "render_figure8",
    "wall_cells",
    "write_png",
]

#: The paper's reported spread after 100 steps: (position sd cm, heading sd deg).
PAPER_MONTE_CARLO = (90.42, 11.5)
EXPLORE_ENV_ID = "polyenvs/BuckybotExplore-v0"


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
    robot: BuckybotParams | None = None,
    seed: int = 0,
) -> MonteCarloResult:
    """Replay one actuator sequence ``n_runs`` times with tipping noise, in open space.

    Args:
        walk: ``"zigzag"``, the straight-ish armchair walk (alternating forward-right and forward-left tips,
            as a wall follower walks), or ``"random"`` (uniform among the two forward tips, never back).
        robot: the robot, whose tip model is used (default: the paper's measurements).
    """
    robot = robot or BuckybotParams()
    rng = np.random.default_rng(seed)
    if walk == "zigzag":
        actions = np.where(np.arange(n_tips) % 2 == 0, 1, 2)
    elif walk == "random":
        actions = rng.integers(1, 3, size=n_tips)
    else:
        raise ValueError(f"walk must be 'zigzag' or 'random', got {walk!r}")
    far = SegmentTable(np.array([[1e7, -1.0, 1e7, 1.0]]))  # a single wall far away: nothing is ever blocked
    sim = BuckybotSimulator(n_runs, robot)
    # Dead reckoning is the same actuator sequence replayed with the mean tip (the paper's "omitting noise").
    ideal = BuckybotSimulator(1, robot)
    for s in (sim, ideal):
        s.set_walls(far)
        s.place(slice(None), np.zeros(2), 0, 0.0)
    travelled = np.zeros(n_runs)
    for action in actions:
        before = sim.position.copy()
        sim.tip(np.full(n_runs, action), rng.standard_normal((n_runs, 3)))
        ideal.tip(np.array([action]), np.zeros((1, 3)))
        travelled += np.hypot(*(sim.position - before).T)
    spread = sim.position - sim.position.mean(axis=0)
    heading_error = (sim.heading - ideal.heading + np.pi) % (2 * np.pi) - np.pi
    return MonteCarloResult(
        position_sd_cm=float(np.sqrt((spread**2).sum(axis=1).mean())),
        heading_sd_deg=float(np.degrees(heading_error.std())),
        distance_travelled_cm=float(travelled.mean()),
        dead_reckoning_error_cm=float(np.sqrt(((sim.position - ideal.position) ** 2).sum(axis=1).mean())),
    )


# --- Figure 8 -----------------------------------------------------------------------------------------------------


def decode_observation(observation: np.ndarray, structure: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The six slant readings (cm, ``nan`` where invalid) and the too-close / no-return flags of an observation.

    ``structure`` is the environment's ``observation_structure`` (name -> (start, stop)).
    """
    obs = np.asarray(observation, dtype=np.float64)
    too_close = obs[slice(*structure["too_close"])] > 0.5
    no_return = obs[slice(*structure["no_return"])] > 0.5
    # The observation stores reading / 182.88 cm in float32; readings are whole inches, so round back onto them.
    reading = np.round(obs[slice(*structure["range"])] * RANGE_MAX_CM / RANGE_QUANTUM_CM) * RANGE_QUANTUM_CM
    reading[too_close | no_return] = np.nan
    return reading, too_close, no_return


@dataclass(frozen=True)
class Figure8Run:
    """One exploration run and the two maps built from it (the paper's Figure 8).

    Row k of the per-step arrays is what the robot had after k tips (row 0: after the reset).

    Attributes:
        plan: the floor plan explored.
        true_map: occupancy grid built from the true poses.
        dead_reckoned_map: the same readings placed from the dead-reckoned poses (same grid geometry).
        true_poses, dead_reckoned_poses: ``(N + 1, 3)`` ``(x_cm, y_cm, heading_rad)``; the heading is the world
            azimuth of the motion frame's direction 0.
        readings: ``(N + 1, 6)`` slant readings in cm, ``nan`` where invalid.
        too_close, no_return: ``(N + 1, 6)`` the two invalid cases.
        distance_cm: ``(N + 1,)`` true distance travelled so far.
    """

    plan: FloorPlan
    true_map: OccupancyGrid
    dead_reckoned_map: OccupancyGrid
    true_poses: np.ndarray
    dead_reckoned_poses: np.ndarray
    readings: np.ndarray
    too_close: np.ndarray
    no_return: np.ndarray
    distance_cm: np.ndarray

    def placement_gaps_cm(self) -> np.ndarray:
        """``(N + 1,)`` mean distance between each step's obstacle points placed from the dead-reckoned and from the
        true pose (``nan`` for a step with no valid reading): the map error as it accrues along the run."""
        out = np.full(len(self.readings), np.nan)
        for k, (t, d, r) in enumerate(zip(self.true_poses, self.dead_reckoned_poses, self.readings, strict=True)):
            total, count = placement_error(t, d, r)
            if count:
                out[k] = total / count
        return out

    def map_fit(self, grid: OccupancyGrid) -> tuple[float, float]:
        """How well ``grid`` matches the plan: the fractions of its occupied cells that a wall passes through, and
        that lie within one cell of such a cell (their 3 x 3 neighbourhood holds one)."""
        walls = wall_cells(grid, self.plan)
        near = np.zeros_like(walls)
        padded = np.pad(walls, 1)
        rows, cols = walls.shape
        for dr in range(3):
            for dc in range(3):
                near |= padded[dr : dr + rows, dc : dc + cols]
        occupied = grid.cells == OccupancyGrid.OCCUPIED
        if not occupied.any():
            return float("nan"), float("nan")
        return float(walls[occupied].mean()), float(near[occupied].mean())


def wall_cells(grid: OccupancyGrid, plan: FloorPlan) -> np.ndarray:
    """``grid.shape`` mask of the cells a wall of ``plan`` touches (closed squares: a wall along a cell boundary
    touches the cells on both sides)."""
    rows, cols = grid.shape
    c = grid.cell_cm
    low = [grid.origin[0] + np.arange(cols) * c, grid.origin[1] + np.arange(rows) * c]
    mask = np.zeros((rows, cols), dtype=bool)
    for segment in plan.segments:
        start, delta = segment[:2], segment[2:] - segment[:2]
        spans = []  # per axis, the segment's parameter range inside each row / column of cells
        for axis in (0, 1):
            if delta[axis] == 0.0:
                inside = (low[axis] <= start[axis]) & (start[axis] <= low[axis] + c)
                spans.append((np.where(inside, 0.0, np.inf), np.where(inside, 1.0, -np.inf)))
            else:
                ta, tb = (low[axis] - start[axis]) / delta[axis], (low[axis] + c - start[axis]) / delta[axis]
                spans.append((np.minimum(ta, tb), np.maximum(ta, tb)))
        enter = np.maximum(np.maximum(spans[1][0][:, None], spans[0][0][None, :]), 0.0)
        leave = np.minimum(np.minimum(spans[1][1][:, None], spans[0][1][None, :]), 1.0)
        mask |= enter <= leave
    return mask


def _poses(ground_truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The true and the dead-reckoned pose of one step's ``info["ground_truth"]``."""
    parts = ground_truth_parts(ground_truth)
    return parts["pose"], parts["dead_reckoned_pose"]


def figure8_maps(
    agent,
    *,
    seed: int = 0,
    floor_plan="office",
    max_steps: int = 1000,
    cell_cm: float = 10.0,
    noise_scale: float = 1.0,
    margin_cm: float = 150.0,
    **env_kwargs,
) -> Figure8Run:
    """Run one seeded exploration episode and build the true-pose and the dead-reckoned occupancy grids.

    Only the environment's public outputs are used: each step's observation (decoded with the environment's
    ``observation_structure``), the ``pose`` and ``dead_reckoned_pose`` parts of ``info["ground_truth"]``.

    Args:
        agent: the policy that explores (``predict`` as Stable-Baselines3's; the paper's is
            ``baselines.make_policy("paper", EXPLORE_ENV_ID, ...)``).
        seed: seeds the environment's reset (start pose, noise).
        floor_plan: a built-in plan name or a list of segments (not ``"random"``: the walls must be known).
        max_steps: stop after this many tips if the episode has not ended.
        cell_cm: grid cell size.
        noise_scale: tipping noise (1 = the paper's measurements); range noise is the paper's unless
            ``range_noise_scale`` is passed.
        margin_cm: grid extent beyond the plan's walls, so points placed from a drifted pose still land on it.
        env_kwargs: passed to ``gymnasium.make``.
    """
    import gymnasium as gym

    import polyenvs  # noqa: F401  (registers the environments)

    plan = make_floor_plan(floor_plan)
    if plan is None:
        raise ValueError("figure8_maps needs a fixed floor plan, not 'random'")
    env = gym.make(
        EXPLORE_ENV_ID, floor_plan=floor_plan, noise_scale=noise_scale, max_episode_steps=max_steps, **env_kwargs
    )
    structure = env.unwrapped.observation_structure
    obs, info = env.reset(seed=seed)
    records = [(obs, info["ground_truth"].copy())]  # the info's array is valid until the next step: kept, copied
    state, start = None, True
    while True:
        action, state = agent.predict(obs, state, episode_start=np.array([start]), deterministic=True)
        start = False
        obs, _, terminated, truncated, info = env.step(int(np.asarray(action).reshape(-1)[0]))
        records.append((obs, info["ground_truth"].copy()))
        if terminated or truncated or len(records) > max_steps:
            break
    env.close()

    decoded = [decode_observation(o, structure) for o, _ in records]
    readings, too_close, no_return = (np.array(column) for column in zip(*decoded, strict=True))
    true_poses, dr_poses = (
        np.array([[*pose[:2], np.radians(pose[2])] for pose in poses], dtype=np.float64)
        for poses in zip(*(_poses(truth) for _, truth in records), strict=True)
    )
    steps = np.hypot(*np.diff(true_poses[:, :2], axis=0).T)
    distance = np.concatenate([[0.0], np.cumsum(steps)])

    xmin, ymin, xmax, ymax = plan.bounds
    # Cells are centred on whole multiples of cell_cm: the built-in plans' walls lie on them, so a wall's cell is
    # one cell, not the two that would share it if walls ran along cell boundaries.
    origin = (np.floor((np.array([xmin, ymin]) - margin_cm) / cell_cm) - 0.5) * cell_cm
    shape = tuple(int(v) for v in np.ceil((np.array([ymax, xmax]) + margin_cm - origin[::-1]) / cell_cm) + 1)
    maps = []
    for poses in (true_poses, dr_poses):
        grid = OccupancyGrid(origin, shape, cell_cm)
        for pose, r, c, n in zip(poses, readings, too_close, no_return, strict=True):
            grid.observe(pose[:2], pose[2], r, c, n)
        maps.append(grid)
    return Figure8Run(plan, maps[0], maps[1], true_poses, dr_poses, readings, too_close, no_return, distance)


_UNKNOWN_RGB, _FREE_RGB, _OCCUPIED_RGB = (215, 215, 215), (255, 255, 255), (0, 0, 0)
_WALL_RGB, _TRUE_PATH_RGB, _DR_PATH_RGB = (0, 170, 0), (220, 30, 30), (30, 60, 220)


def _draw_grid(canvas, grid: OccupancyGrid, value: int, color) -> None:
    """Fill the cells equal to ``value``, one rectangle per horizontal run of them."""
    c = grid.cell_cm
    for row in range(grid.shape[0]):
        line = np.concatenate([[False], grid.cells[row] == value, [False]])
        edges = np.flatnonzero(line[1:] != line[:-1])
        y0 = grid.origin[1] + row * c
        for start, stop in zip(edges[::2], edges[1::2], strict=True):
            x0, x1 = grid.origin[0] + start * c, grid.origin[0] + stop * c
            canvas.polygon(np.array([[x0, y0], [x1, y0], [x1, y0 + c], [x0, y0 + c]]), color)


def render_figure8(run: Figure8Run, panel_width: int = 560, gap_px: int = 12) -> np.ndarray:
    """The two maps side by side as an ``(H, W, 3)`` uint8 image (left: true poses, right: dead reckoning).

    Grey = unknown, white = free, black = occupied cells; the plan's walls in green on top, the true path in red,
    the dead-reckoned path in blue (on the right only). Every 20 m along the run both paths carry a label with the
    distance travelled in metres, so the drift of the right-hand map can be read against it.
    """
    from polyenvs.core.raster import Canvas

    grid = run.true_map
    rows, cols = grid.shape
    lo = grid.origin
    bounds = (lo[0], lo[1], lo[0] + cols * grid.cell_cm, lo[1] + rows * grid.cell_cm)
    walls = run.plan.segments
    marks = np.flatnonzero(np.diff(np.floor(run.distance_cm / 2000.0)) > 0) + 1
    panels = []
    for which, occupancy in (("true", run.true_map), ("dead_reckoned", run.dead_reckoned_map)):
        canvas = Canvas(bounds, width=panel_width, margin=0.0, background=_UNKNOWN_RGB)
        _draw_grid(canvas, occupancy, OccupancyGrid.FREE, _FREE_RGB)
        _draw_grid(canvas, occupancy, OccupancyGrid.OCCUPIED, _OCCUPIED_RGB)
        canvas.lines(walls[:, :2], walls[:, 2:], _WALL_RGB, width_px=1.0)
        canvas.polyline(run.true_poses[:, :2], _TRUE_PATH_RGB, width_px=1.0)
        paths = [(run.true_poses, _TRUE_PATH_RGB)]
        if which == "dead_reckoned":
            canvas.polyline(run.dead_reckoned_poses[:, :2], _DR_PATH_RGB, width_px=1.0)
            paths.append((run.dead_reckoned_poses, _DR_PATH_RGB))
        for poses, color in paths:
            canvas.points(poses[:1, :2], color, radius_px=3.5)  # the start
            for k in marks:
                canvas.points(poses[k : k + 1, :2], color, radius_px=2.5)
                label_at = poses[k, :2] + np.array([0.0, 2.2 * grid.cell_cm])
                canvas.text(label_at, f"{run.distance_cm[k] / 100:.0f}", color, scale=2)
        panels.append(canvas.image)
    spacer = np.full((panels[0].shape[0], gap_px, 3), 255, dtype=np.uint8)
    return np.concatenate([panels[0], spacer, panels[1]], axis=1)


def write_png(path, image: np.ndarray) -> None:
    """Write an ``(H, W, 3)`` uint8 image as PNG: imageio when installed, else a minimal zlib encoder."""
    image = np.ascontiguousarray(image, dtype=np.uint8)
    try:
        import imageio.v3 as iio
    except ImportError:
        height, width, _ = image.shape
        raw = b"".join(b"\x00" + image[row].tobytes() for row in range(height))  # filter type 0 on every row

        def chunk(kind: bytes, data: bytes) -> bytes:
            return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

        header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)  # 8-bit RGB
        Path(path).write_bytes(
            b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
        )
    else:
        iio.imwrite(path, image, extension=".png")


def figure8_summary(run: Figure8Run) -> str:
    """What the two maps show, as lines of text (tips, distance, fit to the walls, placement error by distance)."""
    gaps = run.placement_gaps_cm()
    cell = run.true_map.cell_cm
    (own_true, near_true), (own_dr, near_dr) = run.map_fit(run.true_map), run.map_fit(run.dead_reckoned_map)
    lines = [
        f"{len(run.readings) - 1} tips, {run.distance_cm[-1] / 100:.1f} m travelled, {cell:g} cm cells",
        f"occupied cells on a wall's cell: true poses {own_true:.1%}, dead reckoning {own_dr:.1%}",
        f"occupied cells within one cell of a wall's cell: true poses {near_true:.1%}, dead reckoning {near_dr:.1%}",
        "mean obstacle-point placement error by distance travelled:",
    ]
    edges = np.linspace(0.0, run.distance_cm[-1], 6)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        sel = (run.distance_cm >= a) & (run.distance_cm <= b)
        lines.append(f"  {a / 100:5.1f}-{b / 100:5.1f} m: {np.nanmean(gaps[sel]):6.1f} cm")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit("moved: python -m benchmarks.buckybot_analysis (figure8 | monte-carlo), from the repository root")
