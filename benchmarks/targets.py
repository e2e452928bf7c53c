"""The throughput targets as data: issue 33's table (which raised issue 19's, itself superseding ``performance.md``'s
where they differ), with the spec's memory budgets, and how a figure is checked against them.

Two kinds of target, and every module of ``benchmarks/`` reads its targets (and the text it prints for them) here:

- :data:`TARGETS`, rows of the main table (``benchmarks.report``): our ids by prefix (and task, where the target
  differs per task), the kind of row, the minimum ratio to each peer measured in the same run, and a memory budget;
- :data:`SCALAR_TARGETS`, single figures a family's own benchmark measures (a ratio to a peer of its own, an
  absolute rate, an upper bound on an overhead or a time), each a :class:`Bound`.

A :class:`Bound` prints itself (:meth:`Bound.note`: ``(target >= 20,000)``) and says whether a figure meets it
(:meth:`Bound.met_by`); ratios and memory budgets of :data:`TARGETS` are checked and printed through the same class.
"""

from __future__ import annotations

import operator
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum

from benchmarks.peers import ANT, CARTPOLE, MINIGRID

__all__ = ["SCALAR_TARGETS", "TARGETS", "Bound", "Direction", "Kind", "Ratio", "Target", "target_for"]


class Kind(StrEnum):
    """The kind of row a target applies to; a ratio compares rows of the same kind."""

    MAKE = "make"  # one env through gym.make, steps/s
    VECTOR = "vector"  # a native vector env, env-steps/s
    PPO = "ppo"  # SB3 PPO training, timesteps/s


class Direction(StrEnum):
    """How a measured figure must compare with a bound's value (the member's value is the operator as printed)."""

    AT_LEAST = ">="
    AT_MOST = "<="
    BELOW = "<"


_COMPARE = {Direction.AT_LEAST: operator.ge, Direction.AT_MOST: operator.le, Direction.BELOW: operator.lt}


@dataclass(frozen=True)
class Bound:
    """A figure's target: ``value`` with the direction a measurement must lie in, and the unit printed after it."""

    value: float
    direction: Direction = Direction.AT_LEAST
    #: Printed right after the value: ``"x"`` for a ratio (``>= 4x``), ``" MB"``, ``" s"``; empty for a rate.
    unit: str = ""

    def describe(self) -> str:
        """The bound as text, e.g. ``>= 20,000``, ``<= 1.03x``, ``< 50 MB``."""
        return f"{self.direction} {self.value:,g}{self.unit}"

    def met_by(self, measured: float) -> bool:
        """Whether ``measured`` meets the bound."""
        return _COMPARE[self.direction](measured, self.value)

    def note(self, measured: float | None = None) -> str:
        """The parenthesis a benchmark prints after a figure: ``(target >= 20,000)``, or with the measured figure
        ``(target >= 20,000: met)`` / ``(target >= 20,000: missed)``."""
        if measured is None:
            return f"(target {self.describe()})"
        return f"(target {self.describe()}: {'met' if self.met_by(measured) else 'missed'})"


@dataclass(frozen=True)
class Ratio:
    """At least ``minimum`` times the rate of the peer row ``peer`` (of the same kind), measured in the same run."""

    peer: str
    minimum: float
    label: str

    @property
    def bound(self) -> Bound:
        return Bound(self.minimum, Direction.AT_LEAST, "x")


@dataclass(frozen=True)
class Target:
    """One row of the target table."""

    prefix: str
    kind: Kind
    ratios: tuple[Ratio, ...]
    max_memory_mb: float | None = None
    #: Task names (parts of the id) the row is limited to; empty for every id with ``prefix``.
    tasks: tuple[str, ...] = ()
    #: Why the row has no ratio, where it has none (its rate has a target elsewhere); shown with the budget.
    note: str = ""

    def applies_to(self, env_id: str, kind: Kind) -> bool:
        """Whether this target is the one for ``env_id`` measured as ``kind``."""
        if kind != self.kind or not env_id.startswith(self.prefix):
            return False
        return not self.tasks or any(task in env_id for task in self.tasks)

    def ratio_to(self, peer: str) -> Ratio:
        """This row's ratio target against ``peer``; ``KeyError`` if it has none."""
        for ratio in self.ratios:
            if ratio.peer == peer:
                return ratio
        raise KeyError(f"{self.prefix} ({self.kind}) has no target against {peer}")

    @property
    def memory(self) -> Bound | None:
        return None if self.max_memory_mb is None else Bound(self.max_memory_mb, Direction.BELOW, " MB")

    def describe(self) -> str:
        """The target as a table shows it, e.g. ``>= 1x CartPole-v1, >= 10x MiniGrid, < 5 MB``."""
        parts = [f"{ratio.bound.describe()} {ratio.label}" for ratio in self.ratios]
        if self.memory is not None:
            parts.append(self.memory.describe())
        if self.note:
            parts.append(self.note)
        return ", ".join(parts)

    def verdict(self, ratios: Mapping[str, float | None], peak_memory_mb: float | None) -> str:
        """``yes`` / ``no`` over every ratio and the memory budget, naming what could not be checked in this run.

        ``ratios[peer]`` is the row's ratio to that peer (``None`` or absent when the row or the peer is missing).
        Blank when nothing could be checked. A row with a memory budget only answers on memory alone, and says so.
        """
        passed: list[bool] = []
        unchecked: list[str] = []
        for ratio in self.ratios:
            value = ratios.get(ratio.peer)
            if value is None:
                unchecked.append(ratio.label)
            else:
                passed.append(ratio.bound.met_by(value))
        if self.memory is not None:
            if peak_memory_mb is None:
                unchecked.append("memory")
            else:
                passed.append(self.memory.met_by(peak_memory_mb))
        if not passed:
            return ""
        verdict = "yes" if all(passed) else "no"
        if not self.ratios:
            return f"{verdict} (memory only)"
        return f"{verdict} ({', '.join(unchecked)} unchecked)" if unchecked else verdict


_CARTPOLE_VECTOR = "CartPole vector env"
#: The main table's targets, most specific rows first (the first that applies is used).
TARGETS: tuple[Target, ...] = (
    Target(
        "polyenvs/Buckybot",
        Kind.MAKE,
        (Ratio(CARTPOLE, 1.0, "CartPole-v1"), Ratio(MINIGRID, 10.0, "MiniGrid")),
        max_memory_mb=5.0,
    ),
    Target(
        "polyenvs/Buckybot",
        Kind.VECTOR,
        (Ratio(CARTPOLE, 0.35, _CARTPOLE_VECTOR),),
        max_memory_mb=200.0,
        tasks=("WallFollow", "Goal"),
    ),
    Target(
        "polyenvs/Buckybot",
        Kind.VECTOR,
        (Ratio(CARTPOLE, 0.15, _CARTPOLE_VECTOR),),
        max_memory_mb=200.0,
        tasks=("Explore",),
    ),
    Target(
        "polyenvs/BumperCart", Kind.MAKE, (Ratio(CARTPOLE, 0.6, "CartPole-v1"),), max_memory_mb=5.0, tasks=("Explore",)
    ),
    # Localize's step is the localizer's update, whose rate has its own target (localizer_updates_per_s).
    Target(
        "polyenvs/BumperCart",
        Kind.MAKE,
        (),
        max_memory_mb=5.0,
        tasks=("Localize",),
        note="rate: see the localizer's updates/s",
    ),
    Target("polyenvs/BumperCart", Kind.VECTOR, (Ratio(CARTPOLE, 0.06, _CARTPOLE_VECTOR),), tasks=("Explore",)),
    Target("polyenvs/APLite", Kind.MAKE, (Ratio(CARTPOLE, 0.4, "CartPole-v1"),), tasks=("Corridor", "ObstacleField")),
    Target("polyenvs/Beast", Kind.MAKE, (Ratio(ANT, 1.0, "Ant-v5"),)),
    # Localize's every step is a localizer update over 1,000 particles: PPO on it may cost a little more than on CartPole.
    Target("polyenvs/BumperCart", Kind.PPO, (Ratio(CARTPOLE, 0.8, "PPO on CartPole"),), tasks=("Localize",)),
    Target("polyenvs/", Kind.PPO, (Ratio(CARTPOLE, 1.0, "PPO on CartPole"),)),
)

#: Figures the families' own benchmarks measure, by name.
SCALAR_TARGETS: dict[str, Bound] = {
    # agent-steps/s of each swarm module at N = 20 over mpe2 simple_spread_v3's at N = 20 (benchmarks.swarm)
    "swarm_vs_mpe2_at_20": Bound(100.0, unit="x"),
    # joint steps/s of a 256-robot swarm, and its peak traced memory
    "swarm_joint_steps_per_s_at_256": Bound(200.0),
    "swarm_memory_mb_at_256": Bound(50.0, Direction.BELOW, " MB"),
    # env-steps/s of the batched swarm, 1,024 envs x 4 robots, over VMAS navigation's, one torch thread
    "batched_swarm_vs_vmas": Bound(4.0, unit="x"),
    # a beast's step through gym.make over raw mj_step(nstep=frame_skip) on its own model (benchmarks.beast)
    "beast_vs_raw_mj_step": Bound(1.10, Direction.AT_MOST, "x"),
    # env-steps/s of a beast id's native vector env, 8 envs on the machine's cores, over one env's steps/s on one core
    "beast_vector_vs_single": Bound(1.7, unit="x"),
    # bump-space MCL updates/s at 1,000 particles, with its estimate (benchmarks.bumper)
    "localizer_updates_per_s": Bound(20_000.0),
    # import + gym.make + reset + one step in a fresh process once the numba cache exists (benchmarks.first_step)
    "first_step_s": Bound(1.0, Direction.AT_MOST, " s"),
}


def target_for(env_id: str, kind: Kind, targets: Sequence[Target] | None = None) -> Target | None:
    """The target for ``env_id`` measured as ``kind`` among ``targets`` (:data:`TARGETS` when ``None``, read at each
    call), or ``None``."""
    rows = TARGETS if targets is None else targets
    return next((target for target in rows if target.applies_to(env_id, kind)), None)
