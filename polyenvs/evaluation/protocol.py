"""The leaderboard's protocol: the seeds, the episode counts, the layouts and the policies every evaluation uses.

Every policy runs on the same published seeds (:data:`EVAL_SEED`, :data:`EVAL_SEED` + 1, ...), so comparisons are
paired, for :func:`protocol_episodes` episodes, on each of :data:`LAYOUTS`: the default layouts (today's episodes,
bit for bit) and the held-out ones (``layouts="test"``), each a result of its own (:func:`result_layouts`). The
verdict counts an agent trained on :data:`COUNTED_TRAINING_LAYOUTS` only, and a reproduction re-runs the first
:data:`REPRODUCE_EPISODES` episodes of each evaluation.
"""

from __future__ import annotations

import warnings
from contextlib import contextmanager

from polyenvs.registry import entry

__all__ = [
    "COUNTED_TRAINING_LAYOUTS",
    "EVAL_SEED",
    "LAYOUTS",
    "PROTOCOL_EPISODES",
    "REPRODUCE_EPISODES",
    "layouts_kwargs",
    "leaderboard_policies",
    "old_versions_quietly",
    "protocol_episodes",
    "result_layouts",
]

#: First evaluation seed; episodes use EVAL_SEED, EVAL_SEED + 1, ... for every policy.
EVAL_SEED = 1000
#: Episodes per policy in the reference leaderboard; fewer is "quick mode" and the table says so.
PROTOCOL_EPISODES = 50
#: The layouts every policy is evaluated on: the default (today's episodes) and the held-out test distribution
#: (``layouts="test"``, disjoint from the "train" one that training may use).
LAYOUTS = ("default", "test")
#: Episodes of each evaluation that a reproduction re-runs (the protocol's first seeds) to check a machine against
#: the reference results: a tenth of the protocol, so that every evaluation of the reference is checked within the
#: main job's 15 minutes on two cores (:func:`~polyenvs.evaluation.results.compare_with_reference`).
REPRODUCE_EPISODES = 5
#: The layouts an agent must have trained on for the verdict to count it (the Procgen protocol: train on the training
#: distribution, judge on the held-out one).
COUNTED_TRAINING_LAYOUTS = "train"


def protocol_episodes(env_id: str) -> int:
    """Episodes per policy in the protocol for ``env_id``: its score's own count, else :data:`PROTOCOL_EPISODES`."""
    score = entry(env_id).score
    return score.episodes if score is not None and score.episodes is not None else PROTOCOL_EPISODES


def leaderboard_policies(env_id: str) -> list[str]:
    """The policies the leaderboard evaluates on ``env_id``: random and every hand baseline ("paper" is an alias)."""
    from baselines import available_policies

    return [p for p in available_policies(env_id) if p != "paper"]


def layouts_kwargs(layouts: str) -> dict:
    """The environment keywords of a layout set: none for the default (today's episodes, bit for bit)."""
    return {} if layouts == "default" else {"layouts": layouts}


def result_layouts(doc: dict) -> str:
    """The layouts a result document was evaluated on (``env_kwargs["layouts"]``, else the default)."""
    kwargs = doc.get("env_kwargs")
    return str(kwargs.get("layouts", "default")) if isinstance(kwargs, dict) else "default"


@contextmanager
def old_versions_quietly():
    """Make environments without Gymnasium's "out of date" warning for an id with a newer version: the leaderboard
    evaluates every registered version on purpose (the -v0 ids stay, as Gymnasium keeps them, to compare)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r".*is out of date", category=DeprecationWarning)
        yield
