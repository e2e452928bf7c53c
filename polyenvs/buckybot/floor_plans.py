"""Buckybot floor plans: built-in rooms (including the paper's two failure cases) and a seeded room generator.

All coordinates are centimetres. ``make_floor_plan`` accepts a built-in name, ``"random"`` (a new room drawn
from the environment's generator at every reset) or the user's own list of segments.
"""

from __future__ import annotations

import numpy as np

from polyenvs.core.floor_plan import FloorPlan, polygon_walls, rectangle_walls

__all__ = ["BUILTIN_PLANS", "MAX_RANDOM_SEGMENTS", "RANDOM_ROOM_BOUNDS", "make_floor_plan", "random_room"]

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


def random_room(rng: np.random.Generator) -> FloorPlan:
    """A seeded random room: a rectangle with up to two corner notches (L or U shapes) and up to three pillars."""
    width, height = rng.uniform(300, RANDOM_ROOM_BOUNDS[2]), rng.uniform(250, RANDOM_ROOM_BOUNDS[3])
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
