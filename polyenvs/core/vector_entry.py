"""Native vector envs given the env class: ``gym.make_vec(id, num_envs=N)`` without a vector class per task.

A family's env base names the vector env that runs its tasks, ``VectorEnv = NativeVector(TheFamilysVectorEnv)``
(:class:`polyenvs.core.rows.RowsEnv` does: :class:`~polyenvs.core.rows.RowsVectorEnv`); every task class then has
its own, ``TaskEnv.VectorEnv``: the family's vector env with ``env_class = TaskEnv``, made once, at first use. It
pickles by that name, as a class written in the task's module would.

Gymnasium reaches it through the registration's ``vector_entry_point``, which must stay a string: Minari stores an
``EnvSpec`` as JSON, and ``EnvSpec.to_json`` refuses a callable. A registry row with ``native_vector=True`` registers
:func:`vector_entry_point` of its entry point, ``"polyenvs.core.vector_entry:<module>.<Class>"``; ``gym.make_vec``
loads it as ``getattr(import_module("polyenvs.core.vector_entry"), "<module>.<Class>")``, which this module's
``__getattr__`` (PEP 562) answers with ``<Class>.VectorEnv``.
"""

from __future__ import annotations

import importlib
from typing import Generic, TypeVar

__all__ = ["NativeVector", "vector_entry_point"]

#: The attribute of an env class that holds its native vector env.
ATTRIBUTE = "VectorEnv"

V = TypeVar("V", bound=type)


class NativeVector(Generic[V]):
    """A class attribute ``VectorEnv`` that is, on each env class that reads it, ``base`` bound to that class: a
    subclass of ``base`` whose ``env_class`` is the env class (one per env class, made at first use)."""

    def __init__(self, base: V):
        self.base = base
        self._bound: dict[type, V] = {}

    def __get__(self, instance, env_class: type) -> V:
        vector = self._bound.get(env_class)
        if vector is None:
            vector = self._bound[env_class] = self._bind(env_class)
        return vector

    def _bind(self, env_class: type) -> V:
        where = f"{env_class.__module__}.{env_class.__qualname__}"
        namespace = {
            "env_class": env_class,
            # Where pickle finds it again: the env class's attribute, in the env class's module.
            "__module__": env_class.__module__,
            "__qualname__": f"{env_class.__qualname__}.{ATTRIBUTE}",
            "__doc__": f"Vector form of :class:`~{where}` (same arguments and reset options), ``num_envs`` of it "
            f"behind :class:`~{self.base.__module__}.{self.base.__qualname__}`.",
        }
        return type(self.base)(env_class.__name__.removesuffix("Env") + "VectorEnv", (self.base,), namespace)


def vector_entry_point(entry_point: str) -> str:
    """The ``vector_entry_point`` string of the env class at ``entry_point`` (``"module:Class"``)."""
    module, _, name = entry_point.partition(":")
    return f"{__name__}:{module}.{name}"


def __getattr__(name: str):
    """``"<module>.<Class>"`` -> that class's native vector env (what Gymnasium's ``load_env_creator`` asks)."""
    module, _, class_name = name.rpartition(".")
    if not module:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    env_class = getattr(importlib.import_module(module), class_name)
    try:
        return getattr(env_class, ATTRIBUTE)
    except AttributeError:
        raise AttributeError(f"{name} has no native vector env (no {ATTRIBUTE} attribute)") from None
