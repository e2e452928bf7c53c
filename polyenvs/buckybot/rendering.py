"""Top-down frames of a Buckybot episode: walls, the robot's hexagon and resting face, beams and paths.

Drawn with the numpy rasterizer (:mod:`polyenvs.core.raster`), so ``rgb_array`` needs nothing beyond numpy;
``human`` mode shows the frames in a pygame window (``pip install "polyenvs[render]"``).
"""

from __future__ import annotations

import numpy as np

from polyenvs.buckybot import simulator as S
from polyenvs.buckybot.geometry import SENSOR_AZIMUTHS_RAD, SENSOR_HORIZONTAL_OFFSET_CM, TRUNCATED_EDGE_CM
from polyenvs.buckybot.sensors import horizontal_range
from polyenvs.core.raster import DEAD_RECKONED_PATH, FRAME_WIDTH_PX, TRUE_PATH, with_legend
from polyenvs.core.window import TopDownRenderer

__all__ = ["BuckybotRenderer", "FRAME_WIDTH_PX"]

BODY = (250, 190, 60)
BODY_EDGE = (120, 80, 10)
BODY_FACE = (255, 236, 170)
BEAM_VALID = (40, 160, 60)
BEAM_TOO_CLOSE = (230, 120, 0)
BEAM_NONE = (190, 190, 190)
GOAL = (140, 30, 160)
TIP = (90, 50, 0)
_HEXAGON_ANGLES = np.radians(np.arange(6) * 60.0 + 30.0)


class BuckybotRenderer(TopDownRenderer):
    """Renders row 0 of a :class:`~polyenvs.buckybot.env.BuckybotEnv`; ``human`` mode opens a pygame window lazily.

    Every frame covers ``view_bounds`` (the plan's, or the box every random room fits in), so one renderer makes
    frames of one size whatever the room, and pixel-observation wrappers stay inside their space.
    """

    caption = "polyenvs Buckybot"

    def frame(self, env) -> np.ndarray:
        canvas = self.canvas_with_walls(env.plan.segments)
        state = env.sim.state[0]
        pos, heading, face = state[S.X : S.Y + 1], state[S.HEADING], int(state[S.FACE])
        # Dead-reckoned and true paths (the last few thousand points).
        if env._trail is not None:
            true_path, dead_reckoned_path = env._trail.paths()
            if len(true_path) > 1:
                canvas.polyline(dead_reckoned_path, DEAD_RECKONED_PATH, width_px=1.5)
                canvas.polyline(true_path, TRUE_PATH, width_px=1.5)
        goal = getattr(env, "goal", None)
        if goal is not None:
            canvas.disc(goal, getattr(env, "goal_radius_cm", 10.0), GOAL)
        # Beams: to the reading (green), a short stub when too close (orange), full reach when no return (grey).
        az = heading + SENSOR_AZIMUTHS_RAD
        direction = np.stack([np.cos(az), np.sin(az)], axis=-1)
        start = pos + SENSOR_HORIZONTAL_OFFSET_CM * direction
        reading = state[S.READING : S.READING + 6]
        too_close = state[S.TOO_CLOSE : S.TOO_CLOSE + 6] > 0.5
        no_return = state[S.NO_RETURN : S.NO_RETURN + 6] > 0.5
        length = (
            np.where(
                no_return,
                horizontal_range(182.88),
                np.where(too_close, 15.0, horizontal_range(np.nan_to_num(reading))),
            )
            - SENSOR_HORIZONTAL_OFFSET_CM
        )
        colours = np.where(no_return[:, None], BEAM_NONE, np.where(too_close[:, None], BEAM_TOO_CLOSE, BEAM_VALID))
        canvas.lines(start, start + length[:, None] * direction, colours, width_px=1.5)
        valid = ~(no_return | too_close)
        if valid.any():
            canvas.points((start + length[:, None] * direction)[valid], BEAM_VALID, radius_px=3.0)
        # Body: the 13 cm footprint, the hexagonal resting face (side 5.27 cm), ticks for the three tip
        # directions (direction 0, "back", is the darker one) and the resting face's number.
        canvas.disc(pos, env.body_radius_cm, BODY)
        hexagon = pos + TRUNCATED_EDGE_CM * np.stack(
            [np.cos(_HEXAGON_ANGLES + heading), np.sin(_HEXAGON_ANGLES + heading)], axis=-1
        )
        canvas.polygon(hexagon, BODY_FACE, outline=BODY_EDGE)
        tips = heading + np.radians([0.0, 120.0, 240.0])
        unit = np.stack([np.cos(tips), np.sin(tips)], -1)
        canvas.lines(pos + 7.5 * unit, pos + env.body_radius_cm * unit, [TIP, BODY_EDGE, BODY_EDGE], 2.0)
        label_at = pos + 1.6 * env.body_radius_cm * np.array([1.0, 1.0])  # beside the body: it is too small
        canvas.text(label_at, str(face + 1), TIP, scale=2)
        key = [("true path", TRUE_PATH), ("dead reckoned", DEAD_RECKONED_PATH), ("echo", BEAM_VALID),
               ("too close", BEAM_TOO_CLOSE), ("no return", BEAM_NONE)]  # fmt: skip
        return with_legend(canvas.image, key + ([("goal", GOAL)] if goal is not None else []))
