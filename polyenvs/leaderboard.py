"""Evaluate every policy on every environment and build the leaderboard table (``polyenvs leaderboard``).

Policies: random, every hand baseline, and every trained agent committed under the agents directory
(``benchmarks/agents/<env id with / as __>/<algo>/seed<N>/``, each a training directory: ``model.zip``, optional
``vecnormalize.pkl``, ``run.json``), all on the same published seeds. Each (environment, policy) result, and each
agent's training seed, is a JSON file under the results directory, written atomically; a re-run skips what is done
unless asked to redo it, and re-runs (saying why) a file that is unreadable, not a result, for another number of
episodes, or (for an agent) for another version of the model (its SHA-256 differs).

The table follows RL Zoo's ``benchmark.md`` columns plus the interquartile mean with its 95% bootstrap interval, a
score normalised so that random = 0 and the paper's baseline = 1, and the environment's task metrics. A trained
algorithm gets one row that pools the episodes of all its training seeds: IQM with a stratified bootstrap interval
(episodes resampled within each run), mean ``n_timesteps`` over the seeds, and the number of seeds. Beside the
Markdown file, one PNG per environment draws each row's IQM as a bar with its interval.
"""

from __future__ import annotations

import datetime
import json
import math
import platform
import re
import subprocess
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from polyenvs.errors import InputError
from polyenvs.evaluation import evaluate
from polyenvs.files import atomic_path, write_json_atomic, write_text_atomic
from polyenvs.registry import bare_id, slug
from polyenvs.statistics import iqm_with_stratified_ci

__all__ = [
    "DEFAULT_AGENTS_DIR",
    "agents_line",
    "default_agents_dirs",
    "EVAL_SEED",
    "PROTOCOL_EPISODES",
    "Agent",
    "agent_from_path",
    "find_agents",
    "leaderboard_markdown",
    "leaderboard_plot",
    "leaderboard_policies",
    "leaderboard_rows",
    "load_result",
    "plot_path",
    "provenance",
    "result_path",
    "run_leaderboard",
    "stored_results",
    "write_leaderboard",
]

#: First evaluation seed; episodes use EVAL_SEED, EVAL_SEED + 1, ... for every policy.
EVAL_SEED = 1000
#: Episodes per policy in the reference leaderboard; fewer is "quick mode" and the table says so.
PROTOCOL_EPISODES = 50
#: Where committed trained agents live (relative to the repository root, like the reference results).
DEFAULT_AGENTS_DIR = Path("benchmarks/agents")
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


def result_path(results_dir: Path, env_id: str, policy: str) -> Path:
    """``<results_dir>/<env id with / as __>__<policy>.json``; an agent's ``policy`` here is its :attr:`Agent.key`."""
    return Path(results_dir) / f"{slug(env_id)}__{policy}.json"


def plot_path(table: Path, env_id: str) -> Path:
    """The PNG beside the Markdown table: ``<table stem>_<env id with / as __>.png``."""
    table = Path(table)
    return table.parent / f"{table.stem}_{slug(env_id)}.png"


def leaderboard_policies(env_id: str) -> list[str]:
    """The policies the leaderboard evaluates on ``env_id``: random and every hand baseline ("paper" is an alias)."""
    from baselines import available_policies

    return [p for p in available_policies(env_id) if p != "paper"]


# ---------------------------------------------------------------------------------------------- trained agents


@dataclass(frozen=True)
class Agent:
    """One trained agent (one training seed) on the leaderboard."""

    env_id: str
    algo: str
    path: str  # the training directory (or .zip), as the results name it
    label: str  # the table row it joins: the algorithm for committed agents, the path for --policy ones
    key: str  # result file name part: agent__<algo>__seed<N>, or agent__<path as a slug>
    seed: int | None = None
    run: dict = field(default_factory=dict, compare=False, hash=False)

    @property
    def name(self) -> str:
        """How progress messages name it: ``ppo seed0``."""
        return f"{self.label} seed{self.seed}" if self.seed is not None else self.label

    def meta(self) -> dict:
        """What a result document records about the agent (its row, seed and training length)."""
        return {
            "algo": self.algo,
            "label": self.label,
            "training_seed": self.seed,
            "timesteps": self.run.get("timesteps"),
            "requested_timesteps": self.run.get("requested_timesteps"),
            "completed": self.run.get("completed"),
        }


def _trained():
    import baselines.trained

    return baselines.trained


def _seed_number(path: Path) -> int:
    match = re.fullmatch(r"seed(\d+)", path.name)
    if match is None:
        raise InputError(f"{path}: agent directories are named seed<N> (the training seed)")
    return int(match.group(1))


def find_agents(agents_dir: Path | None, env_id: str) -> list[Agent]:
    """The committed agents of ``env_id``: every ``<agents_dir>/<env>/<algo>/seed<N>/``, by algorithm then seed.

    Each must hold a ``model.zip`` and a ``run.json`` that agrees with where it sits (environment, algorithm,
    seed); anything else raises :class:`InputError` naming the directory. Files (a README) are ignored.
    """
    if agents_dir is None:
        return []
    from baselines.algorithms import ALGOS

    trained = _trained()
    base = Path(agents_dir) / slug(env_id)
    if not base.is_dir():
        return []
    agents = []
    order = {name: i for i, name in enumerate(ALGOS)}  # ppo, dqn, maskable_ppo, sac, td3
    algo_dirs = [p for p in base.iterdir() if p.is_dir() and not p.name.startswith(".")]
    for algo_dir in sorted(algo_dirs, key=lambda p: (order.get(p.name, len(order)), p.name)):
        algo = algo_dir.name
        if algo not in ALGOS:
            raise InputError(f"{algo_dir}: unknown algorithm directory; known: {', '.join(ALGOS)}")
        seed_dirs = [p for p in algo_dir.iterdir() if p.is_dir() and not p.name.startswith(".")]
        for seed_dir in sorted(seed_dirs, key=lambda p: (_seed_number(p), p.name)):
            seed = _seed_number(seed_dir)
            try:
                _, _, run_file = trained.resolve_model_files(seed_dir)
                if run_file is None:
                    raise trained.TrainedModelError(f"{seed_dir}: no run.json (the leaderboard reads its timesteps)")
                run = trained.read_run_info(run_file)
            except trained.TrainedModelError as exc:
                raise InputError(str(exc)) from None
            for what, found, expected in (
                ("env_id", bare_id(str(run.get("env_id", ""))), env_id),
                ("algo", run.get("algo"), algo),
                ("seed", run.get("seed"), seed),
            ):
                if found != expected:
                    raise InputError(f"{run_file}: {what} is {found!r}, but the directory says {expected!r}")
            agents.append(Agent(env_id, algo, str(seed_dir), algo, f"agent__{algo}__seed{seed}", seed, run))
    return agents


def default_agents_dirs() -> list[Path]:
    """Where the leaderboard looks for the committed agents, in order: ``benchmarks/agents`` in the current
    directory, then in the checkout polyenvs runs from (a clone, or an editable install of one). An installed
    package does not ship them (7 MB of models): from anywhere else there are none."""
    candidates = [DEFAULT_AGENTS_DIR]
    root = Path(__file__).resolve().parents[1]
    if (root / "pyproject.toml").is_file() and (root / "polyenvs" / "__init__.py").is_file():
        candidates.append(root / DEFAULT_AGENTS_DIR)
    return candidates


def agents_line(agents_dir: Path | None, env_ids: list[str], looked: list[Path] | None = None) -> str:
    """One line saying where the trained agents come from and what is there for ``env_ids`` (for the output).

    ``agents_dir`` None: none of ``looked`` exists. Raises :class:`InputError` for a malformed agent directory.
    """
    if agents_dir is None:
        where = " and ".join(str(Path(p).absolute()) for p in dict.fromkeys(looked or [DEFAULT_AGENTS_DIR]))
        return (
            f"trained agents: none found (no {where}; the committed agents are in the polyenvs repository's "
            f"{DEFAULT_AGENTS_DIR}/, which an installed package does not include: run from a checkout or pass "
            "--agents-dir DIR)"
        )
    found = {env_id: find_agents(agents_dir, env_id) for env_id in env_ids}
    agents = [a for group in found.values() for a in group]
    where = Path(agents_dir).absolute()
    if not agents:
        return (
            f"trained agents: none in {where} for the {len(env_ids)} environment{'s' if len(env_ids) != 1 else ''} "
            "run (it has no <env id with / as __>/<algo>/seed<N>/ directory for them)"
        )
    algos = ", ".join(dict.fromkeys(a.algo for a in agents))
    envs = sum(1 for group in found.values() if group)
    return (
        f"trained agents: {len(agents)} ({algos}) for {envs} of {len(env_ids)} environment"
        f"{'s' if len(env_ids) != 1 else ''}, from {where}"
    )


def agent_from_path(path: str) -> Agent:
    """An extra agent named on the command line (``--policy PATH``): its run.json must name its environment."""
    trained = _trained()
    try:
        model_file, _, run_file = trained.resolve_model_files(path)
        run = trained.read_run_info(run_file)
    except trained.TrainedModelError as exc:
        raise InputError(str(exc)) from None
    env_id = run.get("env_id")
    if not env_id:
        raise InputError(f"{path}: the leaderboard needs the run.json beside the model to know its environment")
    algo = run.get("algo") or "model"
    seed = run.get("seed") if isinstance(run.get("seed"), int) else None
    slug = re.sub(r"[^A-Za-z0-9._-]+", "_", str(path)).strip("_.") or "model"
    return Agent(bare_id(str(env_id)), algo, str(path), str(path), f"agent__{slug}", seed, run)


def _check_agent(agent: Agent, envs: dict) -> str:
    """Load the agent against its environment (spaces, run.json) before any evaluation; returns its checksum."""
    from polyenvs.evaluation import make_agent, make_env

    if agent.env_id not in envs:
        envs[agent.env_id] = make_env(agent.env_id)
    policy = make_agent(agent.path, agent.env_id, envs[agent.env_id])
    return policy.describe()["sha256"]


# ------------------------------------------------------------------------------------------------- result files


def load_result(
    path: Path, env_id: str, policy: str, episodes: int | None = None, sha256: str | None = None
) -> tuple[dict | None, str | None]:
    """``(document, None)`` if ``path`` holds a usable result, else ``(None, why not)``; ``(None, None)`` if absent.

    Usable: valid JSON, a result document for ``env_id`` and ``policy`` with its episodes, (when ``episodes`` is
    given) exactly that many episodes, and (when ``sha256`` is given, for a trained model) of that model.
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
    if sha256 is not None:
        description = doc.get("policy_description")
        if not isinstance(description, dict) or description.get("sha256") != sha256:
            return None, "it evaluated another version of the model (its SHA-256 differs)"
    return doc, None


def run_leaderboard(
    env_ids: list[str],
    episodes: int,
    *,
    results_dir: Path,
    redo: bool = False,
    progress: Callable[[str], None] = print,
    on_plan: Callable[[int], None] | None = None,
    on_episode: Callable[[dict], None] | None = None,
    agents_dir: Path | None = None,
    extra_agents: list[str] | tuple[str, ...] = (),
) -> list[dict]:
    """Evaluate ``random``, every hand baseline and every trained agent on each environment; returns the documents.

    Agents are the committed ones under ``agents_dir`` (see :func:`find_agents`) plus ``extra_agents`` (paths whose
    run.json names one of ``env_ids``); every agent that needs evaluating is loaded and checked against its
    environment first, so a broken one raises :class:`InputError` before any episode runs. Results already in
    ``results_dir`` for ``episodes`` episodes (and, for an agent, the same model) are reused unless ``redo``;
    anything else there is evaluated again and ``progress`` says which file and why. ``on_plan(total_episodes)`` is
    called once before the first evaluation, ``on_episode`` after each episode. An agent's document carries
    ``"agent": {"algo", "label", "training_seed", "timesteps", ...}``.
    """
    agents: dict[str, list[Agent]] = {env_id: find_agents(agents_dir, env_id) for env_id in env_ids}
    for path in extra_agents:
        agent = agent_from_path(path)
        if agent.env_id not in agents:
            raise InputError(f"--policy {path}: trained on {agent.env_id}, which is not among the environments run")
        agents[agent.env_id].append(agent)

    plan: list[tuple[str, str, str, Path, dict | None, Agent | None]] = []
    envs: dict = {}
    try:
        for env_id in env_ids:
            entries: list[tuple[str, str, Agent | None]] = [(p, p, None) for p in leaderboard_policies(env_id)]
            entries += [(a.path, a.key, a) for a in agents[env_id]]
            for policy, key, agent in entries:
                path = result_path(results_dir, env_id, key)
                name = agent.name if agent is not None else policy
                sha = _check_agent(agent, envs) if agent is not None else None
                doc = None
                if not redo:
                    doc, why = load_result(path, env_id, policy, episodes, sha256=sha)
                    if doc is not None:
                        progress(f"{env_id} {name}: done before ({path})")
                    elif why is not None:
                        progress(f"{env_id} {name}: redoing {path}: {why}")
                if agent is not None and agent.run.get("completed") is False:
                    progress(
                        f"{env_id} {name}: trained {agent.run.get('timesteps')} of "
                        f"{agent.run.get('requested_timesteps')} requested timesteps (interrupted); included as it is"
                    )
                plan.append((env_id, policy, name, path, doc, agent))
    finally:
        for env in envs.values():
            env.close()
    if on_plan is not None:
        on_plan(episodes * sum(doc is None for *_, doc, _ in plan))
    documents = []
    for env_id, policy, name, path, doc, agent in plan:
        if doc is None:
            progress(f"{env_id} {name}: {episodes} episode{'s' if episodes != 1 else ''} ...")
            doc = evaluate(env_id, policy, episodes=episodes, seed=EVAL_SEED, on_episode=on_episode)
            doc["n_episodes"] = episodes
            if agent is not None:
                doc["agent"] = agent.meta()
            doc.update(provenance())
            write_json_atomic(path, doc)
        elif agent is not None:
            doc["agent"] = agent.meta()  # the row it joins now (a --policy agent is labelled by its path)
        documents.append(doc)
    return documents


def stored_results(
    env_ids: list[str], results_dir: Path, progress: Callable[[str], None] = print, agents_dir: Path | None = None
) -> list[dict]:
    """Every usable result in ``results_dir`` for ``env_ids`` (any episode count), without evaluating anything.

    Includes the committed agents under ``agents_dir`` whose results are there and of the same model. Unusable
    files (and unusable agent directories) are skipped, and ``progress`` says which and why.
    """
    trained = _trained() if agents_dir is not None else None
    documents = []
    for env_id in env_ids:
        entries: list[tuple[str, str, Agent | None]] = [(p, p, None) for p in leaderboard_policies(env_id)]
        try:
            entries += [(a.path, a.key, a) for a in find_agents(agents_dir, env_id)]
        except InputError as exc:
            progress(f"{env_id}: agents left out of the table: {exc}")
        for policy, key, agent in entries:
            path = result_path(results_dir, env_id, key)
            sha = None
            if agent is not None:
                model_file, normalize_file, _ = trained.resolve_model_files(agent.path)
                sha = trained.model_checksum(model_file, normalize_file)
            doc, why = load_result(path, env_id, policy, sha256=sha)
            if doc is not None:
                if agent is not None:
                    doc["agent"] = agent.meta()
                documents.append(doc)
            elif why is not None:
                progress(f"{env_id} {agent.name if agent else policy}: left out of the table: {path}: {why}")
    return documents


# ------------------------------------------------------------------------------------------------------ the table


def leaderboard_rows(documents: list[dict]) -> dict[str, list[dict]]:
    """env id -> its rows in table order: baselines as given, then one row per trained algorithm (or path).

    A row: ``{"label", "kind" ("random", "paper", "baseline" or "agent"), "returns" (pooled), "iqm", "low",
    "high", "normalised", "metrics" (means over the pooled episodes), "n_timesteps" (mean over seeds, or None),
    "seeds" (training seeds, agents only), "episodes"}``.
    """
    from baselines import paper_policy

    by_env: dict[str, dict[str, list[dict]]] = {}
    for doc in documents:
        agent = doc.get("agent")
        label = agent.get("label", agent.get("algo")) if isinstance(agent, dict) else doc["policy"]
        by_env.setdefault(doc["env_id"], {}).setdefault(("agent:" if agent else "") + label, []).append(doc)
    tables = {}
    for env_id, groups in by_env.items():
        rows = []
        for group_key, docs in groups.items():
            agent = group_key.startswith("agent:")
            runs = [np.array([e["return"] for e in d["episodes"]], dtype=np.float64) for d in docs]
            iqm, low, high = iqm_with_stratified_ci(runs)
            episodes = [e for d in docs for e in d["episodes"]]
            names = sorted(set().union(*(e.get("metrics", {}).keys() for e in episodes)))
            metrics = {
                m: float(np.mean([e["metrics"][m] for e in episodes if m in e.get("metrics", {})])) for m in names
            }
            timesteps = [d["agent"].get("timesteps") for d in docs] if agent else []
            timesteps = [t for t in timesteps if isinstance(t, int | float) and not isinstance(t, bool)]
            label = group_key.removeprefix("agent:")
            if agent:
                kind = "agent"
            elif label == "random":
                kind = "random"
            else:
                kind = "paper" if label == paper_policy(env_id) else "baseline"
            rows.append(
                {
                    "label": label,
                    "kind": kind,
                    "returns": np.concatenate(runs),
                    "iqm": iqm,
                    "low": low,
                    "high": high,
                    "metrics": metrics,
                    "n_timesteps": float(np.mean(timesteps)) if timesteps else None,
                    "seeds": [d["agent"].get("training_seed") for d in docs] if agent else None,
                    "episodes": len(episodes),
                }
            )
        rand = next((r["iqm"] for r in rows if r["kind"] == "random"), np.nan)
        paper = next((r["iqm"] for r in rows if r["kind"] == "paper"), np.nan)
        for row in rows:
            span = paper - rand
            row["normalised"] = (row["iqm"] - rand) / span if np.isfinite(span) and span != 0 else float("nan")
        tables[env_id] = rows
    return tables


def _format_timesteps(n: float | None) -> str:
    """RL Zoo's style: ``1M``, ``250k``, ``1.5M``, ``256``."""
    if n is None:
        return "-"
    for unit, size in (("M", 1e6), ("k", 1e3)):
        if n >= size:
            return f"{n / size:.3g}{unit}"
    return f"{n:.0f}"


def leaderboard_markdown(documents: list[dict], quick: bool | None = None, plots: dict[str, str] | None = None) -> str:
    """The leaderboard as Markdown: one table per environment (and, with ``plots`` = env id -> PNG file name
    relative to the table, a link to each environment's plot).

    ``quick`` (the table warns that numbers are indicative) defaults to: some result has fewer than
    :data:`PROTOCOL_EPISODES` episodes.
    """
    counts = sorted({int(d["n_episodes"]) for d in documents})
    if quick is None:
        quick = any(n < PROTOCOL_EPISODES for n in counts)
    if len(counts) <= 1:
        each = f"Each policy (each training seed of a trained agent): {counts[0] if counts else 0} evaluation episodes"
    else:
        each = f"Each policy (each training seed of a trained agent): evaluation episodes differ ({', '.join(map(str, counts))})"
    lines = [
        "# polyenvs leaderboard",
        "",
        f"{each} on seeds "
        f"{EVAL_SEED}, {EVAL_SEED + 1}, ... (the same for every policy), deterministic actions. IQM is the "
        "interquartile mean of the episode return with its 95% bootstrap interval; the normalised score is "
        "(IQM - IQM of random) / (IQM of the paper's baseline - IQM of random). A trained algorithm's row pools the "
        "episodes of all its training seeds (eval_episodes counts them all; seeds says how many runs): its interval "
        "is a stratified bootstrap (episodes resampled within each run), n_timesteps the mean over the seeds, and "
        "the task metrics are means over all its episodes.",
        "",
    ]
    if quick:
        lines += [
            f"**Quick mode**: fewer episodes than the protocol's {PROTOCOL_EPISODES}; numbers are indicative only.",
            "",
        ]
    for env_id, rows in leaderboard_rows(documents).items():
        metric_names = sorted(set().union(*(r["metrics"].keys() for r in rows)) - {"return", "length"})
        lines += [f"## {env_id}", ""]
        if plots and env_id in plots:
            lines += [f"![IQM and 95% interval of the return per policy on {env_id}]({plots[env_id]})", ""]
        header = [
            "algo",
            "env_id",
            "mean_reward",
            "std_reward",
            "n_timesteps",
            "eval_episodes",
            "seeds",
            "IQM [95% CI]",
            "normalised",
        ]
        lines += ["| " + " | ".join(header + metric_names) + " |", "|" + "---|" * (len(header) + len(metric_names))]
        for r in rows:
            returns = r["returns"]
            row = [
                r["label"],
                env_id,
                f"{returns.mean():.2f}",
                f"{returns.std():.2f}",
                _format_timesteps(r["n_timesteps"]),  # "-" for hand baselines: they are not trained
                str(len(returns)),
                str(len(r["seeds"])) if r["seeds"] is not None else "-",
                f"{r['iqm']:.2f} [{r['low']:.2f}, {r['high']:.2f}]",
                f"{r['normalised']:.2f}",
            ]
            row += [f"{r['metrics'][m]:.3g}" if m in r["metrics"] else "-" for m in metric_names]
            lines.append("| " + " | ".join(row) + " |")
        lines.append("")
    return "\n".join(lines)


def write_leaderboard(documents: list[dict], path: Path, quick: bool | None = None) -> str:
    """Write the Markdown table to ``path`` and one PNG per environment beside it (:func:`plot_path`)."""
    from polyenvs.core.raster import png_bytes

    path = Path(path)
    plots = {}
    for env_id, rows in leaderboard_rows(documents).items():
        png = plot_path(path, env_id)
        with atomic_path(png) as tmp:
            tmp.write_bytes(png_bytes(leaderboard_plot(env_id, rows)))
        plots[env_id] = png.name
    text = leaderboard_markdown(documents, quick=quick, plots=plots)
    write_text_atomic(path, text)
    return text


# ------------------------------------------------------------------------------------------------------- the plot


#: Bar colours: random grey, the paper's baseline blue, other hand baselines light blue, trained agents orange.
_COLOURS = {
    "random": (150, 150, 150),
    "paper": (31, 119, 180),
    "baseline": (120, 175, 215),
    "agent": (230, 120, 30),
}


def _nice_ticks(low: float, high: float, count: int = 5) -> np.ndarray:
    span = max(high - low, 1e-9)
    raw = span / count
    step = 10 ** math.floor(math.log10(raw))
    step *= next(m for m in (1, 2, 2.5, 5, 10) if m * step >= raw)
    return np.arange(math.ceil(low / step) * step, high + 0.5 * step, step)


def _format_number(value: float) -> str:
    if abs(value) >= 1000:
        return f"{value:.0f}"
    if abs(value) >= 10:
        return f"{value:.1f}"
    return f"{value:.2f}"


def leaderboard_plot(env_id: str, rows: list[dict], width: int = 760) -> np.ndarray:
    """An ``(H, width, 3)`` uint8 image: per row (top to bottom, table order) a horizontal bar from 0 to the IQM of
    the return and a black line over its 95% interval, the IQM written at the right; grey random, dark blue the
    paper's baseline, light blue other hand baselines, orange trained agents. Drawn with
    :class:`polyenvs.core.raster.Canvas`."""
    from polyenvs.core.raster import Canvas, stamp_text, text_width

    scale, row_h, top, bottom = 2, 30, 58, 56
    labels = [r["label"] if len(r["label"]) <= 26 else "..." + r["label"][-23:] for r in rows]
    left = 16 + max(text_width(s, scale) for s in labels) + 16
    right = width - 90
    height = top + row_h * len(rows) + bottom
    values = [v for r in rows for v in (r["iqm"], r["low"], r["high"]) if np.isfinite(v)] + [0.0]
    lo, hi = min(values), max(values)
    pad = 0.04 * max(hi - lo, 1e-9)
    lo, hi = lo - (pad if lo < 0 else 0), hi + (pad if hi > 0 else 0)
    if hi - lo < 1e-9:
        lo, hi = lo - 1, hi + 1

    def x_px(value: float) -> float:
        return left + (value - lo) / (hi - lo) * (right - left)

    canvas = Canvas((0, 0, width, height), width=width, height=height, margin=0)  # world units are pixels, y up

    def y(row_px: float) -> float:  # image row -> world y
        return height - row_px

    ticks = _nice_ticks(lo, hi)
    plot_top, plot_bottom = top - 6, top + row_h * len(rows) + 6
    for t in ticks:
        canvas.lines([(x_px(t), y(plot_top))], [(x_px(t), y(plot_bottom))], (225, 225, 225))
    canvas.lines([(x_px(0), y(plot_top))], [(x_px(0), y(plot_bottom))], (90, 90, 90))
    canvas.lines([(left, y(plot_bottom))], [(right, y(plot_bottom))], (90, 90, 90))
    for i, r in enumerate(rows):
        centre = top + row_h * i + row_h / 2
        if np.isfinite(r["iqm"]):
            a, b = sorted((x_px(0), x_px(r["iqm"])))
            b = max(b, a + 1)
            box = [(a, y(centre - 8)), (b, y(centre - 8)), (b, y(centre + 8)), (a, y(centre + 8))]
            canvas.polygon(box, _COLOURS[r["kind"]])
        if np.isfinite(r["low"]) and np.isfinite(r["high"]):
            xl, xh = x_px(r["low"]), x_px(r["high"])
            canvas.lines(
                [(xl, y(centre)), (xl, y(centre - 5)), (xh, y(centre - 5))],
                [(xh, y(centre)), (xl, y(centre + 5)), (xh, y(centre + 5))],
                (20, 20, 20),
                width_px=2.0,
            )
    image = canvas.image
    stamp_text(image, 16, 10, env_id, (0, 0, 0), scale)
    stamp_text(image, 16, 30, "IQM of the episode return and its 95% interval", (90, 90, 90), scale)
    for i, (label, r) in enumerate(zip(labels, rows, strict=True)):
        centre = top + row_h * i + row_h // 2
        stamp_text(image, 16, centre - 5, label, (0, 0, 0), scale)
        stamp_text(image, right + 12, centre - 5, _format_number(r["iqm"]), (0, 0, 0), scale)
    for t in ticks:
        text = _format_number(float(t)) if abs(t) > 1e-9 * (hi - lo) else "0"
        stamp_text(image, round(x_px(t) - text_width(text, scale) / 2), plot_bottom + 8, text, (60, 60, 60), scale)
    legend = [
        ("random", "random"),
        ("paper", "paper's baseline"),
        ("baseline", "other hand baselines"),
        ("agent", "trained agent"),
    ]
    x = 16
    for kind, name in legend:
        image[height - 18 : height - 8, x : x + 10] = _COLOURS[kind]
        stamp_text(image, x + 14, height - 18, name, (60, 60, 60), scale)
        x += 14 + text_width(name, scale) + 18
    return image
