"""Frames people can read: a key under every 2-D family's frame saying what its colours mean, the formation's
robots large enough to see in a default frame, and a zoom for ``render_mode="human"`` (``window_scale``)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401
from polyenvs.buckybot import rendering as bucky_rendering
from polyenvs.bumper import rendering as cart_rendering
from polyenvs.core.raster import with_legend
from polyenvs.swarm import formation_v0
from polyenvs.swarm import rendering as swarm_rendering

#: One id per 2-D family and the colours its key must show (the beasts render through MuJoCo's camera).
KEYED = {
    "polyenvs/BuckybotWallFollow-v0": (bucky_rendering.TRUE_PATH, bucky_rendering.DEAD_RECKONED_PATH,
                                       bucky_rendering.BEAM_VALID, bucky_rendering.BEAM_NONE),
    "polyenvs/BumperCartExplore-v0": (cart_rendering.TRUE_PATH, cart_rendering.DEAD_RECKONED_PATH,
                                      cart_rendering.BUMP, cart_rendering.TOUCHED),
    "polyenvs/APLiteCorridor-v0": (swarm_rendering.BODY, swarm_rendering.BEAM_HIT, swarm_rendering.LIGHT),
}  # fmt: skip


def _key_strip(frame: np.ndarray) -> np.ndarray:
    """The rows under the map: from the key's grey rule (the last all-200 row) down."""
    rule = np.flatnonzero((frame == 200).all(axis=(1, 2)))
    assert len(rule), "the frame has no key under it"
    return frame[rule[-1] :]


@pytest.mark.parametrize("env_id", KEYED)
def test_every_2d_frame_has_a_key_with_its_colours(env_id):
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    frame = env.render()
    strip = _key_strip(frame)
    for colour in KEYED[env_id]:
        assert (strip == colour).all(axis=-1).sum() >= 20, f"{env_id}: no swatch of {colour} in the key"
    assert env.render().shape == frame.shape  # one size per instance
    env.close()


def test_a_key_wraps_and_hides_nothing_of_the_frame():
    image = np.zeros((50, 120, 3), dtype=np.uint8)
    keyed = with_legend(image, [("true path", (200, 40, 40)), ("dead reckoned", (60, 90, 220)), ("bump", (0, 0, 9))])
    assert keyed.shape[1] == 120 and keyed.shape[0] > 50 + 2 * 14  # three labels in 120 px: more than one line
    assert (keyed[:50] == 0).all()


def test_formation_robots_are_large_enough_to_see_in_a_default_frame():
    """To scale a Maxelbot is 2-3 px wide in the 480 px frame of the formation's field; drawn at least
    MIN_ROBOT_RADIUS_PX in radius, each robot covers at least a 9 px disc's worth of pixels."""
    env = formation_v0.parallel_env(render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    frame = frame[: len(frame) - len(_key_strip(frame))]  # the map only: the key has swatches of these colours
    body = (frame == swarm_rendering.BODY).all(axis=-1).sum() + (frame == swarm_rendering.LEADER).all(axis=-1).sum()
    assert body >= env.unwrapped.n_robots * np.pi * 4.5**2 * 0.8
    env.close()


@pytest.mark.parametrize("env_id", KEYED)
def test_window_scale_zooms_the_human_window_and_not_the_frames(env_id, monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    pygame = pytest.importorskip("pygame")
    plain = gym.make(env_id, render_mode="rgb_array")
    plain.reset(seed=0)
    frame = plain.render()
    env = gym.make(env_id, render_mode="human", window_scale=1.5)
    env.reset(seed=0)
    env.render()
    assert pygame.display.get_surface().get_size() == (round(1.5 * frame.shape[1]), round(1.5 * frame.shape[0]))
    env.close()
    zoomed = gym.make(env_id, render_mode="rgb_array", window_scale=1.5)
    zoomed.reset(seed=0)
    assert np.array_equal(zoomed.render(), frame)
    plain.close()
    zoomed.close()


@pytest.mark.parametrize("bad", [0.0, 9.0, "2", True, float("nan")])
def test_a_bad_window_scale_names_itself(bad):
    for env_id in KEYED:
        with pytest.raises(ValueError, match="window_scale"):
            gym.make(env_id, window_scale=bad)
    with pytest.raises(ValueError, match="window_scale"):
        formation_v0.parallel_env(window_scale=bad)
