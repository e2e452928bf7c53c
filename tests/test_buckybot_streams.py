"""The per-row normal blocks (polyenvs.core.streams): the compiled ziggurat must give NumPy's numbers bit for bit
and leave each generator exactly where ``Generator.standard_normal`` leaves it."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from polyenvs.core.streams import BLOCK_STEPS, RowStreams, standard_normals


def _rejections(rng: np.random.Generator, size: int) -> tuple[int, int]:
    """How many of the next ``size`` raw draws of ``rng`` (a copy is used) fall in the ziggurat's base strip
    (index 0) and how many in its wedges beyond the fast path: the slow paths a test must reach."""
    from numba.np.random._constants import ki_double

    raw = copy.deepcopy(rng).bit_generator.random_raw(size)
    idx = (raw & 0xFF).astype(np.intp)
    rabs = (raw >> np.uint64(9)) & np.uint64(0x000FFFFFFFFFFFFF)
    slow = rabs >= ki_double[idx]
    return int((slow & (idx == 0)).sum()), int((slow & (idx != 0)).sum())


@pytest.mark.parametrize("shape", [(BLOCK_STEPS, 9), (1, 1), (3, 7), (BLOCK_STEPS, 4)])
def test_standard_normals_are_numpys_bit_for_bit(shape):
    tails = wedges = 0
    for seed in range(150):
        ours, theirs = np.random.default_rng(seed), np.random.default_rng(seed)
        for rng in (ours, theirs):
            rng.random(seed % 5)  # start mid-stream
        size = int(np.prod(shape))
        t, w = _rejections(ours, size)
        tails, wedges = tails + t, wedges + w
        got, expected = np.full(shape, np.nan), np.full(shape, np.nan)
        standard_normals(ours, got)
        theirs.standard_normal(out=expected)
        np.testing.assert_array_equal(got, expected)
        assert ours.bit_generator.state == theirs.bit_generator.state
        assert ours.random() == theirs.random()
    if shape == (BLOCK_STEPS, 9):
        assert tails > 0 and wedges > 100  # both slow paths, and refetches mid-normal, were exercised


def test_standard_normals_of_other_bit_generators_are_numpys():
    ours, theirs = (np.random.Generator(np.random.MT19937(3)) for _ in range(2))
    got, expected = np.empty((BLOCK_STEPS, 9)), np.empty((BLOCK_STEPS, 9))
    standard_normals(ours, got)
    theirs.standard_normal(out=expected)
    np.testing.assert_array_equal(got, expected)
    assert ours.random() == theirs.random()


def test_row_streams_refill_draws_each_rows_block_from_its_generator():
    streams = RowStreams(3, 9)
    for row in range(3):
        streams.restart(row, np.random.default_rng(10 + row), reseeded=True)
    streams.cursor[:] = [BLOCK_STEPS, 5, BLOCK_STEPS]
    streams.refill()
    for row in (0, 2):
        expected = np.random.default_rng(10 + row).standard_normal((BLOCK_STEPS, 9))
        np.testing.assert_array_equal(streams.normals[row], expected)
        assert streams.cursor[row] == 0
    assert not streams.normals[1].any() and streams.cursor[1] == 5  # not used up: untouched
