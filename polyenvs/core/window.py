"""Rendering modes over a family's frames: ``rgb_array`` returns them, ``human`` shows them in a pygame window.

Every family draws its frames with :mod:`polyenvs.core.raster` and shows them here, so the window's behaviour (the
frame rate, closing it, the missing-dependency message) is the same for all of them.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FrameRenderer", "FrameWindow"]


class FrameWindow:
    """A pygame window titled ``caption`` showing frames at most ``fps`` times per second."""

    def __init__(self, caption: str, fps: float):
        self.caption = caption
        self.fps = fps
        self._surface = None
        self._clock = None

    def show(self, frame: np.ndarray) -> None:
        """Show an ``(H, W, 3)`` uint8 frame (opening the window, the frame's size, on the first call)."""
        try:
            import pygame
        except ImportError as exc:
            from gymnasium.error import DependencyNotInstalled

            raise DependencyNotInstalled('render_mode="human" needs pygame: pip install "polyenvs[render]"') from exc
        if self._surface is None:
            pygame.init()
            pygame.display.init()
            self._surface = pygame.display.set_mode((frame.shape[1], frame.shape[0]))
            pygame.display.set_caption(self.caption)
            self._clock = pygame.time.Clock()
        self._surface.blit(pygame.surfarray.make_surface(np.transpose(frame, (1, 0, 2))), (0, 0))
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

    def __init__(self, render_mode: str, fps: float):
        self.render_mode = render_mode
        self.fps = fps
        self._window = FrameWindow(self.caption, fps)

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
