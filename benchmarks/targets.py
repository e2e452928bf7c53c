"""The performance spec's targets (``performance.md``, "Targets" and "Memory") as data, and how a row is checked.

Each target names our rows by id prefix (and, where the spec differs per task, by task name), the kind of row, the
minimum ratio to each peer measured in the same run, and a memory budget. Rows of the spec that this benchmark
does not measure yet are left out rather than half-checked: Beast against raw ``mj_step`` on its own model, Swarm at
N = 20 and N = 256, and the bump-space localizer (each needs a setting of its own once the family exists).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum

from benchmarks.peers import ANT, CARTPOLE, MINIGRID, VMAS_NAVIGATION

__all__ = ["TARGETS", "Kind", "Ratio", "Target", "target_for"]


class Kind(StrEnum):
    """The kind of row a target applies to; a ratio compares rows of the same kind."""

    MAKE = "make"  # one env through gym.make, steps/s
    VECTOR = "vector"  # a native vector env, env-steps/s
    PPO = "ppo"  # SB3 PPO training, timesteps/s


@dataclass(frozen=True)
class Ratio:
    """At least ``minimum`` times the rate of the peer row ``peer`` (of the same kind), measured in the same run."""

    peer: str
    minimum: float
    label: str


@dataclass(frozen=True)
class Target:
    """One row of the spec's target table."""

    prefix: str
    kind: Kind
    ratios: tuple[Ratio, ...]
    max_memory_mb: float | None = None
    #: Task names (parts of the id) the row is limited to; empty for every id with ``prefix``.
    tasks: tuple[str, ...] = ()

    def applies_to(self, env_id: str, kind: Kind) -> bool:
        """Whether this target is the one for ``env_id`` measured as ``kind``."""
        if kind != self.kind or not env_id.startswith(self.prefix):
            return False
        return not self.tasks or any(task in env_id for task in self.tasks)

    def describe(self) -> str:
        """The target as a table shows it, e.g. ``>= 0.6x CartPole-v1, >= 10x MiniGrid, < 5 MB``."""
        parts = [f">= {ratio.minimum:g}x {ratio.label}" for ratio in self.ratios]
        if self.max_memory_mb is not None:
            parts.append(f"< {self.max_memory_mb:g} MB")
        return ", ".join(parts)

    def verdict(self, ratios: Mapping[str, float | None], peak_memory_mb: float | None) -> str:
        """``yes`` / ``no`` over every ratio and the memory budget, naming what could not be checked in this run.

        ``ratios[peer]`` is the row's ratio to that peer (``None`` or absent when the row or the peer is missing).
        Blank when nothing could be checked.
        """
        passed: list[bool] = []
        unchecked: list[str] = []
        for ratio in self.ratios:
            value = ratios.get(ratio.peer)
            if value is None:
                unchecked.append(ratio.label)
            else:
                passed.append(value >= ratio.minimum)
        if self.max_memory_mb is not None:
            if peak_memory_mb is None:
                unchecked.append("memory")
            else:
                passed.append(peak_memory_mb < self.max_memory_mb)
        if not passed:
            return ""
        verdict = "yes" if all(passed) else "no"
        return f"{verdict} ({', '.join(unchecked)} unchecked)" if unchecked else verdict


_CARTPOLE = Ratio(CARTPOLE, 0.6, "CartPole-v1")
#: The spec's target table, most specific rows first (the first that applies is used).
TARGETS: tuple[Target, ...] = (
    Target("polyenvs/Buckybot", Kind.MAKE, (_CARTPOLE, Ratio(MINIGRID, 10.0, "MiniGrid")), max_memory_mb=5.0),
    Target(
        "polyenvs/Buckybot",
        Kind.VECTOR,
        (Ratio(CARTPOLE, 0.15, "CartPole vector env"),),
        max_memory_mb=200.0,
        tasks=("WallFollow", "Goal"),
    ),
    Target(
        "polyenvs/Buckybot",
        Kind.VECTOR,
        (Ratio(CARTPOLE, 0.08, "CartPole vector env"),),
        max_memory_mb=200.0,
        tasks=("Explore",),
    ),
    Target("polyenvs/Bumper", Kind.MAKE, (Ratio(CARTPOLE, 0.1, "CartPole-v1"),), max_memory_mb=5.0),
    Target("polyenvs/Beast", Kind.MAKE, (Ratio(ANT, 1.0, "Ant-v5"),)),
    Target("polyenvs/Swarm", Kind.VECTOR, (Ratio(VMAS_NAVIGATION, 1.0, "VMAS navigation"),)),
    Target("polyenvs/", Kind.PPO, (Ratio(CARTPOLE, 0.8, "PPO on CartPole"),)),
)


def target_for(env_id: str, kind: Kind, targets: Sequence[Target] = TARGETS) -> Target | None:
    """The spec's target for ``env_id`` measured as ``kind``, or ``None``."""
    return next((target for target in targets if target.applies_to(env_id, kind)), None)
