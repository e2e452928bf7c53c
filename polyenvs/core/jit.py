"""``njit`` from numba when it is installed, else a no-op decorator (the same code then runs as plain Python), and
:class:`KernelArgs`, the one argument a family's compiled step and reset take besides the rows.

The hot loops of the simulators (rays x walls, robots x walls) are written once, as loops over a leading batch
axis, and compiled by numba: a batch of one then costs a few microseconds instead of the dozens of small-array
numpy calls it would take. ``cache=True`` keeps the compiled code next to the module, so a new process (a
subprocess vector env, say) loads it instead of compiling again.

Numba freezes module-level constants (column indices, lookup tables) into the compiled code and checks a cached
kernel only against its own file's timestamp: after changing a constant that kernels in *other* modules use, delete
the caches (``find polyenvs -name '*.nb[ic]' -delete``). A fresh install never has stale caches.

Packed arguments. Inside compiled code, arrays travel in tuples (``sim = (state, walls, params, ...)``), which
numba passes and unpacks for free. At the boundary with Python they cost: numba types and unboxes a tuple of
arrays element by element at every call, about 0.07 µs an array against 0.045 µs for a plain argument (measured,
numba 0.68), so a single env's step over 16 arrays would pay 0.3-0.5 µs more than with positional arguments. A
:class:`KernelArgs` is a numba StructRef holding the three parts a kernel takes, ``sim`` (the simulator's tuple),
``out`` (the reward and metric table) and ``task`` (the task's tuple); it crosses the boundary as one pointer, about
0.3 µs whatever it holds, so a step dispatches faster than with positional arrays. Build it once and again only when
one of its arrays is replaced; it is not picklable (an environment rebuilds it, see
:class:`polyenvs.core.rows.RowsEnv`).

Dispatch. Calling a compiled function through numba's dispatcher types every argument first; a StructRef has no
fast path there (numba asks Python for its type), which cost about 40% of a single Buckybot step's kernel call.
:func:`compiled_for` returns the machine code for one set of argument types (``Dispatcher.compile``: from the cache
when it holds it), which a caller that always passes arrays of those types can call directly.
"""

from __future__ import annotations

__all__ = ["HAVE_NUMBA", "KernelArgs", "compiled_for", "njit"]

try:
    from numba import njit
    from numba.core.config import DISABLE_JIT

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - numba is a dependency; this keeps a broken install usable, slowly
    HAVE_NUMBA, DISABLE_JIT = False, True

    def njit(*args, **kwargs):
        if args and callable(args[0]):
            return args[0]
        return lambda function: function


def compiled_for(function, *args):
    """``function`` (an ``njit`` function) compiled for the numba types of ``args``, callable without the per-call
    type dispatch; ``function`` itself when nothing is compiled.

    The result does not check its arguments: call it only with arguments of the types of ``args`` (the same arrays,
    say), and get it again after replacing one of them with an array of another type.
    """
    if DISABLE_JIT:
        return function
    from numba import typeof

    return function.compile(tuple(typeof(arg) for arg in args))


if not DISABLE_JIT:
    from numba.core import types
    from numba.experimental import structref

    @structref.register
    class KernelArgsType(types.StructRef):
        """Numba's type of a :class:`KernelArgs`: one per combination of its parts' types."""

        def preprocess_fields(self, fields):
            return tuple((name, types.unliteral(typ)) for name, typ in fields)

    class KernelArgs(structref.StructRefProxy):
        """The parts a compiled step or reset takes, as one argument: ``sim``, ``out`` and ``task``, read in compiled
        code as ``kernel.sim``, ``kernel.out``, ``kernel.task`` (see the module docstring)."""

        def __new__(cls, sim, out, task):
            # Built by a cached compiled function: StructRefProxy's own constructor compiles afresh in every
            # process (about 1.4 s of the first gym.make).
            return _new_kernel_args(sim, out, task)

        def __reduce__(self):
            raise TypeError("KernelArgs is not picklable: pickle the arrays and build it again")

    structref.define_proxy(KernelArgs, KernelArgsType, ["sim", "out", "task"])

    @njit(cache=True)
    def _new_kernel_args(sim, out, task):
        return KernelArgs(sim, out, task)

else:  # pragma: no cover - without compilation the kernels run as Python and read the same attributes

    class KernelArgs:
        """The parts a step or reset takes (plain Python: numba is absent or disabled)."""

        __slots__ = ("sim", "out", "task")

        def __init__(self, sim, out, task):
            self.sim, self.out, self.task = sim, out, task

        def __reduce__(self):
            raise TypeError("KernelArgs is not picklable: pickle the arrays and build it again")
