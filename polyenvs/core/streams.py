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

__all__ = ["BLOCK_STEPS", "RowStreams"]

#: Draw rows per block: the generator call's own cost, amortised over 256 steps, is negligible next to the draws.
BLOCK_STEPS = 256


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
        self.normals[row] = self.generators[row].standard_normal((BLOCK_STEPS, self.draws_per_step))
        self.cursor[row] = 0
