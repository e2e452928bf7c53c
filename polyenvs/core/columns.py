"""Named columns: the indices compiled kernels use, generated from declared names, so none is written by hand.

A task declares its reward terms and metrics as tuples of names. :class:`OutColumns` lays them out as the
``_out`` table of :class:`polyenvs.core.rows.RowsEnv` holds them (reward terms, metrics, then the reward and the
terminated flag) and gives each name its column; adding a metric is adding a name. The columns are plain ints
bound to module-level constants, which numba freezes into the compiled code, so a name costs nothing per step::

    REWARD_TERMS = ("progress", "blocked")
    METRICS = ("distance_cm",)
    OUT = OutColumns(REWARD_TERMS, METRICS)
    PROGRESS, BLOCKED = OUT.term_columns("progress", "blocked")  # looked up by name: order-proof
    DISTANCE = OUT.metric_column("distance_cm")
    REWARD, TERMINATED = OUT.reward, OUT.terminated

:func:`spans` does the same for an observation's named parts (``observation_structure``) and :func:`indices` for
any other named sequence (the arrays a kernel takes as one tuple).

:func:`write_reward` writes what every task's row ends with, the reward (the sum of its terms) and the terminated
flag: a family's compiled step calls it after the task scored the row, so no task writes either by hand.
"""

from __future__ import annotations

from polyenvs.core.jit import njit

__all__ = ["OutColumns", "indices", "spans", "write_reward"]


def _check_names(kind: str, names) -> tuple[str, ...]:
    names = tuple(names)
    for name in names:
        if not isinstance(name, str) or not name:
            raise TypeError(f"{kind} names must be non-empty strings, got {name!r}")
    if len(set(names)) != len(names):
        repeated = sorted({name for name in names if names.count(name) > 1})
        raise ValueError(f"{kind} names repeat: {repeated}")
    return names


def indices(names, start: int = 0) -> dict[str, int]:
    """``{name: index}`` for ``names`` in order, from ``start`` (names must be distinct)."""
    return {name: start + i for i, name in enumerate(_check_names("index", names))}


def spans(sizes: dict[str, int], start: int = 0) -> dict[str, tuple[int, int]]:
    """``{name: (start, stop)}`` for consecutive parts of the given sizes, from ``start`` (an
    ``observation_structure``)."""
    layout: dict[str, tuple[int, int]] = {}
    for name in _check_names("part", sizes):
        size = sizes[name]
        if not isinstance(size, int) or isinstance(size, bool) or size < 1:
            raise ValueError(f"part {name!r} must have a positive integer size, got {size!r}")
        layout[name] = (start, start + size)
        start += size
    return layout


class OutColumns:
    """The columns of a batched-rows ``_out`` table: each reward term, each metric, the reward, terminated.

    Args:
        terms: reward term names (``info["reward_<term>"]``), in their order in ``info``.
        metrics: metric names (``info["episode_metrics"]``), in their order there.

    A reward term and a metric may share a name (a task's ``coverage`` can be both): they are looked up apart.
    """

    def __init__(self, terms, metrics):
        self.terms = _check_names("reward term", terms)
        self.metrics = _check_names("metric", metrics)
        self._term_columns = indices(self.terms)
        self._metric_columns = indices(self.metrics, len(self.terms))
        #: The reward (the sum of the terms) and the terminated flag (1.0 or 0.0), after the metrics.
        self.reward = len(self.terms) + len(self.metrics)
        self.terminated = self.reward + 1
        #: The table's width.
        self.width = self.terminated + 1

    def __repr__(self) -> str:
        return f"OutColumns(terms={self.terms}, metrics={self.metrics})"

    def __eq__(self, other) -> bool:
        return isinstance(other, OutColumns) and (self.terms, self.metrics) == (other.terms, other.metrics)

    def __hash__(self) -> int:
        return hash((self.terms, self.metrics))

    def term_column(self, name: str) -> int:
        """The column of reward term ``name``."""
        if name not in self._term_columns:
            raise KeyError(f"no reward term {name!r}; the terms are {self.terms}")
        return self._term_columns[name]

    def metric_column(self, name: str) -> int:
        """The column of metric ``name``."""
        if name not in self._metric_columns:
            raise KeyError(f"no metric {name!r}; the metrics are {self.metrics}")
        return self._metric_columns[name]

    def term_columns(self, *names: str) -> tuple[int, ...]:
        """The columns of the reward terms ``names``, in the order asked."""
        return tuple(self.term_column(name) for name in names)

    def metric_columns(self, *names: str) -> tuple[int, ...]:
        """The columns of the metrics ``names``, in the order asked."""
        return tuple(self.metric_column(name) for name in names)

    @property
    def term_slice(self) -> slice:
        """The reward terms' columns."""
        return slice(0, len(self.terms))

    @property
    def metric_slice(self) -> slice:
        """The metrics' columns."""
        return slice(len(self.terms), self.reward)


@njit(cache=True)
def write_reward(b, out, terms, terminated):
    """Row ``b``'s reward and terminated flag, the last two columns of ``out`` (an :class:`OutColumns` table).

    The reward is the sum of the first ``terms`` columns (the task's reward terms) in their declared order,
    starting from the first term rather than from 0.0, so that a lone term of -0.0 stays -0.0 and every sum is the
    one a task's own ``a + b + c`` gave; ``terminated`` (a bool) is written as 1.0 or 0.0.
    """
    reward = out[b, 0] if terms > 0 else 0.0
    for j in range(1, terms):
        reward += out[b, j]
    width = out.shape[1]
    out[b, width - 2] = reward
    out[b, width - 1] = 1.0 if terminated else 0.0
