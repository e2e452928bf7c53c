"""Buckybot floor plans: built-in rooms (including the paper's two failure cases), a seeded room generator, and the
held-out layouts.

All coordinates are centimetres. ``make_floor_plan`` accepts a built-in name, ``"random"`` (a new room drawn
from the environment's generator at every reset) or the user's own list of segments.

Held-out layouts (``layouts=`` of every Buckybot id, :data:`LAYOUT_SPLIT`): "train" draws random rooms 300-520 cm
wide; "test" draws, half the time each, one of the hand-drawn :data:`TEST_PLANS` (shapes the generator never makes:
slanted and 45° walls, a T, a U, a partition with a door, a pillared hall) or a random room 540-700 cm wide. Every
test plan is 540-700 cm wide too, so the room's width alone tells the two apart; no built-in plan (the defaults)
is a test plan.
"""

from __future__ import annotations

import numpy as np

from polyenvs.core.floor_plan import FloorPlan, polygon_walls, rectangle_walls
from polyenvs.core.layouts import LayoutSplit, SplitParameter

__all__ = [
    "BUILTIN_PLANS",
    "LAYOUT_SPLIT",
    "MAX_RANDOM_SEGMENTS",
    "RANDOM_ROOM_BOUNDS",
    "TEST_PLANS",
    "layout_plan",
    "make_floor_plan",
    "plan_width",
    "random_room",
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


def random_room(rng: np.random.Generator, widths: tuple[float, float] = RANDOM_ROOM_WIDTHS) -> FloorPlan:
    """A seeded random room ``widths`` cm wide: a rectangle with up to two corner notches (L or U shapes) and up to
    three pillars (the notches leave the outline's full width, so the plan is as wide as drawn)."""
    width, height = rng.uniform(*widths), rng.uniform(250, RANDOM_ROOM_BOUNDS[3])
    corners = [(0.0, 0.0), (width, 0.0), (width, height), (0.0, height)]
    # Cut rectangular notches out of some corners, walking the polygon counter-clockwise.
    outline = []
    for i, (cx, cy) in enumerate(corners):
        if rng.random() < 0.35:
            nx, ny = rng.uniform(0.2, 0.4) * width, rng.uniform(0.2, 0.4) * height
            sx = 1.0 if cx == 0 else -1.0
            sy = 1.0 if cy == 0 else -1.0
            # Corner i is entered along one axis and left along the other; the notch replaces it by three points.
            if i % 2 == 0:
                outline += [(cx, cy + sy * ny), (cx + sx * nx, cy + sy * ny), (cx + sx * nx, cy)]
            else:
                outline += [(cx + sx * nx, cy), (cx + sx * nx, cy + sy * ny), (cx, cy + sy * ny)]
        else:
            outline.append((cx, cy))
    walls = polygon_walls(*outline)
    for _ in range(rng.integers(0, 4)):
        size = rng.uniform(20, 60)
        px, py = rng.uniform(0.25, 0.75) * width, rng.uniform(0.25, 0.75) * height
        walls += rectangle_walls(px, py, px + size, py + size)
    return FloorPlan(np.round(walls, 1), name="random")


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
    varies="a random room (a rectangle 250-550 cm deep with up to four notched corners and up to three pillars)",
    held_out=f"half the test episodes use one of the hand-drawn plans {', '.join(TEST_PLANS)} instead",
)
_TEST_FLOOR_PLANS = tuple(FloorPlan(walls, name=name) for name, walls in TEST_PLANS.items())


def plan_width(plan: FloorPlan) -> float:
    """The plan's width (cm): the x extent of its walls, the parameter :data:`LAYOUT_SPLIT` splits on."""
    xmin, _, xmax, _ = plan.bounds
    return float(xmax - xmin)


def layout_plan(rng: np.random.Generator, layouts: str) -> FloorPlan:
    """A plan of the ``layouts`` ("train" or "test") distribution, drawn from ``rng``."""
    widths = LAYOUT_SPLIT.parameters[0].interval(layouts)
    if layouts == "test" and rng.random() < 0.5:
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
