"""Rendering modes over a family's frames: ``rgb_array`` returns them, ``human`` shows them in a pygame window.

Every family draws its frames with :mod:`polyenvs.core.raster` and shows them here, so the window's behaviour (the
frame rate, closing it, the missing-dependency message) is the same for all of them.
"""

from __future__ import annotations

import numpy as np

from polyenvs.core.extras import install_hint
from polyenvs.core.raster import FRAME_WIDTH_PX, WALL, Canvas
from polyenvs.core.validation import check_in_range

__all__ = ["FrameRenderer", "FrameWindow", "TopDownRenderer", "WINDOW_SCALE_RANGE", "check_window_scale"]

#: ``window_scale`` bounds: a quarter of a 480-pixel frame is still legible, eight times fills a 4K screen.
WINDOW_SCALE_RANGE = (0.25, 8.0)


def check_window_scale(value) -> float:
    """``window_scale`` as a float in :data:`WINDOW_SCALE_RANGE`; ``ValueError`` naming it otherwise."""
    return check_in_range("window_scale", value, *WINDOW_SCALE_RANGE)


class FrameWindow:
    """A pygame window titled ``caption`` showing frames at most ``fps`` times per second, each scaled by
    ``scale`` (the window is the frame's size times ``scale``)."""

    def __init__(self, caption: str, fps: float, scale: float = 1.0):
        self.caption = caption
        self.fps = fps
        self.scale = check_window_scale(scale)
        self._surface = None
        self._clock = None

    def show(self, frame: np.ndarray) -> None:
        """Show an ``(H, W, 3)`` uint8 frame (opening the window, the frame's size, on the first call)."""
        try:
            import pygame
        except ImportError as exc:
            from gymnasium.error import DependencyNotInstalled

            raise DependencyNotInstalled(f'render_mode="human" needs pygame: {install_hint("render")}') from exc
        size = (max(1, round(frame.shape[1] * self.scale)), max(1, round(frame.shape[0] * self.scale)))
        if self._surface is None:
            pygame.init()
            pygame.display.init()
            self._surface = pygame.display.set_mode(size)
            pygame.display.set_caption(self.caption)
            self._clock = pygame.time.Clock()
        image = pygame.surfarray.make_surface(np.transpose(frame, (1, 0, 2)))
        if size != image.get_size():
            image = pygame.transform.smoothscale(image, size)
        self._surface.blit(image, (0, 0))
        pygame.event.pump()
        pygame.display.flip()
        self._clock.tick(self.fps)

    def close(self) -> None:
        """Close the window if one is open (idempotent)."""
        if self._surface is not None:
            import pygame

            pygame.display.quit()
            pygame.quit()
            self._surface = None


class FrameRenderer:
    """Base of a family's renderer: subclasses draw ``frame(env)``; ``render(env)`` returns it (``rgb_array``) or
    shows it in a window titled ``caption`` (``human``, opened at the first frame)."""

    caption = "polyenvs"

    def __init__(self, render_mode: str, fps: float, window_scale: float = 1.0):
        self.render_mode = render_mode
        self.fps = fps
        self._window = FrameWindow(self.caption, fps, window_scale)

    def frame(self, env) -> np.ndarray:
        raise NotImplementedError

    def render(self, env):
        frame = self.frame(env)
        if self.render_mode == "rgb_array":
            return frame
        self._window.show(frame)
        return None

    def close(self) -> None:
        self._window.close()


class TopDownRenderer(FrameRenderer):
    """A renderer of a plan seen from above: every frame covers ``view_bounds`` (x0, y0, x1, y1), so one instance
    makes frames of one size, and starts from the walls (:meth:`canvas_with_walls`)."""

    def __init__(self, render_mode: str, fps: float, view_bounds, window_scale: float = 1.0):
        super().__init__(render_mode, fps, window_scale)
        self.view_bounds = tuple(float(v) for v in view_bounds)

    def canvas_with_walls(self, segments: np.ndarray) -> Canvas:
        """A blank frame with the wall ``segments`` (x1, y1, x2, y2 rows) drawn on it."""
        canvas = Canvas(self.view_bounds, width=FRAME_WIDTH_PX)
        canvas.lines(segments[:, :2], segments[:, 2:], WALL, width_px=3.0)
        return canvas
