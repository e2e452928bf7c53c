"""Transcendental functions computed by the C library, element by element, the same on every machine.

numpy picks a kernel for its float64 transcendental ufuncs at run time from the CPU: on a CPU with AVX-512,
``np.arctan2``, ``np.arcsin``, ``np.arccos``, ``np.arctan``, ``np.tan``, ``np.power``, ``np.log*``, ``np.exp*``,
``np.cbrt`` and the hyperbolic functions run Intel's SVML (numpy/_core/src/umath/loops_umath_fp.dispatch.c.src, for
float32 too), ``np.exp`` and ``np.log`` numpy's own AVX-512F kernels (loops_exponent_log), ``np.tanh`` numpy's SIMD
kernel even on AVX2 (loops_hyperbolic); only elsewhere do they call the C library. The results differ in the last
bit, so an episode whose observations, rewards, metrics or hand-baseline actions pass through one of them differs
between machines. The functions here call the C library on each element instead (``math``, like numba's compiled
code; ``atan2f`` and the like for float32 values): an environment's geometry and its baselines' bearings use them;
tests/test_libm_only.py refuses the ufuncs in those modules. They take a float or an array and return what the ufunc
returns without AVX-512, bit for bit: a scalar or an array of the broadcast shape, float64, or float32 where numpy's
promotion gives float32; other types raise ``TypeError``."""

from __future__ import annotations

import ctypes
import ctypes.util
import math

import numpy as np

_C_LIBRARY = ctypes.CDLL(ctypes.util.find_library("m"))
_F64, _F32 = np.dtype(np.float64), np.dtype(np.float32)


def _c_float(name: str, arity: int):
    """The C library's float32 function ``name`` (``atan2f``, ...): what numpy's float32 loop calls without AVX-512."""
    function = getattr(_C_LIBRARY, name)
    function.restype, function.argtypes = ctypes.c_float, [ctypes.c_float] * arity
    return function


def _typed(functions: dict, *arguments):
    """The function for the float type the numpy ufunc would compute in (float64 or float32), by numpy's promotion
    rules (a Python float does not widen a float32 array)."""
    dtype = np.result_type(*arguments)
    dtype = _F64 if dtype.kind in "biu" else dtype
    if dtype not in functions:
        raise TypeError(f"this libm function takes {' or '.join(map(str, functions))} values, got {dtype}")
    return functions[dtype], dtype


def _unary(functions: dict, x):
    function, dtype = _typed(functions, x)
    values = np.asarray(x)
    if values.ndim == 0:
        return dtype.type(function(float(values)))
    return np.array([function(v) for v in values.ravel().tolist()], dtype=dtype).reshape(values.shape)


def _binary(functions: dict, y, x):
    function, dtype = _typed(functions, y, x)
    ys, xs = np.broadcast_arrays(np.asarray(y), np.asarray(x))
    if ys.ndim == 0:
        return dtype.type(function(float(ys), float(xs)))
    pairs = zip(ys.ravel().tolist(), xs.ravel().tolist(), strict=True)
    return np.array([function(a, b) for a, b in pairs], dtype=dtype).reshape(ys.shape)


# No float32 sine and cosine: numpy's float32 sin and cos are its own SIMD kernel on every x86 machine, not sinf.
_SIN = {_F64: math.sin}
_COS = {_F64: math.cos}
_ASIN = {_F64: math.asin, _F32: _c_float("asinf", 1)}
_ACOS = {_F64: math.acos, _F32: _c_float("acosf", 1)}
_ATAN2 = {_F64: math.atan2, _F32: _c_float("atan2f", 2)}


def sin(x):
    """``math.sin`` of each element."""
    return _unary(_SIN, x)


def cos(x):
    """``math.cos`` of each element."""
    return _unary(_COS, x)


def arcsin(x):
    """``math.asin`` of each element (in [-1, 1])."""
    return _unary(_ASIN, x)


def arccos(x):
    """``math.acos`` of each element (in [-1, 1])."""
    return _unary(_ACOS, x)


def arctan2(y, x):
    """``math.atan2(y, x)`` of each broadcast pair: the angle of the vector (x, y) in (-pi, pi]."""
    return _binary(_ATAN2, y, x)
