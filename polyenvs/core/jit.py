"""``njit`` from numba when it is installed, else a no-op decorator (the same code then runs as plain Python).

The hot loops of the simulators (rays x walls, robots x walls) are written once, as loops over a leading batch
axis, and compiled by numba: a batch of one then costs a few microseconds instead of the dozens of small-array
numpy calls it would take. ``cache=True`` keeps the compiled code next to the module, so a new process (a
subprocess vector env, say) loads it instead of compiling again.

Numba freezes module-level constants (column indices, lookup tables) into the compiled code and checks a cached
kernel only against its own file's timestamp: after changing a constant that kernels in *other* modules use, delete
the caches (``find polyenvs -name '*.nb[ic]' -delete``). A fresh install never has stale caches.
"""

from __future__ import annotations

__all__ = ["njit", "HAVE_NUMBA"]

try:
    from numba import njit

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - numba is a dependency; this keeps a broken install usable, slowly
    HAVE_NUMBA = False

    def njit(*args, **kwargs):
        if args and callable(args[0]):
            return args[0]
        return lambda function: function
