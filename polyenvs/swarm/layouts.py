"""Geometry the tasks share: boxes of walls, start blocks, the hexagonal lattice, seeded obstacle fields, and the
kinds of feature a swarm's layouts hold (:data:`LAYOUT_KINDS`, found by :func:`layout_kinds`)."""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core import libm
from polyenvs.core.geometry2d import SegmentTable, nearest_wall_points
from polyenvs.core.layouts import LayoutKind, check_layouts
from polyenvs.core.validation import check_int

__all__ = [
    "LAYOUT_KINDS",
    "LAYOUT_COUNTS",
    "TRAIN_WALL_MARGIN_M",
    "WALL_MARGIN_M",
    "ObstacleFieldEpisodes",
    "box_walls",
    "drawn_field",
    "episode_kinds",
    "hex_lattice",
    "lattice_pairs",
    "layout_kinds",
    "layout_obstacle_slots",
    "random_obstacles",
    "start_block",
]

#: The kinds of feature the swarm tasks' layouts hold (:func:`layout_kinds` finds them in an episode): what AP-lite's
#: obstacle avoidance is there to handle.
IN_THE_WAY = LayoutKind(
    "obstacle in the way", "an obstacle that a robot driving straight from the swarm's start centre to the goal hits"
)
BY_A_WALL = LayoutKind(
    "obstacle by a wall", "an obstacle less than a robot's width from a wall: the way past it is on one side only"
)
LAYOUT_KINDS = (IN_THE_WAY, BY_A_WALL)

#: How many obstacles a drawn field (``layouts="train"`` or ``"test"``) of the obstacle-field tasks holds (*ours*).
LAYOUT_COUNTS = (3, 7)
#: Obstacle centres keep this far (m) from the side walls in the default and held-out fields (*ours*).
WALL_MARGIN_M = 0.6
#: ... and this far in the training fields, so that an obstacle by a wall, which a robot cannot pass on the
#: wall's side and which the held-out fields' larger rocks make, is among what training draws (*ours*).
TRAIN_WALL_MARGIN_M = 0.4


def box_walls(xmin: float, ymin: float, xmax: float, ymax: float) -> np.ndarray:
    """The four walls of an axis-aligned rectangle, ``(4, 4)``."""
    return np.array(
        [[xmin, ymin, xmax, ymin], [xmax, ymin, xmax, ymax], [xmax, ymax, xmin, ymax], [xmin, ymax, xmin, ymin]]
    )


def start_block(n: int, columns: int, spacing: float) -> np.ndarray:
    """``n`` slots ``(n, 2)`` on a square grid of ``columns`` columns, in rows going away from the origin:
    column offsets ``0, spacing, ...`` along x and row offsets ``0, spacing, ...`` along y."""
    index = np.arange(n)
    return np.column_stack([(index % columns) * spacing, (index // columns) * spacing]).astype(np.float64)


def hex_lattice(n: int, spacing: float) -> np.ndarray:
    """The ``n`` points of a hexagonal lattice of side ``spacing`` nearest the origin ``(n, 2)``, the origin (the
    leader) first; for 7, a hexagon around the leader. Ties are broken by angle, so the result is fixed."""
    rings = math.ceil(math.sqrt(n)) + 1
    i, j = np.meshgrid(np.arange(-rings, rings + 1), np.arange(-rings, rings + 1), indexing="ij")
    points = np.column_stack([(i + 0.5 * j).ravel(), (j * math.sqrt(3) / 2).ravel()]) * spacing
    radius = np.round(np.hypot(points[:, 0], points[:, 1]) / spacing, 6)
    angle = np.round(np.mod(libm.arctan2(points[:, 1], points[:, 0]), 2 * np.pi), 6)
    order = np.lexsort((angle, radius))
    return points[order[:n]]


def lattice_pairs(points: np.ndarray, spacing: float) -> np.ndarray:
    """Index pairs ``(P, 2)`` of lattice points one ``spacing`` apart (the formation's neighbours)."""
    d = np.hypot(*(points[:, None, :] - points[None, :, :]).transpose(2, 0, 1))
    i, j = np.nonzero(np.triu(np.abs(d - spacing) < 1e-6 * spacing, 1))
    return np.column_stack([i, j]).astype(np.int64)


def random_obstacles(rng: np.random.Generator, count: int, region, radius_range, gap: float, keep_out) -> np.ndarray:
    """``count`` discs ``(count, 3)`` with centres uniform in ``region`` = (xmin, ymin, xmax, ymax) and radii
    uniform in ``radius_range``, at least ``gap`` apart (rim to rim) and clear of each ``keep_out`` disc
    (x, y, r) by ``gap``. Rejection sampling; a region too crowded for ``count`` discs places fewer."""
    xmin, ymin, xmax, ymax = region
    discs = [tuple(d) for d in keep_out]
    placed: list[tuple[float, float, float]] = []
    for _ in range(200 * max(count, 1)):
        if len(placed) == count:
            break
        x, y = xmin + (xmax - xmin) * rng.random(), ymin + (ymax - ymin) * rng.random()
        r = radius_range[0] + (radius_range[1] - radius_range[0]) * rng.random()
        if all(math.hypot(x - a, y - b) >= r + c + gap for a, b, c in discs + placed):
            placed.append((x, y, r))
    return np.array(placed, dtype=np.float64).reshape(-1, 3)


def drawn_field(rng: np.random.Generator, layouts: str) -> tuple[int, float]:
    """A drawn field's obstacle count (from ``rng``) and the margin its obstacles keep from the side walls."""
    count = int(rng.integers(LAYOUT_COUNTS[0], LAYOUT_COUNTS[1] + 1))
    return count, TRAIN_WALL_MARGIN_M if layouts == "train" else WALL_MARGIN_M


def layout_obstacle_slots(n_obstacles, layouts, default: int, most: int = LAYOUT_COUNTS[1]) -> int:
    """The obstacle slots of a field: ``n_obstacles`` (checked), or with ``layouts="train"`` or ``"test"``, which
    draw their own count, the most they draw (a ``n_obstacles`` other than ``default`` is refused, not ignored)."""
    n_obstacles = check_int("n_obstacles", n_obstacles, 0, 200)
    if check_layouts(layouts) == "default":
        return n_obstacles
    if n_obstacles != default:
        raise ValueError(
            f"layouts={layouts!r} draws its own obstacles: leave n_obstacles at its default ({default}), or use "
            f"layouts='default' with n_obstacles={n_obstacles}"
        )
    return most


def layout_kinds(walls, circles, starts, goal, robot_radius_m: float) -> frozenset[str]:
    """The names of the :data:`LAYOUT_KINDS` that an episode holds: its ``walls`` ``(W, 4)``, obstacle ``circles``
    ``(C, 3)`` (x, y, r), robots' ``starts`` ``(N, 2)`` and ``goal`` (m), for robots of ``robot_radius_m``."""
    circles = np.asarray(circles, dtype=np.float64).reshape(-1, 3)
    centre = np.asarray(starts, dtype=np.float64).reshape(-1, 2).mean(axis=0)
    way = SegmentTable(np.array([[*centre, *np.asarray(goal, dtype=np.float64)]]))
    kinds = set()
    if (nearest_wall_points(way, circles[None, :, :2])[0][0] < circles[:, 2] + robot_radius_m).any():
        kinds.add(IN_THE_WAY.name)
    rim_to_wall = nearest_wall_points(SegmentTable(walls), circles[None, :, :2])[0][0] - circles[:, 2]
    if (rim_to_wall < 2.0 * robot_radius_m).any():
        kinds.add(BY_A_WALL.name)
    return frozenset(kinds)


def episode_kinds(env) -> frozenset[str]:
    """:func:`layout_kinds` of a swarm task's episode at its reset (``env`` a swarm task, or the ``unwrapped`` of a
    single-robot id, which holds a swarm of one as ``swarm``)."""
    swarm = getattr(env, "swarm", env)
    return layout_kinds(swarm.layout.walls, swarm.circles, swarm.pose[:, :2], swarm.goal, swarm.platform.radius_m)


class ObstacleFieldEpisodes:
    """The episodes of a task that scatters obstacles over a field, mixed in before :class:`SwarmEnv`: the default
    field's ``n_obstacles`` obstacles of radii in :attr:`default_radius_m`, or a drawn field's count, radii (the
    task's split) and wall margin (:func:`drawn_field`). The task draws the field itself, in ``_field``."""

    #: The default field's obstacle radii (m), and the span of a drawn field's goal height (fractions of the width).
    default_radius_m: tuple[float, float]
    layout_goal_span: tuple[float, float]

    def sample_episode(self, rng: np.random.Generator):
        return self._field(rng, self.n_obstacles, None, self.default_radius_m)

    def sample_layout_episode(self, rng: np.random.Generator, layouts: str):
        count, margin = drawn_field(rng, layouts)
        radii = self.layout_split.parameters[0].interval(layouts)
        return self._field(rng, count, self.layout_goal_span, radii, margin)
