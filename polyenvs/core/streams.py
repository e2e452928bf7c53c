"""Per-row random streams: each robot of a batch draws from its own generator, as each sub-environment of a
``SyncVectorEnv`` does.

Conventions every batched family inherits from here:

- Row ``i`` of a native vector env reset with seed ``s`` uses the generator a single environment reset with seed
  ``s + i`` would use, and makes the same calls on it in the same order, so switching vectorisation mode never
  changes a result and every sub-environment reproduces ``gym.make(id)`` bit for bit, through autoresets.
- All randomness flows from those generators (``self.np_random`` in a single environment). Compiled step kernels
  cannot take a ``numpy.random.Generator`` cheaply (passing one costs about 7 µs), so each row keeps a block of
  standard normals drawn from its generator: a kernel reads ``normals[b, cursor[b]]`` (one draw row per robot per
  call) and advances ``cursor[b]``; :meth:`RowStreams.refill` redraws exhausted blocks before the next call.
  Draws are made in blocks, but the numbers a row sees depend only on its generator and its own history.
- A reset makes its random choices first, then refills the row's block only if it is used up. A reset without a
  seed keeps the unread draws of the current block (they came from the same generator, so no number is wasted);
  a reseeded row (``restart``) drops them.
"""

from __future__ import annotations

import numpy as np

from polyenvs.core import ziggurat
from polyenvs.core.jit import njit

__all__ = ["BLOCK_STEPS", "RowStreams", "standard_normals"]

#: Draw rows per block: the generator call's own cost, amortised over 256 steps, is negligible next to the draws.
BLOCK_STEPS = 256


def standard_normals(rng: np.random.Generator, out: np.ndarray) -> None:
    """Fill the contiguous float64 array ``out`` with ``rng.standard_normal(out=out)``'s numbers, bit for bit,
    leaving ``rng`` in the same state, about twice as fast for a PCG64 generator (any other calls NumPy).

    NumPy spends most of a normal on calling its bit generator once per draw; here the raw 64-bit draws come in
    one ``random_raw`` call and NumPy's ziggurat (the same tables, the same order of draws) runs compiled. A draw
    rejected by the ziggurat needs more raw draws than were fetched; each refetch asks for one per normal still
    missing, which never exceeds what they will consume, so the generator ends exactly where NumPy leaves it.
    """
    if not ziggurat.AVAILABLE or type(rng.bit_generator) is not np.random.PCG64:
        rng.standard_normal(out=out)
        return
    flat = out.reshape(-1)
    bits = rng.bit_generator
    raw, done, at = bits.random_raw(flat.size), 0, 0
    while True:
        done, at = _ziggurat(raw, at, flat, done)
        if done == flat.size:
            return
        # The unread tail belongs to a normal that needs more than it: keep it, fetch one per normal missing.
        raw, at = np.concatenate((raw[at:], bits.random_raw(flat.size - done))), 0


@njit(cache=True)
def _ziggurat(raw, at, out, done):
    """NumPy's ``random_standard_normal`` on the draws ``raw[at:]`` into ``out[done:]``; returns ``(done, at)``,
    stopping before the first normal whose draws ``raw`` does not hold."""
    bits = raw.view(np.int64)  # signed, so every operation below stays in integers: masks drop the sign bits
    m, n = bits.shape[0], out.shape[0]
    while done < n:
        p = at
        while True:
            if p >= m:
                return done, at
            layer, rabs, x, accepted = ziggurat.candidate(bits[p])
            p += 1
            if accepted:
                break  # 99.3% of the time
            if layer == 0:  # the base strip's tail
                while not accepted:
                    if p + 2 > m:
                        return done, at
                    xx, accepted = ziggurat.tail_try(ziggurat.unit_double(bits[p]), ziggurat.unit_double(bits[p + 1]))
                    p += 2
                x = ziggurat.tail_value(rabs, xx)
                break
            if p >= m:
                return done, at
            u = ziggurat.unit_double(bits[p])
            p += 1
            if ziggurat.wedge_accepts(layer, x, u):
                break
        out[done] = x
        done += 1
        at = p
    return done, at


class RowStreams:
    """Standard-normal blocks for ``batch_size`` rows, each drawn from that row's generator.

    Args:
        batch_size: number of rows (robots).
        draws_per_step: standard normals a row consumes per kernel call.

    Attributes:
        normals: ``(batch_size, BLOCK_STEPS, draws_per_step)`` float64.
        cursor: ``(batch_size,)`` int64, the next unread draw row of each block.
        generators: row ``i``'s ``numpy.random.Generator`` (``None`` until the row is first reset).
    """

    def __init__(self, batch_size: int, draws_per_step: int):
        self.draws_per_step = int(draws_per_step)
        self.normals = np.zeros((batch_size, BLOCK_STEPS, self.draws_per_step))
        self.cursor = np.full(batch_size, BLOCK_STEPS, dtype=np.int64)
        self.generators: list[np.random.Generator | None] = [None] * batch_size

    def restart(self, row: int, rng: np.random.Generator, reseeded: bool) -> None:
        """Make ``rng`` row ``row``'s generator (a continuation of the current one unless ``reseeded``)."""
        self.generators[row] = rng
        if reseeded:
            self.cursor[row] = BLOCK_STEPS  # draws from the old generator: never read them

    def refill(self, rows=None) -> None:
        """Redraw the blocks (of ``rows``, default all) whose every draw row has been read."""
        if self.cursor.shape[0] == 1:
            if self.cursor[0] >= BLOCK_STEPS:
                self._refill_row(0)
            return
        if rows is None:
            for row in np.flatnonzero(self.cursor >= BLOCK_STEPS).tolist():
                self._refill_row(row)
            return
        for row in rows.tolist():  # a few rows that were just reset
            if self.cursor[row] >= BLOCK_STEPS:
                self._refill_row(row)

    def _refill_row(self, row: int) -> None:
        standard_normals(self.generators[row], self.normals[row])
        self.cursor[row] = 0
