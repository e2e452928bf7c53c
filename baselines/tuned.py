"""A tuned hand baseline: the directory ``polyenvs tune`` writes, as a policy wherever a trained agent goes.

The directory holds ``tuned.json``: the environment, the hand baseline (its name in :mod:`baselines.table`), the
parameters the search chose (names from the baseline's :attr:`~baselines.base.Policy.tunables`), the study's
history, the command, the wall clock and the versions. :func:`load_tuned_policy` rebuilds the baseline with those
parameters; the policy it returns names the parameters by SHA-256 in :meth:`TunedPolicy.describe`, as a trained
model is named by its files' checksum, so a result records exactly what it evaluated. Reading the file needs nothing
beyond the baselines (no Optuna: the search is :mod:`polyenvs.training.tune`'s).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from baselines.factory import make_baseline
from polyenvs.registry import bare_id

__all__ = ["TUNED_FILE", "TunedPolicy", "is_tuned_path", "load_tuned_policy", "read_tuned", "tuned_checksum"]

#: The file that makes a directory a tuned baseline.
TUNED_FILE = "tuned.json"


def is_tuned_path(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a tuned baseline's directory (it holds :data:`TUNED_FILE`)."""
    return (Path(path) / TUNED_FILE).is_file()


def read_tuned(path: str | os.PathLike) -> dict[str, Any]:
    """The ``tuned.json`` of directory ``path``, checked to name an environment, a baseline and numeric parameters;
    ``ValueError`` naming the file otherwise."""
    file = Path(path) / TUNED_FILE
    try:
        doc = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{file}: cannot be read as JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise ValueError(f"{file}: must be a JSON object")
    for key in ("env_id", "policy"):
        if not isinstance(doc.get(key), str) or not doc[key]:
            raise ValueError(f"{file}: {key} must be a non-empty string, got {doc.get(key)!r}")
    params = doc.get("params")
    if not isinstance(params, dict) or not all(_is_number(v) for v in params.values()):
        raise ValueError(f"{file}: params must be an object of numbers, got {params!r}")
    return doc


def _is_number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def tuned_checksum(doc: dict) -> str:
    """SHA-256 of what a tuned baseline acts by (its baseline and parameters), not of the history around them."""
    acting = json.dumps({"policy": doc["policy"], "params": doc["params"]}, sort_keys=True)
    return hashlib.sha256(acting.encode()).hexdigest()


class TunedPolicy:
    """A hand baseline built with tuned parameters: its ``predict``, and a description that says so."""

    def __init__(self, base, path: str, doc: dict):
        self.base, self.path, self.doc = base, path, doc
        self.observation_space, self.action_space = base.observation_space, base.action_space

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        return self.base.predict(observation, state=state, episode_start=episode_start, deterministic=deterministic)

    def describe(self) -> dict:
        """The baseline's description, the tuned parameters, the tuning seed and the checksum (stored with results)."""
        return {
            **self.base.describe(),
            "tuned": self.path,
            "baseline": self.doc["policy"],
            "params": dict(self.doc["params"]),
            "tuning_seed": self.doc.get("seed"),
            "sha256": tuned_checksum(self.doc),
        }


def load_tuned_policy(
    path: str | os.PathLike, env_id: str, observation_space, action_space, seed: int | None = None, **kwargs
) -> TunedPolicy:
    """The tuned baseline in directory ``path`` for ``env_id``: ``ValueError`` for one tuned on another environment,
    extra parameters, or parameters the baseline refuses."""
    if kwargs:
        raise ValueError(
            f"{path}: a tuned baseline takes no parameters (they are its tuned.json's), got {sorted(kwargs)}"
        )
    doc = read_tuned(path)
    tuned_on, env_id = bare_id(doc["env_id"]), bare_id(env_id)
    if tuned_on != env_id:
        raise ValueError(f"{path}: tuned on {tuned_on}, not {env_id}")
    base = make_baseline(doc["policy"], env_id, observation_space, action_space, seed=seed, **doc["params"])
    return TunedPolicy(base, os.fspath(path), doc)
