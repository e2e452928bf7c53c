"""Evaluate every policy on every environment and build the leaderboard table (``polyenvs leaderboard``).

Each (environment, policy) result is a JSON file under the results directory, written atomically; a re-run skips
what is done unless asked to redo it. The table follows RL Zoo's ``benchmark.md`` columns plus the interquartile
mean with its 95% bootstrap interval, a score normalised so that random = 0 and the paper's baseline = 1, and the
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

__all__ = ["run_leaderboard", "leaderboard_markdown", "EVAL_SEED"]

#: First evaluation seed; episodes use EVAL_SEED, EVAL_SEED + 1, ... for every policy.
EVAL_SEED = 1000


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


def run_leaderboard(
    env_ids: list[str],
    episodes: int,
    results_dir: Path,
    redo: bool = False,
    progress: Callable[[str], None] = print,
) -> list[dict]:
    """Evaluate ``random`` and every hand baseline on each environment; returns the result documents."""
    from baselines import available_policies

    documents = []
    for env_id in env_ids:
        for policy in available_policies(env_id):
            if policy == "paper":
                continue  # an alias of one of the others
            path = result_path(results_dir, env_id, policy)
            if path.exists() and not redo:
                doc = json.loads(path.read_text())
                if doc.get("n_episodes") == episodes:
                    documents.append(doc)
                    progress(f"{env_id} {policy}: done before ({path})")
                    continue
            progress(f"{env_id} {policy}: {episodes} episodes ...")
            doc = evaluate(env_id, policy, episodes=episodes, seed=EVAL_SEED)
            doc["n_episodes"] = episodes
            doc.update(_provenance())
            write_json_atomic(path, doc)
            documents.append(doc)
    return documents


def leaderboard_markdown(documents: list[dict], quick: bool = False) -> str:
    """The leaderboard as Markdown: one table per environment."""
    from baselines import PAPER_POLICY

    lines = [
        "# polyenvs leaderboard",
        "",
        f"Each row: {documents[0]['n_episodes'] if documents else 0} evaluation episodes on seeds "
        f"{EVAL_SEED}, {EVAL_SEED + 1}, ... (the same for every policy), deterministic actions. IQM is the "
        "interquartile mean of the episode return with its 95% bootstrap interval; the normalised score is "
        "(IQM - IQM of random) / (IQM of the paper's baseline - IQM of random).",
        "",
    ]
    if quick:
        lines += ["**Quick mode**: fewer episodes than the protocol's 50; numbers are indicative only.", ""]
    by_env: dict[str, list[dict]] = {}
    for doc in documents:
        by_env.setdefault(doc["env_id"], []).append(doc)
    for env_id, docs in by_env.items():
        iqms = {d["policy"]: iqm_with_ci([e["return"] for e in d["episodes"]]) for d in docs}
        rand = iqms.get("random", (np.nan,))[0]
        paper = iqms.get(PAPER_POLICY.get(env_id, ""), (np.nan,))[0]
        metric_names = list(docs[0]["summary"].keys() - {"return", "length"})
        metric_names.sort()
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
            row += [f"{d['summary'][m]:.3g}" for m in metric_names]
            lines.append("| " + " | ".join(row) + " |")
        lines.append("")
    return "\n".join(lines)


def write_leaderboard(documents: list[dict], path: Path, quick: bool = False) -> str:
    text = leaderboard_markdown(documents, quick=quick)
    write_text_atomic(path, text)
    return text
