"""The bumper cart never enters a wall nor leaves its map (issue 14, defect 1), checked after every stage.

The drive stage's closed-form contact search kept only a crossing that left the side of a wall's line the moving
point started on: a body corner that first passed the line beyond the segment's end (through the free space
around a wall corner that juts into the room) and then crossed the segment itself was not stopped. The cart
ended its drive inside a box on ``obstacles`` and left ``l_room`` altogether.

The geometry here is written apart from the simulator (plain numpy, nothing from ``polyenvs.bumper.maps`` or
``cart`` but the state's column numbers): the body is the rectangle from ``rear_cm`` behind the axle to
``bumper_offset_cm`` ahead of it, ``max(bumper_width_cm, wheel_base_cm + 1.4)`` wide (the tyres: the cart refuses
a bumper narrower than that, so it is the bumper's width). Shrunk by ``TOL_CM`` on every side it must share no
point with a wall: its corners in free space, no wall vertex inside it, no edge of it crossing a wall. Checked
poses: after the turn, at the bump (the drive's end), after the bump's slip and after the back-up.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the ids)
from polyenvs.bumper import cart as C
from polyenvs.bumper.maps import MAPS

ENV_ID = "polyenvs/BumperCartExplore-v0"
#: How far (cm) the body may reach into a wall: rounding, not physics.
TOL_CM = 1e-6
#: The tyres' width added to the wheel base for the cart's width (the spec's 6.0 cm base, 7.4 cm wide).
TYRES_CM = 1.4
#: State columns of the pose after each stage: turn, drive (at the bump), the bump's slip, back-up.
STAGES = {
    "turn": [C.TURN_X, C.TURN_Y, C.TURN_HEADING],
    "drive": [C.BUMP_X, C.BUMP_Y, C.BUMP_HEADING],
    "slip": [C.SLIP_X, C.SLIP_Y, C.SLIP_HEADING],
    "back-up": [C.X, C.Y, C.HEADING],
}


# --- independent geometry -------------------------------------------------------------------------------------


def _polygons(env) -> list[np.ndarray]:
    return [np.asarray(p, dtype=np.float64) for p in env.world.polygons]


def _corners(poses: np.ndarray, kwargs: dict) -> np.ndarray:
    """``(P, 4, 2)`` corners of the body at ``(P, 3)`` poses (x, y, heading rad), shrunk by ``TOL_CM``, in order
    round the rectangle."""
    defaults = {"wheel_base_cm": 6.0, "bumper_width_cm": 3.0 * 2.54, "bumper_offset_cm": 7.0, "rear_cm": 5.0}
    g = {**defaults, **{k: v for k, v in kwargs.items() if k in defaults}}
    half = 0.5 * max(g["bumper_width_cm"], g["wheel_base_cm"] + TYRES_CM) - TOL_CM
    front, rear = g["bumper_offset_cm"] - TOL_CM, g["rear_cm"] - TOL_CM
    local = np.array([[front, -half], [front, half], [-rear, half], [-rear, -half]])
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    x = poses[:, 0, None] + local[:, 0] * c - local[:, 1] * s
    y = poses[:, 1, None] + local[:, 0] * s + local[:, 1] * c
    return np.stack([x, y], axis=-1)


def _inside(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Whether each ``(..., 2)`` point is strictly inside ``polygon`` (even-odd rule on a ray to +x)."""
    px, py = points[..., 0, None], points[..., 1, None]
    ax, ay = polygon[:, 0], polygon[:, 1]
    bx, by = np.roll(ax, -1), np.roll(ay, -1)
    straddles = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = ax + (py - ay) / (by - ay) * (bx - ax)
    return (straddles & (px < x_cross)).sum(axis=-1) % 2 == 1


def _in_map(points: np.ndarray, polygons: list[np.ndarray]) -> np.ndarray:
    """Inside the outline (the first polygon) and outside every obstacle."""
    free = _inside(points, polygons[0])
    for obstacle in polygons[1:]:
        free &= ~_inside(points, obstacle)
    return free


def _cross(o, a, b):
    return (a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1]) - (a[..., 1] - o[..., 1]) * (b[..., 0] - o[..., 0])


def _overlaps(poses: np.ndarray, kwargs: dict, polygons: list[np.ndarray]) -> np.ndarray:
    """``(P,)``: whether the shrunk body at each pose shares a point with a wall."""
    body = _corners(poses, kwargs)  # (P, 4, 2), counter-clockwise
    bad = ~_in_map(body, polygons).all(axis=1)
    body_a, body_b = body[:, :, None, :], np.roll(body, -1, axis=1)[:, :, None, :]  # (P, 4, 1, 2)
    for polygon in polygons:
        wall_a, wall_b = polygon[None, None], np.roll(polygon, -1, axis=0)[None, None]  # (1, 1, V, 2)
        # A wall vertex strictly inside the convex body: on the inner side of its four edges.
        bad |= (_cross(body_a, body_b, wall_a) > 0).all(axis=1).any(axis=-1)
        # A body edge crossing a wall edge (each one's ends strictly on both sides of the other).
        d1, d2 = _cross(body_a, body_b, wall_a), _cross(body_a, body_b, wall_b)
        d3, d4 = _cross(wall_a, wall_b, body_a), _cross(wall_a, wall_b, body_b)
        bad |= ((d1 * d2 < 0) & (d3 * d4 < 0)).any(axis=(1, 2))
    return bad


def _state_poses(state: np.ndarray) -> dict[str, np.ndarray]:
    """Each stage's pose of every row, ``(rows, 3)``."""
    return {name: state[:, columns] for name, columns in STAGES.items()}


def _describe(env, kwargs, step, stage, pose) -> str:
    corners = _corners(pose[None], kwargs)[0]
    return (
        f"map {env.world.name!r} {kwargs} step {step}: after the {stage} the body at {np.round(pose, 4).tolist()} "
        f"overlaps a wall (corners {np.round(corners, 4).tolist()})"
    )


# --- maps and parameters --------------------------------------------------------------------------------------


def _random_room(rng: np.random.Generator) -> list[list[tuple[float, float]]]:
    """A star-shaped outline round (200, 200) (concave corners, edges at any angle) with, most of the time, a
    convex obstacle near its centre, well inside the outline."""
    n = int(rng.integers(5, 13))
    angles = np.sort(rng.uniform(0, 2 * np.pi, n))
    while np.diff(angles, append=angles[0] + 2 * np.pi).max() > 0.8 * np.pi:  # star-shaped round the centre
        angles = np.sort(rng.uniform(0, 2 * np.pi, n))
    radii = rng.uniform(70.0, 170.0, n)
    outline = np.column_stack([200 + radii * np.cos(angles), 200 + radii * np.sin(angles)])
    polygons = [outline.tolist()]
    a, b = outline, np.roll(outline, -1, axis=0)
    along = np.clip(((200 - a) * (b - a)).sum(axis=1) / ((b - a) ** 2).sum(axis=1), 0, 1)
    inner = float(np.hypot(*(a + along[:, None] * (b - a) - 200).T).min())  # the centre's distance to the outline
    if rng.random() < 0.7 and inner > 20:
        size, k, spin = rng.uniform(0.1, 0.4) * inner, int(rng.integers(3, 6)), rng.uniform(0, 2 * np.pi)
        polygons.append([(200 + size * math.cos(spin + 2 * np.pi * i / k), 200 + size * math.sin(spin + 2 * np.pi * i / k))
                         for i in range(k)])  # fmt: skip
    return polygons


def _ends_of_ranges(rng: np.random.Generator) -> dict:
    """A cart with every parameter at an end of its range (or, now and then, between), as the cart accepts it."""
    kwargs = {}
    for name, (low, high) in C.CART_PARAMETER_RANGES.items():
        pick = rng.random()
        kwargs[name] = low if pick < 0.4 else high if pick < 0.8 else float(rng.uniform(low, high))
    # The bumper covers the tyres: the widest accepted wheel base is 20 - 1.4 cm.
    kwargs["wheel_base_cm"] = min(kwargs["wheel_base_cm"], C.CART_PARAMETER_RANGES["bumper_width_cm"][1] - TYRES_CM)
    kwargs["bumper_width_cm"] = max(kwargs["bumper_width_cm"], kwargs["wheel_base_cm"] + TYRES_CM)
    return kwargs


def _actions(rng: np.random.Generator, kind: str, steps: int) -> np.ndarray:
    if kind == "random":
        turns = rng.uniform(-1.0, 1.0, steps)
    elif kind == "extreme":
        turns = rng.choice([-1.0, 1.0, 0.0], steps)
    elif kind == "straight":
        turns = np.zeros(steps)
    else:  # mixed: mostly random, with runs of half turns and of driving straight back into a wall
        turns = np.where(rng.random(steps) < 0.5, rng.uniform(-1.0, 1.0, steps), rng.choice([-1.0, 1.0, 0.0], steps))
    return turns.astype(np.float32)[:, None]


def _run_single(map_spec, kwargs: dict, seed: int, steps: int, kind: str) -> tuple[list[str], int]:
    """Roll one env; return the first few overlaps (with where they happened) and the number of bumps."""
    env = gym.make(ENV_ID, map=map_spec, max_episode_steps=None, **kwargs).unwrapped
    env.reset(seed=seed)
    polygons = _polygons(env)
    actions = _actions(np.random.default_rng(seed), kind, steps)
    poses, bumps = [], 0
    for turn in actions:
        *_, info = env.step(turn)
        stage_poses = _state_poses(env.state)
        public = {"drive (info)": info["pose_at_bump"], "back-up (info)": info["pose"]}
        for name, pose in public.items():
            stage_poses[name] = np.array([[pose[0], pose[1], math.radians(pose[2])]])
        poses.append(stage_poses)
        bumps += info["bumped"]
    failures = []
    for name in poses[0]:
        stacked = np.concatenate([p[name] for p in poses])
        bad = _overlaps(stacked, kwargs, polygons) | ~_in_map(stacked[:, :2], polygons)
        failures += [_describe(env, kwargs, int(i), name, stacked[i]) for i in np.flatnonzero(bad)[:2]]
    return failures, bumps


# --- the tests ------------------------------------------------------------------------------------------------


def test_the_issues_drive_into_a_box_stops_at_it():
    """The issue's case: on ``obstacles`` (seed 26, cycle 63) the drive ended with the body's front-left corner at
    (91.86, 50.92), inside the box [80, 92] x [50, 70]. The corner started just above the line y = 50, far west of
    the box, dipped below it at x = 23.1 and came back up through the box's south face at x = 86.6: the search kept
    only the first crossing of each line."""
    env = gym.make(ENV_ID, map="obstacles").unwrapped
    env.reset(seed=26)
    rng = np.random.default_rng(26)
    polygons = _polygons(env)
    for k in range(63):
        *_, info = env.step(rng.uniform(-1, 1, 1).astype(np.float32))
        x, y, heading = info["pose_at_bump"]
        pose = np.array([[x, y, math.radians(heading)]])
        assert not _overlaps(pose, {}, polygons)[0], _describe(env, {}, k, "drive", pose[0])


def test_matched_motors_never_enter_a_wall():
    """With the motors perfectly matched (no mismatch, no wheel-base error, no wheel slip) the drive is a straight
    line and the turns and slips spin about the axle, yet a spin took a wide cart into a box: the box's corner,
    beside the body and behind its rear, crossed the line of the body's side beyond the body, then crossed it
    again through the side itself (the search kept only the first crossing of each line)."""
    failures = []
    for seed, (map_name, wide) in enumerate(
        [("obstacles", False), ("maze", False), ("obstacles", True), ("maze", True)]
    ):
        kwargs = {"mismatch_sd": 0.0, "wheel_base_sd": 0.0, "slip_sd": 0.0}
        if wide:
            kwargs.update(bumper_width_cm=20.0, wheel_base_cm=3.0)
        found, bumps = _run_single(map_name, kwargs, seed, 2500, "random")
        failures += found
        assert bumps > 1000
    assert not failures, "\n".join(failures)


def test_a_wide_cart_with_a_long_back_up_stays_in_the_l_room():
    """The issue: with ``wheel_base_cm=3, backup_cm=30`` on ``l_room`` the cart's centre left the 160 x 160 room
    (139 cm outside in one run)."""
    failures, _ = _run_single("l_room", {"wheel_base_cm": 3.0, "backup_cm": 30.0}, 3, 3000, "random")
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("kind", ["random", "extreme", "mixed"])
def test_no_accepted_parameters_let_the_cart_into_a_wall(kind):
    """Property: every built-in map and random polygon rooms, carts with every parameter at an end of its range,
    random and extreme turns; after every stage the body is out of the walls and the centre in the map."""
    rng = np.random.default_rng({"random": 11, "extreme": 12, "mixed": 13}[kind])
    maps = [*MAPS, "random", "random"]
    failures, trials = [], 0
    while trials < 2 * len(maps):
        spec = maps[trials % len(maps)]
        map_spec = _random_room(rng) if spec == "random" else spec
        kwargs = _ends_of_ranges(rng)
        try:
            gym.make(ENV_ID, map=map_spec, **kwargs)
        except ValueError as error:  # the room is too small for this cart (or a random edge under 0.5 cm)
            assert "does not fit" in str(error) or "edges must" in str(error), error
            continue
        found, _ = _run_single(map_spec, kwargs, trials, 400, kind)
        failures += found
        trials += 1
    assert not failures, "\n".join(failures[:10])


@pytest.mark.parametrize("map_name", ["obstacles", "l_room", "maze", "paper"])
def test_native_vector_env_never_enters_a_wall(map_name):
    """The same property for the native vector env's rows (each with its own episode draws), extreme carts."""
    rng = np.random.default_rng(len(map_name))
    for kwargs in ({"wheel_base_cm": 3.0, "backup_cm": 30.0, "mismatch_sd": 0.1, "snap_prob": 1.0,
                    "snap_max_deg": 45.0, "slide_prob": 1.0, "slide_max_deg": 90.0},
                   {"mismatch_sd": 0.0, "wheel_base_sd": 0.0, "slip_sd": 0.0, "bumper_width_cm": 20.0,
                    "bumper_offset_cm": 3.0, "rear_cm": 1.0, "backup_cm": 1.0}):  # fmt: skip
        envs = gym.make_vec(ENV_ID, num_envs=64, map=map_name, **kwargs)
        envs.reset(seed=5)
        core = envs.unwrapped._core
        poses = {}
        for step in range(150):
            turns = rng.uniform(-1, 1, (64, 1)) if step % 2 else rng.choice([-1.0, 0.0, 1.0], (64, 1))
            _, _, _, _, info = envs.step(turns.astype(np.float32))
            stage_poses = _state_poses(core.state)
            for name, key in (("drive (info)", "pose_at_bump"), ("back-up (info)", "pose")):
                pose = info[key]
                stage_poses[name] = np.column_stack([pose[:, 0], pose[:, 1], np.radians(pose[:, 2])])
            for name, pose in stage_poses.items():
                poses.setdefault(name, []).append(pose)
        envs.close()
        polygons = _polygons(core)
        for name, stacked in poses.items():
            stacked = np.concatenate(stacked)  # step-major: row i of step k is at 64 k + i
            bad = _overlaps(stacked, kwargs, polygons) | ~_in_map(stacked[:, :2], polygons)
            first = int(np.argmax(bad))
            assert not bad.any(), _describe(core, kwargs, f"{first // 64} (row {first % 64})", name, stacked[first])


@pytest.mark.parametrize("layouts", ["train", "test"])
def test_held_out_layouts_never_start_or_drive_the_cart_into_a_wall(layouts):
    """The rooms of ``layouts="train"`` and ``"test"`` (a room per row, redrawn at every reset): the start and
    every stage of the native vector env's rows keep the body out of the walls and the centre in the room."""
    rng = np.random.default_rng(len(layouts))
    envs = gym.make_vec(ENV_ID, num_envs=32, layouts=layouts, max_episode_steps=40)
    envs.reset(seed=9)
    core = envs.unwrapped._core
    for step in range(120):
        worlds = [[np.asarray(p, dtype=np.float64) for p in w.polygons] for w in core._slot_worlds]
        starts = core.state[:, [C.X, C.Y, C.HEADING]].copy()
        _, _, _, truncated, _ = envs.step(rng.uniform(-1, 1, (32, 1)).astype(np.float32))
        stage_poses = _state_poses(core.state)
        for row in range(32):
            polygons = worlds[row]
            poses = np.stack([starts[row], *(pose[row] for pose in stage_poses.values())])
            if step and core._cycles[row] == 0:  # restarted in this step: a fresh room and its start only
                poses, polygons = poses[:1], [np.asarray(p, dtype=np.float64) for p in core._slot_worlds[row].polygons]
                poses[0] = core.state[row, [C.X, C.Y, C.HEADING]]
            bad = _overlaps(poses, {}, polygons) | ~_in_map(poses[:, :2], polygons)
            assert not bad.any(), f"{layouts} row {row} step {step}: {np.round(poses[bad], 3).tolist()}"
    envs.close()


def test_the_checks_here_see_an_overlap():
    """The independent geometry itself: a body just inside a wall, a wall corner in the body, outside the map."""
    room = [np.array([(0.0, 0.0), (100.0, 0.0), (100.0, 80.0), (0.0, 80.0)]),
            np.array([(40.0, 30.0), (60.0, 30.0), (60.0, 50.0), (40.0, 50.0)])]  # fmt: skip
    poses = np.array([
        [50.0, 15.0, 0.0],  # clear
        [100.0 - 7.0 - 1e-5, 40.0, 0.0],  # bumper 1e-5 cm short of the east wall: clear
        [100.0 - 7.0 + 1e-5, 40.0, 0.0],  # 1e-5 cm into it
        [33.0 + 1e-5, 40.0, 0.0],  # bumper 1e-5 cm into the box's west face
        [61.0, 29.0, math.radians(45.0)],  # the box's corner (60, 30) inside the body, its corners all free
        [150.0, 40.0, 0.0],  # outside the room
    ])  # fmt: skip
    assert _overlaps(poses, {}, room).tolist() == [False, False, True, True, True, True]
    assert _in_map(poses[:, :2], room).tolist() == [True, True, True, True, True, False]


@pytest.mark.parametrize("past_cm", [0.0, 1e-13, 1e-10])
def test_a_body_touching_a_wall_is_stopped_at_once_moving_in_and_free_moving_out(past_cm):
    """Rounding can leave a body point a hair past a wall's line (here the bumper ``past_cm`` beyond the east wall
    of ``rectangle``): driving on must stop at once (the crossing lies before the stage's start), backing away
    must not."""
    from polyenvs.bumper.maps import make_map

    world = make_map("rectangle")
    params = C.CartModel().packed()
    x, y, h = 120.0 - 7.0 + past_cm, 45.0, 0.0
    t, seg, _, _ = C._first_contact(x, y, h, 50.0, 50.0, 6.0, params, world.walls)
    assert (t, seg) == (0.0, 1)  # segment 1: (120, 0) -> (120, 90)
    _, seg, _, _ = C._first_contact(x, y, h, -50.0, -50.0, 6.0, params, world.walls)
    assert seg == -1
