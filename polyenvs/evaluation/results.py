"""The leaderboard's result files, and the reproduction of the reference results.

Each (environment, policy, layouts) result, and each agent's training seed, is a JSON document at
:func:`result_path` under the results directory: the seeds, every episode's return, length and task metrics, the
policy's description (a trained model's SHA-256) and :func:`provenance`. :func:`load_result` says whether a file is
usable and, if not, why (unreadable, not a result, for another number of episodes or layouts, or of another version
of the model); :func:`stored_results` reads every usable one without evaluating anything.

A reproduction re-runs the first episodes of each evaluation of the committed reference and compares them with it
episode by episode (:func:`compare_with_reference`): episodes are deterministic, so any difference is this machine's
or this code's.
"""

from __future__ import annotations

import datetime
import json
import platform
import subprocess
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from polyenvs.errors import InputError
from polyenvs.evaluation.agents import Agent, agent_checksum, agent_name, find_agents
from polyenvs.evaluation.protocol import LAYOUTS, leaderboard_policies, result_layouts
from polyenvs.registry import slug

__all__ = [
    "Reproduction",
    "compare_with_reference",
    "evaluation_title",
    "load_result",
    "provenance",
    "result_path",
    "stored_results",
]

_REQUIRED_KEYS = ("env_id", "policy", "episodes", "summary", "n_episodes")


def provenance() -> dict:
    import gymnasium
    import numpy

    import polyenvs

    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    return {
        "versions": {
            "polyenvs": polyenvs.__version__,
            "gymnasium": gymnasium.__version__,
            "numpy": numpy.__version__,
            "python": platform.python_version(),
        },
        "git_commit": commit or None,
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }


def result_path(results_dir: Path, env_id: str, policy: str, layouts: str = "default") -> Path:
    """``<results_dir>/<env id with / as __>__<policy>.json`` (``...__layouts-<name>.json`` for other layouts than
    the default); an agent's ``policy`` here is its :attr:`~polyenvs.evaluation.agents.Agent.key`."""
    suffix = "" if layouts == "default" else f"__layouts-{layouts}"
    return Path(results_dir) / f"{slug(env_id)}__{policy}{suffix}.json"


def evaluation_title(env_id: str, name: str, layouts: str) -> str:
    """How progress and reproduction lines name an evaluation: ``<env id> ppo seed0 (layouts=test)``."""
    return f"{env_id} {name}" + ("" if layouts == "default" else f" (layouts={layouts})")


def _same_policy(stored: str, policy: str, sha256: str | None) -> bool:
    """Whether a result names ``policy``: a hand policy by its name; a trained model (``sha256`` given, checked
    apart) by its path's last three parts (environment, row, seed), since the same agents are named by another path
    from another directory (the reference's ``benchmarks/agents/...`` is ``/clone/benchmarks/agents/...`` there)."""
    if stored == policy:
        return True
    return sha256 is not None and Path(stored).parts[-3:] == Path(policy).parts[-3:]


def load_result(
    path: Path,
    env_id: str,
    policy: str,
    episodes: int | None = None,
    sha256: str | None = None,
    layouts: str = "default",
) -> tuple[dict | None, str | None]:
    """``(document, None)`` if ``path`` holds a usable result, else ``(None, why not)``; ``(None, None)`` if absent.

    Usable: valid JSON, a result document for ``env_id`` and ``policy`` with its episodes, (when ``episodes`` is
    given) exactly that many episodes, (when ``sha256`` is given, for a trained model) of that model, and on
    ``layouts``.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None, None
    except (OSError, UnicodeDecodeError) as exc:
        return None, f"it cannot be read ({exc})"
    if not text.strip():
        return None, "it is empty"
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        return None, f"it is not valid JSON ({exc})"
    if not isinstance(doc, dict) or any(k not in doc for k in _REQUIRED_KEYS):
        missing = [k for k in _REQUIRED_KEYS if not isinstance(doc, dict) or k not in doc]
        return None, f"it is not a results document (missing {', '.join(missing)})"
    if doc["env_id"] != env_id or not _same_policy(str(doc["policy"]), policy, sha256):
        return None, f"it holds {doc['env_id']} {doc['policy']}, not {env_id} {policy}"
    n = doc["n_episodes"]
    if not isinstance(doc["episodes"], list) or not doc["episodes"] or len(doc["episodes"]) != n:
        return None, f"it does not hold its {n!r} episodes"
    if result_layouts(doc) != layouts:
        return None, f"it was evaluated on layouts {result_layouts(doc)!r}, not {layouts!r}"
    if episodes is not None and n != episodes:
        return None, f"it has {n} episodes, not {episodes}"
    if sha256 is not None:
        description = doc.get("policy_description")
        if not isinstance(description, dict) or description.get("sha256") != sha256:
            return None, "it evaluated another version of the model (its SHA-256 differs)"
    return doc, None


def stored_results(
    env_ids: list[str], results_dir: Path, progress: Callable[[str], None] = print, agents_dir: Path | None = None
) -> list[dict]:
    """Every usable result in ``results_dir`` for ``env_ids`` (any episode count), without evaluating anything.

    Includes the committed agents under ``agents_dir`` whose results are there and of the same model. Unusable
    files (and unusable agent directories) are skipped, and ``progress`` says which and why.
    """
    documents = []
    for env_id in env_ids:
        entries: list[tuple[str, str, Agent | None]] = [(p, p, None) for p in leaderboard_policies(env_id)]
        try:
            entries += [(a.path, a.key, a) for a in find_agents(agents_dir, env_id)]
        except InputError as exc:
            progress(f"{env_id}: agents left out of the table: {exc}")
        for policy, key, agent in entries:
            sha = agent_checksum(agent) if agent is not None else None
            for layouts in LAYOUTS:
                path = result_path(results_dir, env_id, key, layouts)
                doc, why = load_result(path, env_id, policy, sha256=sha, layouts=layouts)
                if doc is not None:
                    if agent is not None:
                        doc["agent"] = agent.meta()
                    documents.append(doc)
                elif why is not None:
                    progress(f"{env_id} {agent.name if agent else policy}: left out of the table: {path}: {why}")
    return documents


@dataclass
class Reproduction:
    """How re-run episodes compare with the reference's episodes of the same seeds (:func:`compare_with_reference`)."""

    same: int = 0  # episodes identical to the reference's: return, length and every metric
    differ: list[str] = field(default_factory=list)  # a line per evaluation with an episode that is not
    absent: list[str] = field(default_factory=list)  # a line per evaluation the reference cannot be compared on

    def summary(self) -> str:
        line = f"reproduced {self.same} episodes of the reference exactly"
        if self.differ:
            line += f"; {len(self.differ)} evaluation{'s' if len(self.differ) != 1 else ''} differ"
        if self.absent:
            line += f"; {len(self.absent)} not in the reference"
        return line


def _identity(doc: dict) -> tuple:
    """What a result is of, whichever directory its agent was found in: environment, layouts and policy (an agent
    by its row, ``ppo`` or ``ppo_residual_paper`` for instance, and its training seed)."""
    agent = doc.get("agent")
    return doc["env_id"], result_layouts(doc), (agent["label"], agent["training_seed"]) if agent else doc["policy"]


def _title(doc: dict) -> str:
    agent = doc.get("agent")
    name = agent_name(agent["label"], agent["training_seed"]) if agent else doc["policy"]
    return evaluation_title(doc["env_id"], name, result_layouts(doc))


def _canonical(episode: dict, recorded: dict) -> str:
    """``episode`` as text, with only the metrics that ``recorded`` (the reference's episode) has: a metric added
    to an environment since the reference was made is new information, not a change to the episode."""
    metrics = {k: v for k, v in episode.get("metrics", {}).items() if k in recorded.get("metrics", {})}
    return json.dumps({**episode, "metrics": metrics}, sort_keys=True)  # the same text is the same bits


def compare_with_reference(sample: list[dict], reference: list[dict]) -> Reproduction:
    """Compare each document of ``sample`` (a re-run of the protocol's first seeds) episode by episode with the
    document of ``reference`` (:func:`stored_results` of the reference results) of the same environment, layouts
    and policy.

    Episodes are deterministic (same seed, same episode, on any machine), so a re-run episode that differs in its
    return, its length or any metric the reference recorded means that this machine or this code does not reproduce
    the reference (a metric added since, such as the beasts' power, is not compared).
    """
    by_identity = {_identity(doc): doc for doc in reference}
    result = Reproduction()
    for doc in sample:
        ref = by_identity.get(_identity(doc))
        ours = doc["episodes"]
        if ref is None or len(ref["episodes"]) < len(ours):
            why = "not in the reference" if ref is None else f"the reference has {len(ref['episodes'])} episodes"
            result.absent.append(f"{_title(doc)}: {why} (evaluate it with the full protocol)")
            continue
        differing = [
            a["seed"] for a, b in zip(ours, ref["episodes"], strict=False) if _canonical(a, b) != _canonical(b, b)
        ]
        result.same += len(ours) - len(differing)
        if differing:
            result.differ.append(f"{_title(doc)}: seeds {', '.join(map(str, differing))} differ from the reference")
    return result
