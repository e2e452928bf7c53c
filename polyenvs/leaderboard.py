"""Evaluate every policy on every environment and build the leaderboard table (``polyenvs leaderboard``).

Each (environment, policy) result is a JSON file under the results directory, written atomically; a re-run skips
what is done unless asked to redo it, and re-runs (saying why) a file that is unreadable, not a result, or for
another number of episodes. The table follows RL Zoo's ``benchmark.md`` columns plus the interquartile mean with
its 95% bootstrap interval, a score normalised so that random = 0 and the paper's baseline = 1, and the
environment's task metrics.
"""

from __future__ import annotations

import datetime
import json
import platform
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np

from polyenvs.evaluation import evaluate, iqm_with_ci, write_json_atomic, write_text_atomic

__all__ = [
    "EVAL_SEED",
    "PROTOCOL_EPISODES",
    "leaderboard_markdown",
    "leaderboard_policies",
    "load_result",
    "result_path",
    "run_leaderboard",
    "stored_results",
    "write_leaderboard",
]

#: First evaluation seed; episodes use EVAL_SEED, EVAL_SEED + 1, ... for every policy.
EVAL_SEED = 1000
#: Episodes per policy in the reference leaderboard; fewer is "quick mode" and the table says so.
PROTOCOL_EPISODES = 50
_REQUIRED_KEYS = ("env_id", "policy", "episodes", "summary", "n_episodes")


def _provenance() -> dict:
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


def result_path(results_dir: Path, env_id: str, policy: str) -> Path:
    return Path(results_dir) / f"{env_id.replace('/', '__')}__{policy}.json"


def leaderboard_policies(env_id: str) -> list[str]:
    """The policies the leaderboard evaluates on ``env_id``: random and every hand baseline ("paper" is an alias)."""
    from baselines import available_policies

    return [p for p in available_policies(env_id) if p != "paper"]


def load_result(path: Path, env_id: str, policy: str, episodes: int | None = None) -> tuple[dict | None, str | None]:
    """``(document, None)`` if ``path`` holds a usable result, else ``(None, why not)``; ``(None, None)`` if absent.

    Usable: valid JSON, a result document for ``env_id`` and ``policy`` with its episodes, and (when ``episodes``
    is given) exactly that many episodes.
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
    if doc["env_id"] != env_id or doc["policy"] != policy:
        return None, f"it holds {doc['env_id']} {doc['policy']}, not {env_id} {policy}"
    n = doc["n_episodes"]
    if not isinstance(doc["episodes"], list) or not doc["episodes"] or len(doc["episodes"]) != n:
        return None, f"it does not hold its {n!r} episodes"
    if episodes is not None and n != episodes:
        return None, f"it has {n} episodes, not {episodes}"
    return doc, None


def run_leaderboard(
    env_ids: list[str],
    episodes: int,
    results_dir: Path,
    redo: bool = False,
    progress: Callable[[str], None] = print,
    on_plan: Callable[[int], None] | None = None,
    on_episode: Callable[[dict], None] | None = None,
) -> list[dict]:
    """Evaluate ``random`` and every hand baseline on each environment; returns the result documents.

    Results already in ``results_dir`` for ``episodes`` episodes are reused unless ``redo``; anything else there
    (empty, corrupt, another episode count) is evaluated again and ``progress`` says which file and why.
    ``on_plan(total_episodes)`` is called once before the first evaluation, ``on_episode`` after each episode.
    """
    plan: list[tuple[str, str, Path, dict | None]] = []
    for env_id in env_ids:
        for policy in leaderboard_policies(env_id):
            path = result_path(results_dir, env_id, policy)
            doc = None
            if not redo:
                doc, why = load_result(path, env_id, policy, episodes)
                if doc is not None:
                    progress(f"{env_id} {policy}: done before ({path})")
                elif why is not None:
                    progress(f"{env_id} {policy}: redoing {path}: {why}")
            plan.append((env_id, policy, path, doc))
    if on_plan is not None:
        on_plan(episodes * sum(doc is None for *_, doc in plan))
    documents = []
    for env_id, policy, path, doc in plan:
        if doc is None:
            progress(f"{env_id} {policy}: {episodes} episode{'s' if episodes != 1 else ''} ...")
            doc = evaluate(env_id, policy, episodes=episodes, seed=EVAL_SEED, on_episode=on_episode)
            doc["n_episodes"] = episodes
            doc.update(_provenance())
            write_json_atomic(path, doc)
        documents.append(doc)
    return documents


def stored_results(env_ids: list[str], results_dir: Path, progress: Callable[[str], None] = print) -> list[dict]:
    """Every usable result in ``results_dir`` for ``env_ids`` (any episode count), without evaluating anything.

    Unusable files are skipped, and ``progress`` says which and why.
    """
    documents = []
    for env_id in env_ids:
        for policy in leaderboard_policies(env_id):
            path = result_path(results_dir, env_id, policy)
            doc, why = load_result(path, env_id, policy)
            if doc is not None:
                documents.append(doc)
            elif why is not None:
                progress(f"{env_id} {policy}: left out of the table: {path}: {why}")
    return documents


def leaderboard_markdown(documents: list[dict], quick: bool | None = None) -> str:
    """The leaderboard as Markdown: one table per environment.

    ``quick`` (the table warns that numbers are indicative) defaults to: some row has fewer than
    :data:`PROTOCOL_EPISODES` episodes.
    """
    from baselines import PAPER_POLICY

    counts = sorted({int(d["n_episodes"]) for d in documents})
    if quick is None:
        quick = any(n < PROTOCOL_EPISODES for n in counts)
    if len(counts) <= 1:
        each = f"Each row: {counts[0] if counts else 0} evaluation episodes"
    else:
        each = f"Each row: eval_episodes evaluation episodes (rows differ: {', '.join(map(str, counts))})"
    lines = [
        "# polyenvs leaderboard",
        "",
        f"{each} on seeds "
        f"{EVAL_SEED}, {EVAL_SEED + 1}, ... (the same for every policy), deterministic actions. IQM is the "
        "interquartile mean of the episode return with its 95% bootstrap interval; the normalised score is "
        "(IQM - IQM of random) / (IQM of the paper's baseline - IQM of random).",
        "",
    ]
    if quick:
        lines += [
            f"**Quick mode**: fewer episodes than the protocol's {PROTOCOL_EPISODES}; numbers are indicative only.",
            "",
        ]
    by_env: dict[str, list[dict]] = {}
    for doc in documents:
        by_env.setdefault(doc["env_id"], []).append(doc)
    for env_id, docs in by_env.items():
        iqms = {d["policy"]: iqm_with_ci([e["return"] for e in d["episodes"]]) for d in docs}
        rand = iqms.get("random", (np.nan,))[0]
        paper = iqms.get(PAPER_POLICY.get(env_id, ""), (np.nan,))[0]
        metric_names = sorted(set().union(*(d["summary"].keys() for d in docs)) - {"return", "length"})
        lines += [f"## {env_id}", ""]
        header = [
            "algo",
            "env_id",
            "mean_reward",
            "std_reward",
            "n_timesteps",
            "eval_episodes",
            "IQM [95% CI]",
            "normalised",
        ]
        lines += ["| " + " | ".join(header + metric_names) + " |", "|" + "---|" * (len(header) + len(metric_names))]
        for d in docs:
            returns = np.array([e["return"] for e in d["episodes"]])
            iqm, lo, hi = iqms[d["policy"]]
            norm = (iqm - rand) / (paper - rand) if np.isfinite(paper - rand) and paper != rand else float("nan")
            row = [
                d["policy"],
                env_id,
                f"{returns.mean():.2f}",
                f"{returns.std():.2f}",
                "-",  # hand baselines are not trained
                str(len(returns)),
                f"{iqm:.2f} [{lo:.2f}, {hi:.2f}]",
                f"{norm:.2f}",
            ]
            row += [f"{d['summary'][m]:.3g}" if m in d["summary"] else "-" for m in metric_names]
            lines.append("| " + " | ".join(row) + " |")
        lines.append("")
    return "\n".join(lines)


def write_leaderboard(documents: list[dict], path: Path, quick: bool | None = None) -> str:
    text = leaderboard_markdown(documents, quick=quick)
    write_text_atomic(path, text)
    return text
