"""NumPy's standard normal, ``random_standard_normal`` of ``numpy/random/src/distributions/distributions.c``: the
256-layer ziggurat with numba's copy of NumPy's tables, in the pieces its two compiled users share.

NumPy draws a normal from one 64-bit word (layer, sign and abscissa); most words are accepted at once
(:func:`candidate`); a word of the base layer falls into the tail (two uniform draws per try, :func:`tail_value`)
and any other into a wedge (one uniform draw, :func:`wedge_accepts`). The users differ only in where the draws come
from: :mod:`polyenvs.core.streams` reads a block of raw draws fetched beforehand, :mod:`polyenvs.core.generators`
calls each generator's C functions. Every draw and the generator's state after it match NumPy bit for bit (tested
in both).
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.jit import njit

__all__ = ["AVAILABLE", "candidate", "tail_try", "tail_value", "unit_double", "wedge_accepts"]

try:
    from numba.np.random._constants import fi_double as _FI
    from numba.np.random._constants import ki_double as _KI
    from numba.np.random._constants import wi_double as _WI
    from numba.np.random._constants import ziggurat_nor_inv_r as _INV_R
    from numba.np.random._constants import ziggurat_nor_r as _R
except ImportError:  # pragma: no cover - without numba the callers draw through NumPy
    AVAILABLE = False
    _FI = _KI = _WI = np.zeros(256)
    _INV_R = _R = 0.0
else:
    AVAILABLE = True
    _KI = _KI.astype(np.int64)  # every entry is below 2**52; draws may be read as signed integers
_ABSCISSA = 0x000FFFFFFFFFFFFF
_TOP53 = (1 << 53) - 1
_TO_UNIT = 1.0 / 9007199254740992.0


@njit(cache=True)
def candidate(r):
    """The word ``r``'s ``(layer, abscissa bits, value, accepted at once)``; ``r`` int64 or uint64 (the masks keep
    only bits that read the same either way)."""
    layer = r & 0xFF
    rabs = (r >> 9) & _ABSCISSA
    x = rabs * _WI[layer]
    if (r >> 8) & 1:
        x = -x
    return layer, rabs, x, rabs < _KI[layer]


@njit(cache=True)
def tail_try(u1, u2):
    """One try in the base layer's tail from two uniforms: ``(xx, accepted)``."""
    xx = -_INV_R * math.log1p(-u1)
    yy = -math.log1p(-u2)
    return xx, yy + yy > xx * xx


@njit(cache=True)
def tail_value(rabs, xx):
    """The accepted tail normal, its sign from the word's abscissa bits as NumPy takes it."""
    return -(_R + xx) if (rabs >> 8) & 1 else _R + xx


@njit(cache=True)
def wedge_accepts(layer, x, u):
    """Whether the wedge of ``layer`` (not the base layer) accepts ``x`` with the uniform ``u``."""
    return (_FI[layer - 1] - _FI[layer]) * u + _FI[layer] < math.exp(-0.5 * x * x)


@njit(cache=True)
def unit_double(word):
    """A raw 64-bit draw as PCG64's ``next_double`` turns it into a uniform in [0, 1): its top 53 bits."""
    return ((word >> 11) & _TOP53) * _TO_UNIT
