"""Evaluate every policy on every environment and build the leaderboard table (``polyenvs leaderboard``).

Policies: random, every hand baseline, and every trained agent committed under the agents directory
(``benchmarks/agents/<env id with / as __>/<algo>/seed<N>/``, each a training directory: ``model.zip``, optional
``vecnormalize.pkl``, ``run.json``), all on the same published seeds. Each (environment, policy) result, and each
agent's training seed, is a JSON file under the results directory, written atomically; a re-run skips what is done
unless asked to redo it, and re-runs (saying why) a file that is unreadable, not a result, for another number of
episodes, or (for an agent) for another version of the model (its SHA-256 differs).

Every policy is evaluated on the default layouts and, where the environment takes ``layouts=``, on the held-out
ones (``layouts="test"``), each a result file of its own; the evaluations run one by one or on a process pool
(``workers``), with the same results.

The table ranks each environment's rows by its task score (:class:`polyenvs.registry.Score`, declared on its
registry row): the score's interquartile mean with its 95% stratified bootstrap interval, a score normalised so
that random = 0 and the paper's algorithm (or the row's upper anchor) = 1, "not discriminative" instead where
their intervals overlap, the return's IQM beside it, and the held-out score with the gap. RL Zoo's
``benchmark.md`` columns and the task metrics follow in a collapsed block. A trained algorithm gets one row that
pools the episodes of all its training seeds: IQM with a stratified bootstrap interval (episodes resampled within
each run), mean ``n_timesteps`` over the seeds, and the number of seeds. Beside the Markdown file, charts drawn
with matplotlib (:mod:`polyenvs.charts`): an interval plot of the score per environment and a performance profile
over the environments.
"""

from __future__ import annotations

import datetime
import json
import platform
import re
import subprocess
import time
import warnings
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from polyenvs.errors import InputError
from polyenvs.evaluation import evaluate
from polyenvs.files import write_json_atomic, write_text_atomic
from polyenvs.registry import ParallelEnvEntry, bare_id, entry, slug
from polyenvs.statistics import (
    Comparison,
    aggregate_with_two_level_ci,
    compare,
    interquartile_mean,
    iqm_with_stratified_ci,
    probability_of_improvement,
)

__all__ = [
    "DEFAULT_AGENTS_DIR",
    "agent_verdict",
    "agents_line",
    "checkout_dirs",
    "compare_with_reference",
    "default_agents_dirs",
    "environment_section",
    "EVAL_SEED",
    "PROTOCOL_EPISODES",
    "Agent",
    "agent_from_path",
    "find_agents",
    "LAYOUTS",
    "layouts_kwargs",
    "old_versions_quietly",
    "leaderboard_markdown",
    "leaderboard_policies",
    "leaderboard_rows",
    "leaderboard_tables",
    "profile_path",
    "result_layouts",
    "load_result",
    "plot_path",
    "provenance",
    "REPRODUCE_EPISODES",
    "Reproduction",
    "result_path",
    "run_leaderboard",
    "step_budget",
    "stored_results",
    "write_leaderboard",
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
#: main job's 15 minutes on two cores (:func:`compare_with_reference`).
REPRODUCE_EPISODES = 5
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


def result_path(results_dir: Path, env_id: str, policy: str, layouts: str = "default") -> Path:
    """``<results_dir>/<env id with / as __>__<policy>.json`` (``...__layouts-<name>.json`` for other layouts than
    the default); an agent's ``policy`` here is its :attr:`Agent.key`."""
    suffix = "" if layouts == "default" else f"__layouts-{layouts}"
    return Path(results_dir) / f"{slug(env_id)}__{policy}{suffix}.json"


def result_layouts(doc: dict) -> str:
    """The layouts a result document was evaluated on (``env_kwargs["layouts"]``, else the default)."""
    kwargs = doc.get("env_kwargs")
    return str(kwargs.get("layouts", "default")) if isinstance(kwargs, dict) else "default"


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
        return _agent_name(self.label, self.seed)

    def meta(self) -> dict:
        """What a result document records about the agent (its row, seed and training length)."""
        return {
            "algo": self.algo,
            "label": self.label,
            "training_seed": self.seed,
            "timesteps": self.run.get("timesteps"),
            "requested_timesteps": self.run.get("requested_timesteps"),
            "completed": self.run.get("completed"),
            "training_layouts": training_layouts(self.run),
        }


def training_layouts(run: dict) -> str:
    """The layouts a training run drew its episodes from (its ``env_kwargs``' ``layouts``; "default" where it set
    none, as every run did before ``polyenvs train`` followed the Procgen protocol)."""
    env_kwargs = run.get("env_kwargs")
    layouts = env_kwargs.get("layouts", "default") if isinstance(env_kwargs, dict) else "default"
    return layouts if isinstance(layouts, str) else "default"


def _agent_name(label: str, seed: int | None) -> str:
    return f"{label} seed{seed}" if seed is not None else label


def _trained():
    import baselines.trained

    return baselines.trained


def _seed_number(path: Path) -> int:
    match = re.fullmatch(r"seed(\d+)", path.name)
    if match is None:
        raise InputError(f"{path}: agent directories are named seed<N> (the training seed)")
    return int(match.group(1))


#: A directory of agents that start from a hand baseline: ``<algo>_residual_<baseline>`` (a correction of it, where
#: ``polyenvs train --residual`` writes) or ``<algo>_bc_<baseline>`` (cloned from its demonstrations, ``--bc-from``).
_DERIVED_DIR = re.compile(r"(?P<algo>[a-z0-9_]+?)_(?P<how>residual|bc)_(?P<baseline>.+)")


def _algo_dir(path: Path, algos) -> tuple[str, dict[str, str | None]]:
    """``(algorithm, {"residual": baseline or None, "bc": baseline or None})`` an agents directory's name says."""
    if path.name in algos:
        return path.name, {"residual": None, "bc": None}
    match = _DERIVED_DIR.fullmatch(path.name)
    if match is None or match["algo"] not in algos:
        raise InputError(
            f"{path}: unknown algorithm directory; known: {', '.join(algos)} (or <algo>_residual_<baseline>, "
            "<algo>_bc_<baseline>)"
        )
    return match["algo"], {"residual": None, "bc": None, match["how"]: match["baseline"]}


def _bases(run: dict) -> dict[str, str | None]:
    """The baseline a run corrects (``residual``) and the one whose demonstrations it cloned (``bc``), or None."""
    residual, bc = run.get("residual"), run.get("bc")
    dataset = bc.get("dataset") if isinstance(bc, dict) else None
    return {
        "residual": residual.get("baseline") if isinstance(residual, dict) else None,
        "bc": dataset.get("policy") if isinstance(dataset, dict) else None,
    }


def find_agents(agents_dir: Path | None, env_id: str) -> list[Agent]:
    """The committed agents of ``env_id``: every ``<agents_dir>/<env>/<algo>/seed<N>/``, by algorithm then seed;
    a residual agent's ``<algo>`` directory is ``<algo>_residual_<baseline>``, one cloned from a baseline's
    demonstrations ``<algo>_bc_<baseline>``, each its own row.

    Each must hold a ``model.zip`` and a ``run.json`` that agrees with where it sits (environment, algorithm,
    seed, the baseline a residual agent corrects, the policy of the demonstrations it cloned); anything else raises :class:`InputError` naming the directory.
    Files (a README) are ignored.
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
    for algo_dir in sorted(algo_dirs, key=lambda p: (order.get(_algo_dir(p, ALGOS)[0]), p.name)):
        algo, bases = _algo_dir(algo_dir, ALGOS)
        label = algo_dir.name
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
                ("residual baseline", _bases(run)["residual"], bases["residual"]),
                ("demonstrations' policy", _bases(run)["bc"], bases["bc"]),
            ):
                if found != expected:
                    raise InputError(f"{run_file}: {what} is {found!r}, but the directory says {expected!r}")
            agents.append(Agent(env_id, algo, str(seed_dir), label, f"agent__{label}__seed{seed}", seed, run))
    return agents


def checkout_dirs(relative: Path) -> list[Path]:
    """Where to look for a directory of the repository, in order: ``relative`` to the current directory, then in
    the checkout polyenvs runs from (a clone, or an editable install of one). An installed package does not ship
    the repository's ``benchmarks/`` (16 MB of models): from anywhere else there is only the first."""
    candidates = [Path(relative)]
    root = Path(__file__).resolve().parents[1]
    if (root / "pyproject.toml").is_file() and (root / "polyenvs" / "__init__.py").is_file():
        candidates.append(root / relative)
    return candidates


def default_agents_dirs() -> list[Path]:
    """Where the leaderboard looks for the committed agents: :func:`checkout_dirs` of ``benchmarks/agents``."""
    return checkout_dirs(DEFAULT_AGENTS_DIR)


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
        with old_versions_quietly():
            envs[agent.env_id] = make_env(agent.env_id)
    policy = make_agent(agent.path, agent.env_id, envs[agent.env_id])
    return policy.describe()["sha256"]


# ------------------------------------------------------------------------------------------------- result files


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


@dataclass
class _Evaluation:
    """One (environment, policy, layouts) of the leaderboard: its result file, and its document once there."""

    env_id: str
    policy: str  # a baseline name or an agent's path
    name: str  # how progress lines name it
    path: Path
    layouts: str
    episodes: int
    agent: Agent | None = None
    doc: dict | None = None

    @property
    def title(self) -> str:
        return _evaluation_title(self.env_id, self.name, self.layouts)


def _evaluation_title(env_id: str, name: str, layouts: str) -> str:
    """How progress and reproduction lines name an evaluation: ``<env id> ppo seed0 (layouts=test)``."""
    return f"{env_id} {name}" + ("" if layouts == "default" else f" (layouts={layouts})")


@contextmanager
def old_versions_quietly():
    """Make environments without Gymnasium's "out of date" warning for an id with a newer version: the leaderboard
    evaluates every registered version on purpose (the -v0 ids stay, as Gymnasium keeps them, to compare)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r".*is out of date", category=DeprecationWarning)
        yield


def layouts_kwargs(layouts: str) -> dict:
    """The environment keywords of a layout set: none for the default (today's episodes, bit for bit)."""
    return {} if layouts == "default" else {"layouts": layouts}


def protocol_episodes(env_id: str) -> int:
    """Episodes per policy in the protocol for ``env_id``: its score's own count, else :data:`PROTOCOL_EPISODES`."""
    score = entry(env_id).score
    return score.episodes if score is not None and score.episodes is not None else PROTOCOL_EPISODES


def run_leaderboard(
    env_ids: list[str],
    episodes: int | None,
    *,
    results_dir: Path,
    redo: bool = False,
    progress: Callable[[str], None] = print,
    on_plan: Callable[[int], None] | None = None,
    on_episode: Callable[[dict], None] | None = None,
    agents_dir: Path | None = None,
    extra_agents: list[str] | tuple[str, ...] = (),
    workers: int = 1,
) -> list[dict]:
    """Evaluate ``random``, every hand baseline and every trained agent on each environment, on the default layouts
    and (where the environment takes ``layouts=``) the held-out ones; returns the documents. ``episodes`` per
    policy, or ``None`` for the protocol's count of each environment (:func:`protocol_episodes`).

    Agents are the committed ones under ``agents_dir`` (see :func:`find_agents`) plus ``extra_agents`` (paths whose
    run.json names one of ``env_ids``); every agent that needs evaluating is loaded and checked against its
    environment first, so a broken one raises :class:`InputError` before any episode runs. Results already in
    ``results_dir`` for ``episodes`` episodes (and, for an agent, the same model) are reused unless ``redo``;
    anything else there is evaluated again and ``progress`` says which file and why. ``on_plan(total_episodes)`` is
    called once before the first evaluation, ``on_episode`` after each episode (with ``workers`` > 1, for each
    episode of an evaluation when it finishes), and ``progress`` prints a line per finished evaluation. With
    ``workers`` > 1 the evaluations run on that many processes (:func:`polyenvs.pool.run_local`), with the same
    results as one by one. An agent's document carries ``"agent": {"algo", "label", "training_seed", ...}``.
    """
    agents: dict[str, list[Agent]] = {env_id: find_agents(agents_dir, env_id) for env_id in env_ids}
    for path in extra_agents:
        agent = agent_from_path(path)
        if agent.env_id not in agents:
            raise InputError(f"--policy {path}: trained on {agent.env_id}, which is not among the environments run")
        agents[agent.env_id].append(agent)
    plan = _plan_evaluations(env_ids, episodes, results_dir, redo, progress, agents)
    todo = [item for item in plan if item.doc is None]
    if on_plan is not None:
        on_plan(sum(item.episodes for item in todo))

    def finish(item: _Evaluation, doc: dict, seconds: float) -> None:
        doc["n_episodes"] = item.episodes
        if item.agent is not None:
            doc["agent"] = item.agent.meta()
        doc.update(provenance())
        write_json_atomic(item.path, doc)
        item.doc = doc
        done = sum(i.doc is not None for i in todo)
        progress(
            f"{item.title}: {item.episodes} episode{'s' if item.episodes != 1 else ''} in {seconds:.1f} s "
            f"({done}/{len(todo)})"
        )

    if workers > 1 and len(todo) > 1:
        _evaluate_in_pool(todo, workers, finish, on_episode)
    else:
        for item in todo:
            started = time.monotonic()
            kwargs = layouts_kwargs(item.layouts)
            with old_versions_quietly():
                doc = evaluate(item.env_id, item.policy, episodes=item.episodes, seed=EVAL_SEED, env_kwargs=kwargs or None,
                               on_episode=on_episode)  # fmt: skip
            finish(item, doc, time.monotonic() - started)
    for item in plan:
        if item.agent is not None:
            item.doc["agent"] = item.agent.meta()  # the row it joins now (a --policy agent is labelled by its path)
    return [item.doc for item in plan]


def _plan_evaluations(env_ids, episodes, results_dir, redo, progress, agents) -> list[_Evaluation]:
    """Every evaluation of the leaderboard, with the stored document of those done before (unless ``redo``)."""
    plan: list[_Evaluation] = []
    envs: dict = {}
    try:
        for env_id in env_ids:
            count = episodes if episodes is not None else protocol_episodes(env_id)
            entries: list[tuple[str, str, Agent | None]] = [(p, p, None) for p in leaderboard_policies(env_id)]
            entries += [(a.path, a.key, a) for a in agents[env_id]]
            for policy, key, agent in entries:
                sha = _check_agent(agent, envs) if agent is not None else None
                name = agent.name if agent is not None else policy
                if agent is not None and agent.run.get("completed") is False:
                    progress(
                        f"{env_id} {name}: trained {agent.run.get('timesteps')} of "
                        f"{agent.run.get('requested_timesteps')} requested timesteps (interrupted); included as it is"
                    )
                for layout in LAYOUTS:  # every row takes layouts= (tests/test_layouts.py)
                    path = result_path(results_dir, env_id, key, layout)
                    item = _Evaluation(env_id, policy, name, path, layout, count, agent)
                    if not redo:
                        item.doc, why = load_result(path, env_id, policy, count, sha256=sha, layouts=layout)
                        if item.doc is not None:
                            progress(f"{item.title}: done before ({item.path})")
                        elif why is not None:
                            progress(f"{item.title}: redoing {item.path}: {why}")
                    plan.append(item)
    finally:
        for env in envs.values():
            env.close()
    return plan


def _evaluate_one(job: tuple[int, str, str, int, dict]) -> tuple[dict, float]:
    """One evaluation in a worker process: ``(index, env id, policy, episodes, env kwargs)`` -> (document,
    seconds)."""
    _, env_id, policy, episodes, kwargs = job
    started = time.monotonic()
    with old_versions_quietly():
        doc = evaluate(env_id, policy, episodes=episodes, seed=EVAL_SEED, env_kwargs=kwargs or None)
    return doc, time.monotonic() - started


def step_budget(env_id: str) -> int:
    """The most steps (cycles, for a parallel environment) an episode of ``env_id`` can take: its registry row's
    limit, the measure of an evaluation's length the pool orders by."""
    row = entry(env_id)
    return row.max_cycles if isinstance(row, ParallelEnvEntry) else row.max_episode_steps


def _evaluate_in_pool(todo: list[_Evaluation], workers: int, finish, on_episode) -> None:
    from polyenvs.pool import run_local

    jobs = [(i, item.env_id, item.policy, item.episodes, layouts_kwargs(item.layouts)) for i, item in enumerate(todo)]
    # Longest first (steps an episode may take, times episodes), so that the workers finish together instead of one
    # running an 8,000-step evaluation alone at the end; the order changes no result (each is seeded on its own).
    jobs.sort(key=lambda job: -step_budget(job[1]) * job[3])

    def on_result(job, result) -> None:
        doc, seconds = result
        finish(todo[job[0]], doc, seconds)
        for episode in doc["episodes"] if on_episode is not None else ():
            on_episode(episode)

    def on_error(job, exc: BaseException) -> None:
        raise exc  # as the serial run would: the pool cancels the rest

    run_local(_evaluate_one, jobs, workers, on_result, on_error)


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
            sha = None
            if agent is not None:
                model_file, normalize_file, _ = trained.resolve_model_files(agent.path)
                sha = trained.model_checksum(model_file, normalize_file)
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
    name = _agent_name(agent["label"], agent["training_seed"]) if agent else doc["policy"]
    return _evaluation_title(doc["env_id"], name, result_layouts(doc))


def _canonical(episode: dict) -> str:
    return json.dumps(episode, sort_keys=True)  # floats as Python writes them: the same text is the same bits


def compare_with_reference(sample: list[dict], reference: list[dict]) -> Reproduction:
    """Compare each document of ``sample`` (a re-run of the protocol's first seeds) episode by episode with the
    document of ``reference`` (:func:`stored_results` of the reference results) of the same environment, layouts
    and policy.

    Episodes are deterministic (same seed, same episode, on any machine), so a re-run episode that differs in its
    return, its length or any metric means that this machine or this code does not reproduce the reference.
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
        differing = [a["seed"] for a, b in zip(ours, ref["episodes"], strict=False) if _canonical(a) != _canonical(b)]
        result.same += len(ours) - len(differing)
        if differing:
            result.differ.append(f"{_title(doc)}: seeds {', '.join(map(str, differing))} differ from the reference")
    return result


# ------------------------------------------------------------------------------------------------------ the table


def _score_groups(docs: list[dict], metric: str | None) -> list[np.ndarray] | None:
    """Each run's per-episode values of ``metric`` (the task score), or None where some episode lacks it (a result
    from before the environment emitted it)."""
    if metric is None:
        return None
    groups = [np.array([e.get("metrics", {}).get(metric, np.nan) for e in d["episodes"]], float) for d in docs]
    return groups if all(np.isfinite(g).all() for g in groups) else None


def _present_groups(docs: list[dict], metric: str | None) -> list[np.ndarray] | None:
    """Each run's values of ``metric`` where its episodes report one (a tie-break metric: an episode that never
    reached the goal has no time to it), or None where no run has any."""
    if metric is None:
        return None
    groups = [np.array([e["metrics"][metric] for e in d["episodes"] if metric in e.get("metrics", {})]) for d in docs]
    groups = [g.astype(np.float64) for g in groups if g.size]
    return groups if groups and all(np.isfinite(g).all() for g in groups) else None


def _interval(groups: list[np.ndarray] | None, score) -> dict | None:
    """``{"value", "low", "high", "mean"}`` over ``groups``: the score's aggregate (IQM or mean) and its two-level
    bootstrap interval (training seeds, then episodes within each: the run is the unit, as rliable's), or None
    without values."""
    if groups is None:
        return None
    value, low, high = aggregate_with_two_level_ci(groups, score.aggregate)
    return {"value": value, "low": low, "high": high, "mean": float(np.mean(np.concatenate(groups)))}


def _seed_scores(groups: list[np.ndarray] | None, score) -> list[float] | None:
    """Each run's (training seed's) aggregate of the score, in seed order."""
    if groups is None:
        return None
    aggregate = np.mean if score.aggregate == "mean" else interquartile_mean
    return [float(aggregate(g)) for g in groups]


def _kind(label: str, agent: bool, env_id: str, score) -> str:
    from baselines import paper_policy

    if agent:
        return "agent"
    if label == "random":
        return "random"
    if score is not None and label == score.upper_anchor:
        return "anchor"
    return "paper" if label == paper_policy(env_id) else "baseline"


def _row(env_id: str, group_key: str, docs: list[dict], held_out: list[dict], score) -> dict:
    agent = group_key.startswith("agent:")
    runs = [np.array([e["return"] for e in d["episodes"]], dtype=np.float64) for d in docs]
    iqm, low, high = iqm_with_stratified_ci(runs)
    episodes = [e for d in docs for e in d["episodes"]]
    names = sorted(set().union(*(e.get("metrics", {}).keys() for e in episodes)))
    metrics = {m: float(np.mean([e["metrics"][m] for e in episodes if m in e.get("metrics", {})])) for m in names}
    timesteps = [d["agent"].get("timesteps") for d in docs] if agent else []
    timesteps = [t for t in timesteps if isinstance(t, int | float) and not isinstance(t, bool)]
    label = group_key.removeprefix("agent:")
    metric = score.metric if score is not None else None
    tie_break = score.tie_break if score is not None else None
    layouts = {d["agent"].get("training_layouts", "default") for d in docs} if agent else set()
    return {
        "label": label,
        "kind": _kind(label, agent, env_id, score),
        "returns": np.concatenate(runs),
        "iqm": iqm,
        "low": low,
        "high": high,
        "score_runs": _score_groups(docs, metric),
        "held_out_runs": _score_groups(held_out, metric) if held_out else None,
        "tie_runs": _present_groups(docs, tie_break),
        "held_out_tie_runs": _present_groups(held_out, tie_break) if held_out else None,
        "score": _interval(_score_groups(docs, metric), score),
        "held_out": _interval(_score_groups(held_out, metric), score) if held_out else None,
        "seed_scores": _seed_scores(_score_groups(docs, metric), score) if agent else None,
        "held_out_seed_scores": _seed_scores(_score_groups(held_out, metric), score) if agent and held_out else None,
        "training_layouts": "/".join(sorted(layouts)) if agent else None,
        "tie": metrics.get(score.tie_break) if score is not None and score.tie_break else None,
        "held_out_tie": _tie_mean(held_out, score),
        "metrics": metrics,
        "n_timesteps": float(np.mean(timesteps)) if timesteps else None,
        "seeds": [d["agent"].get("training_seed") for d in docs] if agent else None,
        "episodes": len(episodes),
    }


def _tie_mean(docs: list[dict], score) -> float | None:
    """The mean of the score's tie-break metric over ``docs``' episodes (None without one or without values)."""
    if score is None or not score.tie_break:
        return None
    values = [
        e["metrics"][score.tie_break] for d in docs for e in d["episodes"] if score.tie_break in e.get("metrics", {})
    ]
    return float(np.mean(values)) if values else None


def _overlap(a: dict, b: dict) -> bool:
    return a["low"] <= b["high"] and b["low"] <= a["high"]


def _normalise(rows: list[dict], score) -> bool:
    """Set each row's ``normalised`` score (random 0, the anchor 1) and ``gap`` (held-out minus default, worse
    positive); returns whether the anchor's interval is clear of random's (else ``normalised`` is None)."""
    rand = next((r["score"] for r in rows if r["kind"] == "random"), None)
    anchor_kind = "anchor" if score is not None and score.upper_anchor else "paper"
    anchor = next((r["score"] for r in rows if r["kind"] == anchor_kind), None)
    discriminative = rand is not None and anchor is not None and not _overlap(rand, anchor)
    for row in rows:
        s, h = row["score"], row["held_out"]
        row["normalised"] = None
        if discriminative and s is not None:
            row["normalised"] = (s["value"] - rand["value"]) / (anchor["value"] - rand["value"])
        row["gap"] = score.sign * (s["value"] - h["value"]) if s is not None and h is not None else None
    return discriminative


def _rank_key(row: dict, score) -> tuple:
    """Better rows first: by the score's IQM in its direction, then (rows at the ceiling) by the tie-break metric;
    rows without a score last, in table order."""
    s = row["score"]
    if score is None or s is None:
        return (1, 0.0, 0.0)
    at_ceiling = score.ceiling is not None and s["value"] == score.ceiling
    tie = score.tie_sign * row["tie"] if at_ceiling and row["tie"] is not None else 0.0
    return (0, -score.sign * s["value"], -tie)


def leaderboard_tables(documents: list[dict]) -> dict[str, dict]:
    """env id -> ``{"score": its :class:`~polyenvs.registry.Score` (or None), "discriminative": bool, "rows"}``.

    Rows are ranked by the task score (:func:`_rank_key`). A row: ``{"label", "kind" ("random", "paper",
    "anchor", "baseline" or "agent"), "returns" (pooled), "iqm", "low", "high" (of the return), "score" and
    "held_out" (``{"iqm", "low", "high", "mean"}`` of the score on the default and the held-out layouts, or None),
    "score_runs" (the score's values per run), "normalised" (None where not discriminative), "gap", "tie" and
    "held_out_tie" (the tie-break metric's mean on the default and the held-out layouts),
    "metrics" (means over the pooled episodes), "n_timesteps" (mean over seeds, or None), "seeds" (training seeds,
    agents only), "episodes"}``. A trained algorithm's row pools its training seeds' episodes.
    """
    by_env: dict[str, dict[str, dict[str, list[dict]]]] = {}
    for doc in documents:
        agent = doc.get("agent")
        label = agent.get("label", agent.get("algo")) if isinstance(agent, dict) else doc["policy"]
        key = ("agent:" if agent else "") + label
        by_env.setdefault(doc["env_id"], {}).setdefault(key, {}).setdefault(result_layouts(doc), []).append(doc)
    tables = {}
    for env_id, groups in by_env.items():
        score = _score_of(env_id)
        rows = [
            _row(env_id, key, layouts["default"], layouts.get("test", []), score)
            for key, layouts in groups.items()
            if "default" in layouts
        ]
        discriminative = _normalise(rows, score)
        rows.sort(key=lambda r: _rank_key(r, score))
        tables[env_id] = {"score": score, "discriminative": discriminative, "rows": rows}
    return tables


def leaderboard_rows(documents: list[dict]) -> dict[str, list[dict]]:
    """env id -> its rows, ranked (:func:`leaderboard_tables`)."""
    return {env_id: table["rows"] for env_id, table in leaderboard_tables(documents).items()}


def _score_of(env_id: str):
    try:
        return entry(env_id).score
    except KeyError:  # a result of an environment no longer (or not yet) in the registry
        return None


def _format_timesteps(n: float | None) -> str:
    """RL Zoo's style: ``1M``, ``250k``, ``1.5M``, ``256``."""
    if n is None:
        return "-"
    for unit, size in (("M", 1e6), ("k", 1e3)):
        if n >= size:
            return f"{n / size:.3g}{unit}"
    return f"{n:.0f}"


def _format_interval(stats: dict | None) -> str:
    return "-" if stats is None else f"{stats['value']:.3g} [{stats['low']:.3g}, {stats['high']:.3g}]"


def _score_line(env_id: str, table: dict) -> str:
    score = table["score"]
    if score is None:
        return "No task score is declared for this environment: rows keep table order."
    words = "higher" if score.direction == "max" else "lower"
    best = "ceiling" if score.direction == "max" else "floor"
    how = "mean over episodes" if score.aggregate == "mean" else "IQM over episodes"
    line = f"Task score: `{score.metric}`, its {how} ({words} is better"
    line += f", {best} {score.ceiling:g}" if score.ceiling is not None else ""
    if score.tie_break:
        tie_words = "higher" if score.tie_direction == "max" else "lower"
        line += f"; ties at the {best}: {tie_words} `{score.tie_break}`"
    anchor = score.upper_anchor or "the paper's algorithm"
    line += f"). Normalised: random 0, {anchor} 1."
    if not table["discriminative"]:
        line += (
            f" **Not discriminative**: {anchor}'s interval overlaps random's (or one of them has no result), so no "
            "normalised score is given."
        )
    successor = _superseded_by(env_id)
    if successor is not None:
        line += (
            f" **Superseded** by `{successor}`, which the benchmark ranks on; this version stays registered "
            "unchanged for the results made with it."
        )
    return line


def _superseded_by(env_id: str) -> str | None:
    try:
        return entry(env_id).superseded_by
    except KeyError:  # a result of an environment no longer (or not yet) in the registry
        return None


def _headline_table(table: dict) -> list[str]:
    lines = [
        "| policy | score [95% CI] | normalised | return IQM [95% CI] | held-out score [95% CI] | gap | "
        "per training seed (default; held-out) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in table["rows"]:
        if r["normalised"] is not None:
            normalised = f"{r['normalised']:.2f}"
        else:
            normalised = "not discriminative" if r["score"] is not None else "-"
        cells = [
            r["label"],
            _format_interval(r["score"]),
            normalised,
            f"{r['iqm']:.2f} [{r['low']:.2f}, {r['high']:.2f}]",
            _format_interval(r["held_out"]),
            f"{r['gap']:.3g}" if r["gap"] is not None else "-",
            _format_seed_scores(r),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _format_seed_scores(row: dict) -> str:
    """``0.98, 0.96, 0.53; 0.9, 0.8, 0.4``: each training seed's score on the default and the held-out layouts."""
    if row["seed_scores"] is None:
        return "-"
    parts = [row["seed_scores"], row["held_out_seed_scores"] or []]
    return "; ".join(", ".join(f"{v:.3g}" for v in values) for values in parts if values)


def _details_table(env_id: str, rows: list[dict]) -> list[str]:
    """RL Zoo's columns and every task metric (means), in a collapsed block below the headline table."""
    metric_names = sorted(set().union(*(r["metrics"].keys() for r in rows)) - {"return", "length"})
    header = ["algo", "env_id", "mean_reward", "std_reward", "n_timesteps", "eval_episodes", "seeds", "IQM [95% CI]"]
    lines = [
        "<details><summary>RL Zoo's columns and the task metrics (means over the default layouts' episodes)</summary>",
        "",
        "| " + " | ".join(header + metric_names) + " |",
        "|" + "---|" * (len(header) + len(metric_names)),
    ]
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
        ]
        row += [f"{r['metrics'][m]:.3g}" if m in r["metrics"] else "-" for m in metric_names]
        lines.append("| " + " | ".join(row) + " |")
    return [*lines, "", "</details>"]


#: The layouts an agent must have trained on for the verdict to count it (the Procgen protocol: train on the training
#: distribution, judge on the held-out one).
COUNTED_TRAINING_LAYOUTS = "train"
#: Which layouts' comparison the verdict counts, and which it shows beside.
_LAYOUT_KEYS = {"held_out": ("held_out_runs", "held_out_tie_runs"), "default": ("score_runs", "tie_runs")}


def _compare(agent: dict, reference: dict, score, layouts: str) -> Comparison | None:
    """The agent against the reference on ``layouts`` ("default" or "held_out"): the difference of the task score
    with its run-level interval (and of the tie-break metric where both are at the ceiling), or None without
    values on both sides."""
    runs, ties = _LAYOUT_KEYS[layouts]
    if agent[runs] is None or reference[runs] is None:
        return None
    return compare(
        agent[runs],
        reference[runs],
        aggregate=score.aggregate,
        direction=score.direction,
        ceiling=score.ceiling,
        agent_tie_groups=agent[ties],
        reference_tie_groups=reference[ties],
        tie_direction=score.tie_direction,
    )


def _beats(comparison: Comparison | None) -> bool:
    return comparison is not None and comparison.outcome == "better"


def is_counted(agent: dict) -> bool:
    """Whether the verdict counts an agent's row: every seed trained on the training layouts only."""
    return agent["training_layouts"] == COUNTED_TRAINING_LAYOUTS


def agent_verdict(table: dict) -> dict | None:
    """Whether a trained agent beats the paper's algorithm (the upper anchor where the row names one) on a table of
    :func:`leaderboard_tables`, with the run as the unit: ``{"reference", "agent" (the best agent's row),
    "held_out", "default" (bools: the interval of agent minus reference wholly on the better side, or both at the
    ceiling and the tie-break's difference so), "comparisons" (layouts -> :class:`~polyenvs.statistics.Comparison`
    or None), "improvement" (P(agent > reference) on the held-out layouts, ``(p, low, high)``, or None), "counted"
    (the agent trained on the training layouts)}``, or None without a score, a reference or an agent.

    The best agent is the first ranked that beats the reference on the held-out layouts, counted agents before
    others, then one that beats it on the default layouts, else the best ranked.
    """
    score, rows = table["score"], table["rows"]
    kind = "anchor" if score is not None and score.upper_anchor else "paper"
    reference = next((r for r in rows if r["kind"] == kind), None)
    agents = [r for r in rows if r["kind"] == "agent" and r["score"] is not None]
    if score is None or reference is None or not agents:
        return None
    verdicts = [_verdict_of(agent, reference, score) for agent in agents]
    return max(verdicts, key=lambda v: (v["counted"], v["held_out"], v["default"]))  # max keeps the first of equals


def _verdict_of(agent: dict, reference: dict, score) -> dict:
    comparisons = {layouts: _compare(agent, reference, score, layouts) for layouts in _LAYOUT_KEYS}
    improvement = None
    if agent["held_out_runs"] is not None and reference["held_out_runs"] is not None:
        improvement = probability_of_improvement(
            agent["held_out_runs"], reference["held_out_runs"], score.aggregate, score.direction
        )
    return {
        "reference": reference,
        "agent": agent,
        "held_out": _beats(comparisons["held_out"]),
        "default": _beats(comparisons["default"]),
        "comparisons": comparisons,
        "improvement": improvement,
        "counted": is_counted(agent),
    }


def _format_difference(comparison: Comparison | None) -> str:
    """``+0.04 [0.01, 0.07] (+5.0%)``: agent minus reference with its interval and relative change; the tie-break's
    difference after it where it decided."""
    if comparison is None:
        return "-"
    d = comparison.score
    text = f"{d.value:+.3g} [{d.low:.3g}, {d.high:.3g}]"
    text += f" ({100 * d.relative:+.1f}%)" if d.relative is not None else ""
    if comparison.tie_break is not None:
        tie = comparison.tie_break
        text += f"; tie-break {tie.value:+.3g} [{tie.low:.3g}, {tie.high:.3g}]"
    return text


def _format_probability(improvement: tuple[float, float, float] | None) -> str:
    return "-" if improvement is None else f"{improvement[0]:.2f} [{improvement[1]:.2f}, {improvement[2]:.2f}]"


_VERDICT_HEADER = (
    "| environment | paper's algorithm (or anchor), held-out | best trained agent, held-out (trained on) | "
    "held-out difference [95% CI] (relative) | P(agent > paper), held-out | beats it on held-out layouts | "
    "on the default layouts |"
)


def _verdict_section(tables: dict[str, dict]) -> list[str]:
    """The question the leaderboard answers, per environment: does a trained agent beat the paper's algorithm on
    layouts it never trained on?"""
    lines = [
        "## Does a trained agent beat the paper's algorithm?",
        "",
        'On layouts it never trained on: the held-out ones (`layouts="test"`), the default ones beside. Beats: '
        "the 95% interval of the difference of the task score, agent minus the paper's algorithm (the upper "
        "anchor, on a row that names one), lies wholly on the better side of 0, with the training run as the unit "
        "(a two-level bootstrap: training seeds, then episodes within each; the reference's episodes); or both "
        "are at the score's ceiling and the interval of the difference of the tie-break metric's mean lies wholly "
        "on its better side. P(agent > paper) is rliable's probability of improvement: the chance that a training "
        "run of the agent scores better than the paper's algorithm. Only agents trained on the training layouts "
        f'(`layouts="{COUNTED_TRAINING_LAYOUTS}"`) are counted; others are shown, labelled with what they trained on.',
        "",
        _VERDICT_HEADER,
        "|---|---|---|---|---|---|---|",
    ]
    counts = {"held": 0, "default": 0, "any_held": 0, "any_default": 0, "total": 0, "counted": 0}
    for env_id, table in tables.items():
        verdict, successor = agent_verdict(table), _superseded_by(env_id)
        counts["total"] += successor is None
        if successor is not None:
            env_id = f"{env_id} (superseded by {successor}: not counted)"
        if verdict is None:
            reference = next((r for r in table["rows"] if r["kind"] in ("paper", "anchor")), None)
            name = f"{reference['label']} {_format_interval(reference['held_out'])}" if reference else "-"
            lines.append(f"| {env_id} | {name} | no trained agent | - | - | - | - |")
            continue
        if successor is None:
            _count(counts, verdict)
        lines.append("| " + " | ".join(_verdict_cells(env_id, verdict)) + " |")
    summary = (
        f"Counting agents trained on the training layouts: a trained agent beats the paper's algorithm on the "
        f"held-out layouts on {counts['held']} of the {counts['total']} environments the benchmark ranks on "
        f"({counts['counted']} have such an agent), and on the default layouts on {counts['default']}. Counting "
        f"every agent, whatever it trained on: {counts['any_held']} on the held-out layouts, "
        f"{counts['any_default']} on the default ones."
    )
    return [*lines[:2], summary, "", *lines[2:], ""]


def _count(counts: dict, verdict: dict) -> None:
    counts["any_held"] += verdict["held_out"]
    counts["any_default"] += verdict["default"]
    if verdict["counted"]:
        counts["counted"] += 1
        counts["held"] += verdict["held_out"]
        counts["default"] += verdict["default"]


def _verdict_cells(env_id: str, verdict: dict) -> list[str]:
    ref, agent = verdict["reference"], verdict["agent"]
    trained_on = f"{agent['training_layouts']} layouts" + ("" if verdict["counted"] else ": not counted")
    return [
        env_id,
        f"{ref['label']} {_format_interval(ref['held_out'])}",
        f"{agent['label']} {_format_interval(agent['held_out'])} ({trained_on})",
        _format_difference(verdict["comparisons"]["held_out"]),
        _format_probability(verdict["improvement"]),
        "**yes**" if verdict["held_out"] else "no",
        "**yes**" if verdict["default"] else "no",
    ]


def _episode_counts(documents: list[dict]) -> str:
    """How many episodes each policy ran: the usual count, then the environments that ran another."""
    per_env: dict[str, set[int]] = {}
    for doc in documents:
        per_env.setdefault(doc["env_id"], set()).add(int(doc["n_episodes"]))
    counts = [n for ns in per_env.values() for n in ns]
    usual = max(set(counts), key=counts.count) if counts else 0
    others = [f"{'/'.join(map(str, sorted(ns)))} on {env_id}" for env_id, ns in per_env.items() if ns != {usual}]
    return f"{usual}" + (f" ({'; '.join(others)})" if others else "")


def leaderboard_markdown(
    documents: list[dict],
    quick: bool | None = None,
    plots: dict[str, str] | None = None,
    profile: str | None = None,
) -> str:
    """The leaderboard as Markdown: per environment, the headline table (ranked by the task score) and RL Zoo's
    columns with the task metrics in a collapsed block; with ``plots`` (env id -> PNG file name relative to the
    table) a link to each environment's interval plot, with ``profile`` to the performance profile.

    ``quick`` (the table warns that numbers are indicative) defaults to: some result has fewer than
    :data:`PROTOCOL_EPISODES` episodes.
    """
    counts = sorted({int(d["n_episodes"]) for d in documents})
    if quick is None:
        quick = any(n < PROTOCOL_EPISODES for n in counts)
    each = f"Each policy (each training seed of a trained agent): {_episode_counts(documents)} evaluation episodes"
    lines = [
        "# polyenvs leaderboard",
        "",
        f"{each} on seeds {EVAL_SEED}, {EVAL_SEED + 1}, ... (the same for every policy), deterministic actions, on "
        'the default layouts and on the held-out ones (`layouts="test"`, which no training run sees). Rows are '
        "ranked by each environment's task score (the episode metric that is its paper's task, declared on its "
        "registry row): its interquartile mean (IQM; the mean for a success rate) with a 95% stratified bootstrap "
        "interval, normalised so that "
        "random = 0 and the paper's algorithm (or a stated upper anchor) = 1, unless their intervals overlap "
        '("not discriminative"). The return\'s IQM is shown beside it. The gap is the default score minus the '
        "held-out one, in the score's units, positive where the held-out layouts are worse. A trained algorithm's "
        "row pools the episodes of all its training seeds, and its interval takes the run as the unit (a two-level "
        "bootstrap: training seeds drawn with replacement, then episodes within each); each seed's own score is "
        "in the last column.",
        "",
    ]
    if quick:
        lines += [
            f"**Quick mode**: fewer episodes than the protocol's {PROTOCOL_EPISODES}; numbers are indicative only.",
            "",
        ]
    tables = leaderboard_tables(documents)
    lines += _verdict_section(tables)
    if profile:
        lines += [f"![Performance profile of the normalised task scores over the environments]({profile})", ""]
    for env_id, table in tables.items():
        lines += [f"## {env_id}", "", *environment_section(env_id, table, (plots or {}).get(env_id))]
    return "\n".join(lines)


def environment_section(env_id: str, table: dict, plot: str | None = None) -> list[str]:
    """One environment's part of the leaderboard (a table of :func:`leaderboard_tables`), as Markdown lines: the
    score's line, the link to its interval plot (``plot``, a path relative to the page), the headline table and
    the collapsed details."""
    lines = [_score_line(env_id, table), ""]
    if plot:
        lines += [f"![The task score and its 95% interval per policy on {env_id}]({plot})", ""]
    return [*lines, *_headline_table(table), "", *_details_table(env_id, table["rows"]), ""]


def profile_path(table: Path) -> Path:
    """The performance profile's PNG beside the Markdown table: ``<table stem>_profile.png``."""
    table = Path(table)
    return table.parent / f"{table.stem}_profile.png"


def write_leaderboard(
    documents: list[dict], path: Path, quick: bool | None = None, progress: Callable[[str], None] = print
) -> str:
    """Write the Markdown table to ``path`` and its charts beside it (:func:`plot_path`, :func:`profile_path`),
    drawn with matplotlib (the ``plots`` extra); without it the table is written alone and ``progress`` says so."""
    from polyenvs import charts

    path = Path(path)
    tables = leaderboard_tables(documents)
    plots, profile = {}, None
    if charts.available():
        for env_id, table in tables.items():
            charts.save(charts.interval_plot(env_id, table), plot_path(path, env_id))
            plots[env_id] = plot_path(path, env_id).name
        figure = charts.performance_profile_plot(tables)
        if figure is not None:
            charts.save(figure, profile_path(path))
            profile = profile_path(path).name
    else:
        progress(f"charts left out: they need matplotlib: {charts.INSTALL_HINT}")
    text = leaderboard_markdown(documents, quick=quick, plots=plots, profile=profile)
    write_text_atomic(path, text)
    return text
