"""Drawing on many NumPy generators in one compiled call, bit for bit as each generator's own methods would.

A batch of E environments keeps one ``np.random.Generator`` per environment (so that each environment's episode
is the single environment's, whatever the others do). Drawing a step's normals and uniforms through each
generator's methods costs two Python calls per environment, about 9 µs per environment on these machines, which at
E = 1024 was the batched swarm's largest cost. Numba can take a Generator as an argument, but unboxes it at every
call (about 35 µs each), so it cannot take a thousand of them.

Every NumPy bit generator exposes its C interface (``bit_generator.ctypes``): the address of its state and the
functions ``next_uint64`` and ``next_double``. :func:`generator_addresses` collects them, once, as an ``(E, 3)``
array; the kernels here call those functions through their addresses and run NumPy's own algorithms on them
(``random_standard_normal``: :mod:`polyenvs.core.ziggurat`; ``random``: ``next_double``), so every draw, and every generator's state after
it, is what ``Generator.standard_normal(out=...)`` and ``Generator.random(out=...)`` give (checked in the tests).

Without numba (or with ``NUMBA_DISABLE_JIT``) :data:`COMPILED` is false and callers draw through the generators.
"""

from __future__ import annotations

import ctypes

import numpy as np

from polyenvs.core import ziggurat
from polyenvs.core.jit import DISABLE_JIT, HAVE_NUMBA, njit

__all__ = ["COMPILED", "STATE", "generator_addresses", "normals_then_uniforms", "random_into", "standard_normal_into"]

#: Columns of :func:`generator_addresses`: the state, ``next_uint64``, ``next_double``.
STATE, NEXT_UINT64, NEXT_DOUBLE = range(3)
#: Whether the kernels here are compiled (else they cannot call C functions, and callers use the generators).
COMPILED = HAVE_NUMBA and not DISABLE_JIT


def generator_addresses(generators) -> np.ndarray:
    """``(len(generators), 3)`` int64: each generator's state address and its ``next_uint64`` and ``next_double``
    functions (valid while the generator lives: its owner keeps it)."""
    rows = []
    for g in generators:
        interface = g.bit_generator.ctypes
        rows.append([
            interface.state_address,
            ctypes.cast(interface.next_uint64, ctypes.c_void_p).value,
            ctypes.cast(interface.next_double, ctypes.c_void_p).value,
        ])  # fmt: skip
    return np.array(rows, dtype=np.int64).reshape(-1, 3)


if COMPILED:
    from llvmlite import ir
    from numba.core import cgutils, types
    from numba.extending import intrinsic

    def _caller(result_type, llvm_result):
        """An intrinsic ``f(function_address, state_address)``: call the C function ``result f(void *state)``."""

        @intrinsic
        def call(typingctx, function, state):
            def codegen(context, builder, signature, args):
                signature_ir = ir.FunctionType(llvm_result, [cgutils.voidptr_t])
                pointer = builder.inttoptr(args[0], signature_ir.as_pointer())
                return builder.call(pointer, [builder.inttoptr(args[1], cgutils.voidptr_t)])

            return result_type(types.int64, types.int64), codegen

        return call

    _next_uint64 = _caller(types.uint64, ir.IntType(64))
    _next_double = _caller(types.float64, ir.DoubleType())
else:  # pragma: no cover - without numba the callers draw through the generators

    def _next_uint64(function, state):
        raise RuntimeError("polyenvs.core.generators needs numba")

    _next_double = _next_uint64


@njit(cache=True)
def _standard_normal(address):
    """One draw of NumPy's ``random_standard_normal`` on the generator at ``address`` (a row of
    :func:`generator_addresses`)."""
    state, next_uint64, next_double = address[STATE], address[NEXT_UINT64], address[NEXT_DOUBLE]
    while True:
        layer, rabs, x, accepted = ziggurat.candidate(_next_uint64(next_uint64, state))
        if accepted:
            return x
        if layer == 0:  # the base layer's tail
            while True:
                u1 = _next_double(next_double, state)
                xx, accepted = ziggurat.tail_try(u1, _next_double(next_double, state))
                if accepted:
                    return ziggurat.tail_value(rabs, xx)
        elif ziggurat.wedge_accepts(layer, x, _next_double(next_double, state)):
            return x


@njit(cache=True)
def standard_normal_into(address, out):
    """Fill the C-contiguous 2-D ``out`` as ``Generator.standard_normal(out=out)`` would (row-major order)."""
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[i, j] = _standard_normal(address)


@njit(cache=True)
def random_into(address, out):
    """Fill the C-contiguous 2-D ``out`` as ``Generator.random(out=out)`` would."""
    next_double, state = address[NEXT_DOUBLE], address[STATE]
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[i, j] = _next_double(next_double, state)


@njit(cache=True)
def normals_then_uniforms(addresses, which, normals, uniforms):
    """For each batch entry ``b`` with ``which[b]`` set, ``standard_normal(out=normals[b])`` then
    ``random(out=uniforms[b])`` on generator ``addresses[b]``; ``normals`` and ``uniforms`` are C-contiguous
    ``(B, rows, columns)``."""
    for b in range(addresses.shape[0]):
        if which[b]:
            standard_normal_into(addresses[b], normals[b])
            random_into(addresses[b], uniforms[b])
