"""Our environments as benchmark cases, straight from the registry table ``polyenvs.registry.REGISTRY``.

Every entry is measured through ``gym.make`` (default wrappers, as a user gets it), and, where its
``vector_entry_point`` is set, as a native vector env of ``VECTOR_NUM_ENVS`` envs via ``gym.make_vec``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from benchmarks.harness import Case, env_case, one_line
from benchmarks.peers import SETTING_MAKE, SETTING_VECTOR, VECTOR_NUM_ENVS

__all__ = ["polyenvs_cases"]


def polyenvs_cases(*, only: str | None, min_seconds: float, seed: int = 0) -> tuple[list[Case], list[str]]:
    """Cases for the registry entries whose id contains ``only`` (all when ``None``): each id, then its vector env.

    Returns the cases and notes (an import failure, an ``only`` that matches nothing), so the peers are still
    measured while an environment is broken.
    """
    try:
        import polyenvs  # noqa: F401 - registers the ids
        from polyenvs.registry import REGISTRY
    except Exception as exc:  # noqa: BLE001 - a broken package must not hide the peers
        return [], [f"importing polyenvs failed ({one_line(exc)}): only the peers were measured."]

    # The PettingZoo swarms are measured per robot against mpe2 (benchmarks.swarm), not as Gymnasium steps.
    entries = [entry for entry in REGISTRY if entry.kind == "gymnasium" and (only is None or only in entry.id)]
    if not entries:
        return [], [f"no polyenvs environment id contains {only!r}: only the peers were measured."]
    kw: dict[str, Any] = {"min_seconds": min_seconds, "seed": seed}
    cases = []
    for entry in entries:
        cases.append(env_case(entry.id, SETTING_MAKE, _maker(entry.id), **kw))
        if entry.vector_entry_point:
            cases.append(env_case(entry.id, SETTING_VECTOR, _vector_maker(entry.id), vector=True, **kw))
    return cases, []


def _maker(env_id: str):
    return lambda: gym.make(env_id)


def _vector_maker(env_id: str):
    return lambda: gym.make_vec(env_id, num_envs=VECTOR_NUM_ENVS, vectorization_mode="vector_entry_point")
