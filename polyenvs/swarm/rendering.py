"""Top-down frames of a swarm: walls, obstacles, the goal light, formation links, robots, headings and IR beams.

Drawn with the numpy rasterizer (:mod:`polyenvs.core.raster`); ``human`` mode shows the frames in a pygame window
(``pip install "polyenvs[render]"``). Every frame of an instance covers the same bounds, so frames have one size.
"""

from __future__ import annotations

import numpy as np

from polyenvs.core.raster import FRAME_WIDTH_PX, with_legend
from polyenvs.core.window import TopDownRenderer
from polyenvs.swarm.batch import BEAM_M

__all__ = ["FRAME_WIDTH_PX", "SwarmRenderer"]

#: Robots are drawn at least this many pixels in radius: to scale, a Maxelbot on the obstacle field is 2-3 px
#: wide at 480 px, too small to see or to tell from an obstacle.
MIN_ROBOT_RADIUS_PX = 6.0
OBSTACLE = (120, 120, 120)
LIGHT = (250, 200, 0)
LIGHT_HALO = (255, 240, 170)
LINK = (120, 170, 230)
BODY = (40, 110, 200)
LEADER = (200, 60, 40)
HEADING = (255, 255, 255)
BEAM_HIT = (40, 160, 60)
BEAM_NONE = (205, 205, 205)


class SwarmRenderer(TopDownRenderer):
    """Renders a :class:`~polyenvs.swarm.env.SwarmEnv`; ``human`` mode opens a pygame window lazily."""

    caption = "polyenvs swarm"

    def frame(self, env) -> np.ndarray:
        canvas = self.canvas_with_walls(env.layout.walls)
        canvas.disc(env.goal, env.goal_radius_m, LIGHT_HALO)
        canvas.disc(env.goal, 0.1, LIGHT)
        for x, y, r in env.circles:
            canvas.disc((x, y), r, OBSTACLE)
        live = np.flatnonzero(env.active)
        pose = env.pose
        radius = env.platform.radius_m
        drawn = max(radius, MIN_ROBOT_RADIUS_PX / canvas.scale)
        if getattr(env, "pairs", None) is not None:
            i, j = env.pairs[:, 0], env.pairs[:, 1]
            keep = (env.active[i] > 0) & (env.active[j] > 0)
            canvas.lines(pose[i[keep], :2], pose[j[keep], :2], LINK, width_px=1.5)
        if len(live):
            angle = pose[live, 2:3] + np.radians(env.sensor_angles_deg)[None, :]
            unit = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
            start = pose[live, None, :2] + radius * unit
            hit = np.isfinite(env.beams[live])
            length = np.where(hit, env.beams[live], BEAM_M)[..., None]
            colours = np.where(hit.reshape(-1, 1), BEAM_HIT, BEAM_NONE)
            canvas.lines(start.reshape(-1, 2), (start + length * unit).reshape(-1, 2), colours, width_px=1.0)
        leader = getattr(env, "leader", None)  # a task whose robot broadcasts names it
        for i in live.tolist():
            canvas.disc(pose[i, :2], drawn, LEADER if i == leader else BODY)
        if len(live):
            tip = pose[live, :2] + drawn * np.column_stack([np.cos(pose[live, 2]), np.sin(pose[live, 2])])
            canvas.lines(pose[live, :2], tip, HEADING, width_px=2.0)
        key = [("robot", BODY)] + ([("leader", LEADER)] if leader is not None else [])
        key += [("ir echo", BEAM_HIT), ("light", LIGHT), ("obstacle", OBSTACLE)]
        if getattr(env, "pairs", None) is not None:
            key.append(("formation link", LINK))
        return with_legend(canvas.image, key)
