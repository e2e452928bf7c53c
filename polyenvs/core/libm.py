"""Float64 transcendental functions computed by the C library, element by element, the same on every machine.

numpy picks a kernel for its float64 transcendental ufuncs at run time from the CPU: on a CPU with AVX-512,
``np.arctan2``, ``np.arcsin``, ``np.arccos``, ``np.arctan``, ``np.tan``, ``np.power``, ``np.log*``, ``np.exp*``,
``np.cbrt`` and the hyperbolic functions run Intel's SVML (numpy/_core/src/umath/loops_umath_fp.dispatch.c.src),
``np.exp`` and ``np.log`` numpy's own AVX-512F kernels (loops_exponent_log), ``np.tanh`` numpy's SIMD kernel even
on AVX2 (loops_hyperbolic); only elsewhere do they call the C library. The results differ in the last bit, so an
episode whose observations, rewards, metrics or hand-baseline actions pass through one of them differs between
machines. The functions here call ``math`` (the C library, like numba's compiled code) on each element instead: an
environment's geometry and its baselines' bearings use them; tests/test_libm_only.py refuses the ufuncs in those
modules. They take a float or an array and return, like the ufuncs, a ``np.float64`` or a float64 array of the
broadcast shape (so numpy's promotion rules treat the result as before). Float32 input raises ``TypeError``.
"""

from __future__ import annotations

import math

import numpy as np


def _float64(x) -> np.ndarray:
    values = np.asarray(x)
    if values.dtype.kind == "f" and values.dtype != np.float64:
        # numpy would compute in the narrower type (its own SIMD kernels); widening here would change the values.
        raise TypeError(f"libm functions take float64 values, got {values.dtype}")
    return values.astype(np.float64, copy=False)


def _unary(function, x):
    values = _float64(x)
    if values.ndim == 0:
        return np.float64(function(float(values)))
    return np.array([function(v) for v in values.ravel().tolist()], dtype=np.float64).reshape(values.shape)


def _binary(function, y, x):
    ys, xs = np.broadcast_arrays(_float64(y), _float64(x))
    if ys.ndim == 0:
        return np.float64(function(float(ys), float(xs)))
    pairs = zip(ys.ravel().tolist(), xs.ravel().tolist(), strict=True)
    return np.array([function(a, b) for a, b in pairs], dtype=np.float64).reshape(ys.shape)


def sin(x):
    """``math.sin`` of each element."""
    return _unary(math.sin, x)


def cos(x):
    """``math.cos`` of each element."""
    return _unary(math.cos, x)


def arcsin(x):
    """``math.asin`` of each element (in [-1, 1])."""
    return _unary(math.asin, x)


def arccos(x):
    """``math.acos`` of each element (in [-1, 1])."""
    return _unary(math.acos, x)


def arctan2(y, x):
    """``math.atan2(y, x)`` of each broadcast pair: the angle of the vector (x, y) in (-pi, pi]."""
    return _binary(math.atan2, y, x)
