"""Buckybot floor plans: built-in rooms (including the paper's two failure cases), a seeded room generator, and the
held-out layouts.

All coordinates are centimetres. ``make_floor_plan`` accepts a built-in name, ``"random"`` (a new room drawn
from the environment's generator at every reset) or the user's own list of segments.

Held-out layouts (``layouts=`` of every Buckybot id, :data:`LAYOUT_SPLIT`): "train" draws training rooms
(:func:`training_room`) 300-520 cm wide; "test" draws, half the time each, one of the hand-drawn :data:`TEST_PLANS`
(a T, an octagon, two rooms joined by a door, a U, a pillared hall, a trapezoid) or a random room
(:func:`random_room`) 540-700 cm wide. Every test plan is 540-700 cm wide too, so the room's width alone tells the two
apart; no built-in plan (the defaults) is a test plan. The test side holds no kind of feature that training lacks
(:data:`LAYOUT_KINDS`, found by :func:`plan_kinds`): a training room may be notched, cut at 45°, slanted, split by a
partition and hold pillars.
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.floor_plan import FloorPlan, polygon_walls, rectangle_walls
from polyenvs.core.layouts import (
    DIAGONAL_WALL,
    SLANTED_WALL,
    LayoutKind,
    LayoutSplit,
    SplitParameter,
    wall_direction_kinds,
)

__all__ = [
    "BUILTIN_PLANS",
    "LAYOUT_KINDS",
    "LAYOUT_SPLIT",
    "MAX_RANDOM_SEGMENTS",
    "PASSAGE_CM",
    "RANDOM_ROOM_BOUNDS",
    "TEST_PLANS",
    "episode_kinds",
    "layout_plan",
    "make_floor_plan",
    "plan_kinds",
    "plan_width",
    "random_room",
    "training_room",
]

#: Every random room lies inside this box (xmin, ymin, xmax, ymax), so frames and grids can be sized once.
RANDOM_ROOM_BOUNDS = (0.0, 0.0, 700.0, 550.0)
#: The most walls a random room has: 12 for an outline with four notched corners, 4 for each of 3 pillars.
MAX_RANDOM_SEGMENTS = 24


def _office() -> list:
    """An 800 x 600 cm office: a corridor along the south wall and three rooms, each with a 90 cm door."""
    walls = rectangle_walls(0, 0, 800, 600)
    door = 90
    # Corridor wall at y = 180 with a door into each room.
    for x0, x1 in ((0, 260), (260, 540), (540, 800)):
        mid = (x0 + x1) / 2
        walls += [(x0, 180, mid - door / 2, 180), (mid + door / 2, 180, x1, 180)]
    # Partitions between the rooms, each with a door near the north wall.
    for x in (260, 540):
        walls += [(x, 180, x, 450), (x, 450 + door, x, 600)]
    return walls


BUILTIN_PLANS: dict[str, list] = {
    # A plain 4 x 3 m room: the wall follower's home ground.
    "rectangle": rectangle_walls(0, 0, 400, 300),
    # An L-shaped room: three 90° corners and one reflex (270°) corner.
    "l_room": polygon_walls((0, 0), (500, 0), (500, 220), (260, 220), (260, 450), (0, 450)),
    # The paper's first failure case: a small square room, so the follower is always near a 90° corner.
    "corner": rectangle_walls(0, 0, 220, 220),
    # The paper's second failure case: a narrow hallway, 120 cm wide, so both walls sit near d* = 50 cm.
    "hallway": rectangle_walls(0, 0, 700, 120),
    "office": _office(),
}


#: Widths (cm) of the rooms ``floor_plan="random"`` draws.
RANDOM_ROOM_WIDTHS = (300.0, RANDOM_ROOM_BOUNDS[2])


def _unit(start: tuple[float, float], end: tuple[float, float]) -> tuple[float, float]:
    """The unit vector from ``start`` towards ``end``."""
    length = math.hypot(end[0] - start[0], end[1] - start[1])
    return (end[0] - start[0]) / length, (end[1] - start[1]) / length


def _cut_corner(corners: list, i: int, legs: tuple[float, float], notch: bool) -> list[tuple[float, float]]:
    """The points that replace corner ``i`` of the outline ``corners`` (counter-clockwise) when it is cut back by
    ``legs`` cm along the edge from the previous corner and along the edge to the next: a notch (three points, a
    reflex corner between two) or a straight cut (two points; at a right angle with equal legs, a 45° wall)."""
    (cx, cy), (back, ahead) = corners[i], legs
    bx, by = _unit(corners[i], corners[i - 1])
    ax, ay = _unit(corners[i], corners[(i + 1) % len(corners)])
    first, last = (cx + back * bx, cy + back * by), (cx + ahead * ax, cy + ahead * ay)
    return [first, (first[0] + ahead * ax, first[1] + ahead * ay), last] if notch else [first, last]


def random_room(rng: np.random.Generator, widths: tuple[float, float] = RANDOM_ROOM_WIDTHS) -> FloorPlan:
    """A seeded random room ``widths`` cm wide: a rectangle with up to two corner notches (L or U shapes) and up to
    three pillars (the notches leave the outline's full width, so the plan is as wide as drawn)."""
    width, height = rng.uniform(*widths), rng.uniform(250, RANDOM_ROOM_BOUNDS[3])
    corners = [(0.0, 0.0), (width, 0.0), (width, height), (0.0, height)]
    # Cut rectangular notches out of some corners, walking the polygon counter-clockwise.
    outline = []
    for i, corner in enumerate(corners):
        if rng.random() < 0.35:
            nx, ny = rng.uniform(0.2, 0.4) * width, rng.uniform(0.2, 0.4) * height
            # Corners 0 and 2 are entered along the y axis, 1 and 3 along the x axis.
            outline += _cut_corner(corners, i, (ny, nx) if i % 2 == 0 else (nx, ny), notch=True)
        else:
            outline.append(corner)
    walls = polygon_walls(*outline)
    for _ in range(rng.integers(0, 4)):
        size = rng.uniform(20, 60)
        px, py = rng.uniform(0.25, 0.75) * width, rng.uniform(0.25, 0.75) * height
        walls += rectangle_walls(px, py, px + size, py + size)
    return FloorPlan(np.round(walls, 1), name="random")


#: Training rooms (*ours*): the chances that a corner is notched and that it is cut straight (at 45° where the corner
#: is square), that the north wall slants (one end 15-30 % of the height lower), that a partition stands in the room.
TRAINING_NOTCH, TRAINING_CUT, TRAINING_SLANT, TRAINING_PARTITION = 0.25, 0.25, 0.4, 0.4
#: Every way round a training room's partition and pillars is at least this wide (cm; *ours*): more than twice the
#: robot's 26 cm, so every goal is reachable and both sides of a partition can be followed.
PASSAGE_CM = 60.0
#: Tries to place a partition or a pillar where it keeps :data:`PASSAGE_CM` from every other wall; after them it is
#: left out.
_PLACEMENT_TRIES = 20


def training_room(rng: np.random.Generator, widths: tuple[float, float]) -> FloorPlan:
    """A seeded training room ``widths`` cm wide and 250-550 cm deep: a rectangle whose north wall may slant, each
    corner notched, cut straight or left square, then maybe a partition and up to three pillars, each a
    :data:`PASSAGE_CM` passage from every other wall. The cuts leave the east and west walls standing, so the plan
    is as wide as drawn."""
    width, height = rng.uniform(*widths), rng.uniform(250, RANDOM_ROOM_BOUNDS[3])
    north = [height, height]  # the west and east ends of the north wall
    if rng.random() < TRAINING_SLANT:
        north[int(rng.random() < 0.5)] -= rng.uniform(0.15, 0.3) * height
    corners = [(0.0, 0.0), (width, 0.0), (width, north[1]), (0.0, north[0])]
    outline = polygon_walls(*(point for i in range(4) for point in _training_corner(rng, corners, i)))
    walls = outline + (_partition(rng, outline, width, north) if rng.random() < TRAINING_PARTITION else [])
    pillars = min(int(rng.integers(0, 4)), (MAX_RANDOM_SEGMENTS - len(walls)) // 4)
    return FloorPlan(np.round(walls + _pillars(rng, outline, walls, pillars), 1), name="training room")


def _training_corner(rng: np.random.Generator, corners: list, i: int) -> list[tuple[float, float]]:
    """Corner ``i`` of a training room: notched (legs 20-35 % of their edges), cut straight (equal legs, 15-30 % of
    the shorter edge) or left as it is. No cut reaches past 35 % of an edge, so two never meet."""
    edges = [math.dist(corners[i], corners[j]) for j in (i - 1, (i + 1) % len(corners))]
    draw = rng.random()
    if draw < TRAINING_NOTCH:
        legs = rng.uniform(0.2, 0.35) * edges[0], rng.uniform(0.2, 0.35) * edges[1]
        return _cut_corner(corners, i, legs, notch=True)
    if draw < TRAINING_NOTCH + TRAINING_CUT:
        leg = rng.uniform(0.15, 0.3) * min(edges)
        return _cut_corner(corners, i, (leg, leg), notch=False)
    return [corners[i]]


def _partition(rng: np.random.Generator, outline: list, width: float, north: list) -> list:
    """A partition: a wall at 38-62 % of the width (where no corner cut reaches), up from the south wall or standing
    free a passage above it, and ending a passage or more below the north wall; redrawn until it keeps
    :data:`PASSAGE_CM` from every wall it does not stand on (none after :data:`_PLACEMENT_TRIES`)."""
    for _ in range(_PLACEMENT_TRIES):
        x = rng.uniform(0.38, 0.62) * width
        bottom = 0.0 if rng.random() < 0.5 else rng.uniform(1.0, 1.5) * PASSAGE_CM
        top = north[0] + (north[1] - north[0]) * x / width - rng.uniform(1.2, 1.8) * PASSAGE_CM
        others = [w for w in outline if bottom > 0.0 or max(w[1], w[3]) > 0.0]  # all but the south wall it stands on
        if top - bottom >= PASSAGE_CM and _gap([(x, bottom, x, top)], others) >= PASSAGE_CM:
            return [(x, bottom, x, top)]
    return []


def _pillars(rng: np.random.Generator, outline: list, walls: list, count: int) -> list:
    """Up to ``count`` square pillars 20-60 cm wide inside ``outline``, each :data:`PASSAGE_CM` from ``walls`` and
    from the pillars before it (redrawn up to :data:`_PLACEMENT_TRIES` times, else left out)."""
    xmax, ymax = np.asarray(outline)[:, [0, 1]].max(axis=0)
    placed: list = []
    for _ in range(count):
        for _ in range(_PLACEMENT_TRIES):
            size = rng.uniform(20, 60)
            x, y = rng.uniform(PASSAGE_CM, xmax - PASSAGE_CM - size), rng.uniform(PASSAGE_CM, ymax - PASSAGE_CM - size)
            centre = np.array([[x + size / 2, y + size / 2]])
            # A centre this clear of every wall keeps every wall a passage from the pillar's sides and corners.
            needed = PASSAGE_CM + size / math.sqrt(2)
            if _inside(centre[0], outline) and _clearance(centre, walls + placed)[0] >= needed:
                placed += rectangle_walls(x, y, x + size, y + size)
                break
    return placed


def _clearance(points: np.ndarray, walls: list) -> np.ndarray:
    """``(P,)`` distance (cm) from each of ``points`` ``(P, 2)`` to the nearest of ``walls``. Plain numpy: for a
    room's few walls, packing them for the compiled kernels (:meth:`FloorPlan.clearance`) costs more than this."""
    seg = np.asarray(walls, dtype=np.float64)
    start, vector = seg[None, :, 0:2], seg[None, :, 2:4] - seg[None, :, 0:2]
    along = np.clip(((points[:, None, :] - start) * vector).sum(-1) / (vector**2).sum(-1), 0.0, 1.0)
    return np.hypot(*(start + along[..., None] * vector - points[:, None, :]).transpose(2, 0, 1)).min(axis=1)


def _gap(walls: list, others: list) -> float:
    """The least distance (cm) between two sets of walls that do not cross: it is reached at an end of one of them."""
    ends = np.asarray(walls, dtype=np.float64).reshape(-1, 2), np.asarray(others, dtype=np.float64).reshape(-1, 2)
    return float(min(_clearance(ends[0], others).min(), _clearance(ends[1], walls).min()))


def _inside(point: np.ndarray, polygon: list) -> bool:
    """Whether ``point`` lies inside the closed ``polygon`` (its walls): the ray from it to +x crosses an odd number."""
    seg = np.asarray(polygon, dtype=np.float64)
    straddles = (seg[:, 1] > point[1]) != (seg[:, 3] > point[1])
    rise = np.where(straddles, seg[:, 3] - seg[:, 1], 1.0)
    crossing_x = seg[:, 0] + (point[1] - seg[:, 1]) / rise * (seg[:, 2] - seg[:, 0])
    return bool((straddles & (point[0] < crossing_x)).sum() % 2)


#: The held-out plans (cm): shapes the room generator never makes, each 540-700 cm wide and inside
#: ``RANDOM_ROOM_BOUNDS`` with at most ``MAX_RANDOM_SEGMENTS`` walls (so frames and wall tables keep their size).
TEST_PLANS: dict[str, list] = {
    # A T: a 220 cm stem under a 640 x 240 cm bar (two reflex corners).
    "t_room": polygon_walls((200, 0), (420, 0), (420, 280), (640, 280), (640, 520), (0, 520), (0, 280), (200, 280)),
    # An octagon: 45° walls, which no built-in or random room has.
    "octagon": polygon_walls((160, 0), (460, 0), (620, 160), (620, 360), (460, 520), (160, 520), (0, 360), (0, 160)),
    # Two rooms joined by a 110 cm door in a free-standing partition (a wall with two sides to follow).
    "two_rooms": rectangle_walls(0, 0, 660, 420) + [(330, 0, 330, 150), (330, 260, 330, 420)],
    # A U: two 200 cm arms around a 200 x 260 cm notch.
    "u_room": polygon_walls((0, 0), (600, 0), (600, 480), (400, 480), (400, 220), (200, 220), (200, 480), (0, 480)),
    # A hall with four 30 cm pillars in two rows.
    "pillared_hall": rectangle_walls(0, 0, 680, 460)
    + [w for x, y in ((170, 150), (480, 150), (170, 280), (480, 280)) for w in rectangle_walls(x, y, x + 30, y + 30)],
    # A quadrilateral with two slanted walls (no right angle but one).
    "trapezoid": polygon_walls((0, 0), (660, 0), (580, 440), (0, 380)),
}
#: The split (:mod:`polyenvs.core.layouts`): the room's width, train 300-520 cm, test 540-700 cm.
LAYOUT_SPLIT = LayoutSplit(
    (SplitParameter("room width", "cm", train=(300.0, 520.0), test=(540.0, 700.0)),),
    varies="a training room (a rectangle 250-550 cm deep whose north wall may slant, its corners notched, cut or "
    "square, maybe a partition and up to three pillars)",
    held_out=f"half the test episodes use one of the hand-drawn plans {', '.join(TEST_PLANS)} instead, the others a "
    "rectangle with notched corners and pillars",
)
_TEST_FLOOR_PLANS = tuple(FloorPlan(walls, name=name) for name, walls in TEST_PLANS.items())

#: The kinds of feature Buckybot's layouts hold (:func:`plan_kinds` finds them in a plan). Each hand-drawn test plan
#: shows one; a training room draws every one.
NOTCH = LayoutKind("notch", "a reflex (270°) corner of the outline: an L, T or U shape, a notched corner")
PILLAR = LayoutKind("pillar", "a closed loop of walls inside the outline, which the robot can circle")
PARTITION = LayoutKind("partition", "a wall in no closed loop: it ends in the room, so it has two sides to follow")
LAYOUT_KINDS = (NOTCH, PILLAR, DIAGONAL_WALL, SLANTED_WALL, PARTITION)


def plan_kinds(plan: FloorPlan) -> frozenset[str]:
    """The names of the :data:`LAYOUT_KINDS` that ``plan``'s walls hold."""
    loops, loose = _wall_loops(plan.segments)
    kinds = wall_direction_kinds(plan.segments)
    if loose:
        kinds.add(PARTITION.name)
    if len(loops) > 1:
        kinds.add(PILLAR.name)
    if loops and _has_reflex_corner(max(loops, key=lambda loop: abs(_signed_area(loop)))):
        kinds.add(NOTCH.name)
    return frozenset(kinds)


def episode_kinds(env) -> frozenset[str]:
    """:func:`plan_kinds` of the plan of a Buckybot environment's (row 0's) episode."""
    return plan_kinds(env.plan)


def _wall_loops(segments: np.ndarray) -> tuple[list[np.ndarray], int]:
    """The closed loops that walls joined end to end form (each its corners in order, ``(n, 2)``), and how many
    walls are in none. A wall that ends on another wall's middle (a T) is joined to nothing there."""
    points, ends = np.unique(np.round(segments.reshape(-1, 2), 3), axis=0, return_inverse=True)
    ends = ends.reshape(-1, 2).tolist()
    walls_at: list[list[int]] = [[] for _ in points]
    for wall, (a, b) in enumerate(ends):
        walls_at[a].append(wall)
        walls_at[b].append(wall)
    loops, in_loop = [], np.zeros(len(ends), dtype=bool)
    for start in range(len(ends)):
        if in_loop[start]:
            continue
        # Walk on from the wall's second end while every corner joins exactly two walls: back at the start, a loop.
        walls, corners, corner = [start], [], ends[start][1]
        while len(walls_at[corner]) == 2:
            corners.append(corner)
            one, other = walls_at[corner]
            wall = other if one == walls[-1] else one
            if wall == start:
                loops.append(points[corners])
                in_loop[walls] = True
                break
            walls.append(wall)
            corner = ends[wall][1] if ends[wall][0] == corner else ends[wall][0]
    return loops, int((~in_loop).sum())


def _signed_area(corners: np.ndarray) -> float:
    """Positive for a counter-clockwise polygon (the shoelace formula)."""
    x, y = corners[:, 0], corners[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _has_reflex_corner(corners: np.ndarray) -> bool:
    """Whether the polygon turns against its own direction at a corner (an interior angle over 180°)."""
    incoming, outgoing = corners - np.roll(corners, 1, axis=0), np.roll(corners, -1, axis=0) - corners
    turn = incoming[:, 0] * outgoing[:, 1] - incoming[:, 1] * outgoing[:, 0]
    return bool((np.sign(_signed_area(corners)) * turn < -1e-6).any())


def plan_width(plan: FloorPlan) -> float:
    """The plan's width (cm): the x extent of its walls, the parameter :data:`LAYOUT_SPLIT` splits on."""
    xmin, _, xmax, _ = plan.bounds
    return float(xmax - xmin)


def layout_plan(rng: np.random.Generator, layouts: str) -> FloorPlan:
    """A plan of the ``layouts`` ("train" or "test") distribution, drawn from ``rng``."""
    widths = LAYOUT_SPLIT.parameters[0].interval(layouts)
    if layouts == "train":
        return training_room(rng, widths)
    if rng.random() < 0.5:
        return _TEST_FLOOR_PLANS[int(rng.random() * len(_TEST_FLOOR_PLANS))]
    return random_room(rng, widths)


def make_floor_plan(floor_plan) -> FloorPlan | None:
    """A ``FloorPlan`` from a built-in name or a segment list; ``None`` for ``"random"`` (drawn at each reset)."""
    if isinstance(floor_plan, FloorPlan):
        return floor_plan
    if isinstance(floor_plan, str):
        if floor_plan == "random":
            return None
        if floor_plan not in BUILTIN_PLANS:
            raise ValueError(
                f"floor_plan must be one of {sorted([*BUILTIN_PLANS, 'random'])} or a list of segments, got {floor_plan!r}"
            )
        return FloorPlan(BUILTIN_PLANS[floor_plan], name=floor_plan)
    return FloorPlan(floor_plan, name="custom")
