"""Tests of the numpy rasterizer: coordinate convention, coverage of each primitive, clipping and no-op inputs."""

from __future__ import annotations

import numpy as np
import pytest

from polyenvs.core.raster import Canvas, stamp_text, text_width

WHITE = np.array([255, 255, 255], dtype=np.uint8)
RED = (255, 0, 0)
BLUE = (0, 0, 255)


def make_canvas(**kwargs) -> Canvas:
    """A 100x100 canvas over [0, 10]^2 at exactly 10 px per world unit (no margin)."""
    return Canvas((0.0, 0.0, 10.0, 10.0), width=100, margin=0.0, **kwargs)


def painted(image: np.ndarray) -> np.ndarray:
    """Boolean (H, W) mask of the pixels that are no longer background."""
    return (image != WHITE).any(axis=-1)


def test_image_dtype_shape_and_copy():
    canvas = Canvas((0.0, 0.0, 2.0, 1.0), width=200, margin=0.0)
    image = canvas.image
    assert image.shape == (100, 200, 3)
    assert image.dtype == np.uint8
    assert (image == WHITE).all()
    image[:] = 0  # the property hands out a copy
    assert (canvas.image == WHITE).all()


def test_margin_sets_the_height_from_the_aspect_ratio():
    # 5% of the larger side (10) on each side: 11 x 6 world units -> 440 x 240 px at width 440.
    canvas = Canvas((0.0, 0.0, 10.0, 5.0), width=440)
    assert canvas.image.shape == (240, 440, 3)
    # Uniform scale, content centred: the world centre maps to the image centre.
    np.testing.assert_allclose(canvas.to_pixels(np.array([5.0, 2.5])), [220.0, 120.0])
    np.testing.assert_allclose(canvas.to_pixels(np.array([10.0, 5.0])), [420.0, 20.0])


def test_y_axis_points_up():
    canvas = make_canvas()
    low, high = canvas.to_pixels(np.array([[5.0, 2.0], [5.0, 8.0]]))
    assert high[1] < low[1]
    assert low[0] == high[0]
    canvas.points(np.array([[5.05, 8.05]]), RED, radius_px=0.0)
    rows, cols = np.nonzero(painted(canvas.image))
    assert rows.tolist() == [19] and cols.tolist() == [50]


def test_horizontal_line_lands_on_expected_row():
    canvas = make_canvas()
    # y = 2.05 -> row 100 - 20.5 = 79.5, inside pixel row 79; x 1..9 -> columns 10..90.
    canvas.lines(np.array([[1.0, 2.05]]), np.array([[9.0, 2.05]]), RED)
    rows, cols = np.nonzero(painted(canvas.image))
    assert set(rows.tolist()) == {79}
    assert cols.min() == 10 and cols.max() == 90
    assert len(cols) == 81  # no gaps
    assert (canvas.image[79, 10:91] == RED).all()


def test_thick_line_and_per_segment_colours():
    canvas = make_canvas()
    starts = np.array([[1.0, 2.05], [1.0, 7.05]])
    ends = np.array([[9.0, 2.05], [9.0, 7.05]])
    canvas.lines(starts, ends, np.array([RED, BLUE]), width_px=3.0)
    image = canvas.image
    assert set(np.nonzero(painted(image))[0].tolist()) == {78, 79, 80, 28, 29, 30}
    assert (image[78:81, 50] == RED).all()
    assert (image[28:31, 50] == BLUE).all()


def test_polyline_is_connected():
    canvas = make_canvas()
    path = np.array([[1.05, 1.05], [8.05, 1.05], [8.05, 8.05]])
    canvas.polyline(path, RED)
    mask = painted(canvas.image)
    assert mask[89, 10:81].all()  # bottom leg
    assert mask[19:90, 80].all()  # right leg
    assert mask.sum() == 71 + 71 - 1


def test_polyline_nan_breaks_the_path():
    canvas = make_canvas()
    path = np.array([[1.05, 5.05], [3.05, 5.05], [np.nan, np.nan], [7.05, 5.05], [9.05, 5.05]])
    canvas.polyline(path, RED)
    mask = painted(canvas.image)
    assert mask[49, 10:31].all() and mask[49, 70:91].all()
    assert not mask[49, 31:70].any()


@pytest.mark.parametrize("clockwise", [False, True])
def test_polygon_covers_interior_not_exterior(clockwise):
    canvas = make_canvas()
    square = np.array([[2.0, 2.0], [6.0, 2.0], [6.0, 6.0], [2.0, 6.0]])
    canvas.polygon(square[::-1] if clockwise else square, RED)
    image = canvas.image
    inside_col, inside_row = np.floor(canvas.to_pixels(np.array([4.0, 4.0]))).astype(int)
    outside_col, outside_row = np.floor(canvas.to_pixels(np.array([8.0, 8.0]))).astype(int)
    assert (image[inside_row, inside_col] == RED).all()
    assert (image[outside_row, outside_col] == WHITE).all()
    # Pixel centres in [2, 6]^2: columns 20..59, rows 40..79 -> exactly 40 x 40 pixels.
    mask = painted(image)
    assert mask.sum() == 1600 and mask[40:80, 20:60].all()


def test_polygon_outline_and_non_convex_fill():
    canvas = make_canvas()
    # An L shape: the notch at the top right must stay empty.
    ell = np.array([[1.0, 1.0], [9.0, 1.0], [9.0, 5.0], [5.0, 5.0], [5.0, 9.0], [1.0, 9.0]])
    canvas.polygon(ell, RED, outline=BLUE)
    image = canvas.image
    assert (image[80, 20] == RED).all()  # lower-left arm
    assert (image[20, 80] == WHITE).all()  # notch
    assert (image[90, 50] == BLUE).all()  # bottom edge y = 1 -> row 100 - 10 = 90


def test_disc_covers_centre_not_outside():
    canvas = make_canvas()
    canvas.disc((5.0, 5.0), 1.0, RED)
    mask = painted(canvas.image)
    assert mask[49:51, 49:51].all()
    assert not mask[35, 50] and not mask[50, 65]
    # Area of a 10 px radius disc, within a few pixels of pi r^2.
    assert abs(mask.sum() - np.pi * 100) < 20
    tiny = make_canvas()
    tiny.disc((5.05, 5.05), 0.0, RED)
    assert painted(tiny.image).sum() == 1


def test_out_of_frame_drawing_is_silent_and_leaves_image_unchanged():
    canvas = make_canvas()
    far = np.array([[50.0, 50.0], [60.0, 55.0], [55.0, 70.0]])
    canvas.lines(far[:-1], far[1:], RED, width_px=5.0)
    canvas.lines(np.array([[-1e12, -5.0]]), np.array([[1e12, -5.0]]), RED)
    canvas.polyline(far - 100.0, RED, width_px=3.0)
    canvas.polygon(far, RED, outline=BLUE)
    canvas.polygon(np.array([[-1e9, -1e9], [-1e9 + 1, -1e9], [-1e9, -1e9 + 1]]), RED)
    canvas.disc((-20.0, 5.0), 3.0, RED)
    canvas.points(np.array([[-0.5, 5.0], [10.5, 5.0], [5.0, 11.0], [1e30, -1e30]]), RED, radius_px=2.0)
    # Near the float limit pixel coordinates overflow; such points are skipped without warnings.
    huge = np.array([[1.7e308, 0.0], [-1.7e308, 1.0], [0.0, 1.7e308]])
    with np.errstate(all="raise"):
        canvas.lines(huge, huge[::-1], RED, width_px=3.0)
        canvas.polygon(huge, RED)
        canvas.disc((1e300, 1e300), 1e299, RED)
    assert (canvas.image == WHITE).all()


def test_wide_strokes_keep_earlier_drawing():
    canvas = make_canvas()
    canvas.disc((5.0, 5.0), 1.0, BLUE)
    before = canvas.image
    # Wider than the hidden border the canvas starts with, and entirely off-frame.
    canvas.lines(np.array([[-20.0, -20.0]]), np.array([[-15.0, -15.0]]), RED, width_px=60.0)
    np.testing.assert_array_equal(canvas.image, before)
    canvas.lines(np.array([[0.0, 0.0]]), np.array([[0.0, 10.0]]), RED, width_px=60.0)
    mask = (canvas.image == RED).all(axis=-1)
    assert mask[:, :31].all() and not mask[:, 31:].any()


def test_points_per_item_colours_and_radius():
    canvas = make_canvas()
    canvas.points(np.array([[2.05, 5.05], [8.05, 5.05]]), np.array([RED, BLUE]), radius_px=1.5)
    image = canvas.image
    assert (image[48:51, 19:22] == RED).all() and (image[48:51, 79:82] == BLUE).all()
    assert painted(image).sum() == 18


def test_partly_visible_primitives_are_clipped():
    canvas = make_canvas()
    canvas.lines(np.array([[-1e12, 5.05]]), np.array([[1e12, 5.05]]), RED, width_px=2.0)
    canvas.polygon(np.array([[-5.0, -5.0], [15.0, -5.0], [15.0, 1.0], [-5.0, 1.0]]), RED)
    canvas.disc((10.0, 10.0), 2.0, RED)
    canvas.points(np.array([[0.0, 0.0]]), RED, radius_px=3.0)
    mask = painted(canvas.image)
    assert mask[49].all()
    assert mask[90:].all()
    assert mask[0, 99] and not mask[0, 0]


def test_empty_and_nan_inputs_are_noops():
    canvas = make_canvas()
    empty = np.zeros((0, 2))
    canvas.lines(empty, empty, RED)
    canvas.polyline(empty, RED)
    canvas.polyline([], RED)
    canvas.polygon(empty, RED, outline=BLUE)
    canvas.points(empty, RED)
    nan = np.full((3, 2), np.nan)
    canvas.lines(nan, nan, RED)
    canvas.polyline(nan, RED)
    canvas.polygon(nan, RED)
    canvas.points(nan, RED)
    canvas.disc((np.nan, 1.0), 1.0, RED)
    assert (canvas.image == WHITE).all()


def test_invalid_arguments_raise_value_error():
    canvas = make_canvas()
    with pytest.raises(ValueError, match="starts"):
        canvas.lines(np.zeros((2, 3)), np.zeros((2, 3)), RED)
    with pytest.raises(ValueError, match="color"):
        canvas.lines(np.zeros((2, 2)), np.ones((2, 2)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="width_px"):
        canvas.polyline(np.zeros((2, 2)), RED, width_px=0.0)
    with pytest.raises(ValueError, match="radius"):
        canvas.disc((0.0, 0.0), -1.0, RED)
    with pytest.raises(ValueError, match="bounds"):
        Canvas((1.0, 0.0, 0.0, 1.0))


def test_stamp_text_writes_pixels_and_clips():
    image = np.zeros((20, 30, 3), dtype=np.uint8)
    stamp_text(image, 2, 3, "I", (255, 255, 255), scale=1)
    # The 3x5 "I": a full top and bottom row, the middle column between them.
    assert (image[3, 2:5] == 255).all() and (image[7, 2:5] == 255).all() and (image[4:7, 3] == 255).all()
    assert image.sum() == 255 * 3 * 9
    stamp_text(image, 28, 18, "WIDE", (255, 0, 0), scale=2)  # runs off the image: clipped, no error
    assert text_width("WIDE", 2) == 30


def test_text_draws_digits_centred_and_skips_unknown_characters():
    canvas = Canvas((0.0, 0.0, 10.0, 10.0), width=100)
    blank = canvas.image
    canvas.text((5.0, 5.0), "@~", (0, 0, 0))
    assert np.array_equal(canvas.image, blank)
    canvas.text((5.0, 5.0), "x", (0, 0, 0))  # letters are drawn as capitals
    assert not np.array_equal(canvas.image, blank)
    canvas = Canvas((0.0, 0.0, 10.0, 10.0), width=100)
    canvas.text((5.0, 5.0), "18", (255, 0, 0), scale=2)
    red = np.argwhere((canvas.image == (255, 0, 0)).all(axis=-1))
    assert len(red) > 0
    centre = canvas.to_pixels(np.array([5.0, 5.0]))
    assert abs(red[:, 1].mean() - centre[0]) < 3 and abs(red[:, 0].mean() - centre[1]) < 3
