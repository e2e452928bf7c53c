"""Run the leaderboard's evaluations (``polyenvs leaderboard``): every policy on every environment, on the protocol.

Policies: random, every hand baseline, and every trained agent committed under the agents directory
(:func:`~polyenvs.evaluation.agents.find_agents`) or named on the command line, all on the same published seeds
(:mod:`~polyenvs.evaluation.protocol`), on the default layouts and on the held-out ones. Each evaluation is a result
file of its own (:mod:`~polyenvs.evaluation.results`), written atomically; a re-run skips what is done unless asked
to redo it, and re-runs (saying why) a file that is unreadable, not a result, for another number of episodes, or
(for an agent) for another version of the model (its SHA-256 differs). The evaluations run one by one here, or
through :func:`polyenvs.pool.run_jobs` on a local process pool (``workers``) or on Ray (``backend="ray"``: a local
instance of ``workers`` CPUs or, with ``address``, a running cluster), with the same results: each evaluation is
seeded on its own, and its result file is written here, in the parent, as it finishes (a run killed midway keeps what
finished, and a re-run does the rest). On a cluster the nodes read the trained agents' models from the same paths
as here: every node needs polyenvs and the agents directory at the same place (a shared file system, or the same
checkout), but not the results directory.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from polyenvs.errors import InputError
from polyenvs.evaluation.agents import Agent, agent_from_path, check_agent, find_agents, unfinished
from polyenvs.evaluation.episodes import evaluate
from polyenvs.evaluation.protocol import (
    EVAL_SEED,
    LAYOUTS,
    layouts_kwargs,
    leaderboard_policies,
    old_versions_quietly,
    protocol_episodes,
)
from polyenvs.evaluation.results import evaluation_title, load_result, provenance, result_path
from polyenvs.files import write_json_atomic
from polyenvs.pool import check_backend, run_jobs
from polyenvs.registry import ParallelEnvEntry, entry

__all__ = ["Listeners", "run_leaderboard", "step_budget"]


@dataclass(frozen=True)
class Listeners:
    """What a leaderboard run tells its caller: ``progress(line)`` a line per finished evaluation (and per result
    reused or redone), ``on_plan(total_episodes)`` once before the first evaluation, ``on_episode(result)`` after
    each episode (with workers, for each episode of an evaluation when it finishes)."""

    progress: Callable[[str], None] = print
    on_plan: Callable[[int], None] | None = None
    on_episode: Callable[[dict], None] | None = None


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
        return evaluation_title(self.env_id, self.name, self.layouts)


def run_leaderboard(  # noqa: PLR0913 - keyword-only after the two the command always gives, each documented
    env_ids: list[str],
    episodes: int | None,
    *,
    results_dir: Path,
    redo: bool = False,
    listeners: Listeners | None = None,
    agents_dir: Path | None = None,
    extra_agents: list[str] | tuple[str, ...] = (),
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
) -> list[dict]:
    """Evaluate ``random``, every hand baseline and every trained agent on each environment, on the default layouts
    and (where the environment takes ``layouts=``) the held-out ones; returns the documents. ``episodes`` per
    policy, or ``None`` for the protocol's count of each environment
    (:func:`~polyenvs.evaluation.protocol.protocol_episodes`).

    Agents are the committed ones under ``agents_dir`` (see :func:`~polyenvs.evaluation.agents.find_agents`) plus
    ``extra_agents`` (paths whose run.json names one of ``env_ids``); every agent that needs evaluating is loaded
    and checked against its environment first, so a broken one raises :class:`~polyenvs.errors.InputError` before
    any episode runs. Results already in ``results_dir`` for ``episodes`` episodes (and, for an agent, the same
    model) are reused unless ``redo``; anything else there is evaluated again and ``listeners.progress`` says which
    file and why (:class:`Listeners`: by default lines are printed). With ``workers`` > 1 the evaluations run on that
    many processes, and with ``backend="ray"`` on Ray (``address``: a running cluster's; see
    :func:`polyenvs.pool.run_jobs`), with the same results as one by one. An agent's document carries
    ``"agent": {"algo", "label", "training_seed", ...}``.
    """
    check_backend(backend, address)
    listeners = listeners if listeners is not None else Listeners()
    agents = _agents_of(env_ids, agents_dir, extra_agents)
    plan = _plan_evaluations(env_ids, episodes, results_dir, redo, listeners.progress, agents)
    todo = [item for item in plan if item.doc is None]
    if listeners.on_plan is not None:
        listeners.on_plan(sum(item.episodes for item in todo))

    def finish(item: _Evaluation, doc: dict, seconds: float) -> None:
        doc["n_episodes"] = item.episodes
        if item.agent is not None:
            doc["agent"] = item.agent.meta()
        doc.update(provenance())
        write_json_atomic(item.path, doc)
        item.doc = doc
        done = sum(i.doc is not None for i in todo)
        listeners.progress(
            f"{item.title}: {item.episodes} episode{'s' if item.episodes != 1 else ''} in {seconds:.1f} s "
            f"({done}/{len(todo)})"
        )

    if backend == "ray" or (workers > 1 and len(todo) > 1):
        _evaluate_in_pool(todo, workers, finish, listeners.on_episode, backend, address)
    else:
        _evaluate_in_turn(todo, finish, listeners.on_episode)
    for item in plan:
        if item.agent is not None:
            item.doc["agent"] = item.agent.meta()  # the row it joins now (a --policy agent is labelled by its path)
    return [item.doc for item in plan]


def _agents_of(env_ids: list[str], agents_dir: Path | None, extra_agents) -> dict[str, list[Agent]]:
    """Each environment's trained agents: the committed ones under ``agents_dir``, then the ``extra_agents``."""
    agents: dict[str, list[Agent]] = {env_id: find_agents(agents_dir, env_id) for env_id in env_ids}
    for path in extra_agents:
        agent = agent_from_path(path)
        if agent.env_id not in agents:
            raise InputError(f"--policy {path}: trained on {agent.env_id}, which is not among the environments run")
        agents[agent.env_id].append(agent)
    return agents


def _evaluate_in_turn(todo: list[_Evaluation], finish, on_episode) -> None:
    """The evaluations one after the other, in this process."""
    for item in todo:
        started = time.monotonic()
        kwargs = layouts_kwargs(item.layouts)
        with old_versions_quietly():
            doc = evaluate(item.env_id, item.policy, episodes=item.episodes, seed=EVAL_SEED, env_kwargs=kwargs or None,
                           on_episode=on_episode)  # fmt: skip
        finish(item, doc, time.monotonic() - started)


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
                sha = check_agent(agent, envs) if agent is not None else None
                name = agent.name if agent is not None else policy
                if agent is not None and agent.run.get("completed") is False:
                    progress(f"{env_id} {name}: {unfinished(agent)} (interrupted); included as it is")
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


def _evaluate_in_pool(todo: list[_Evaluation], workers: int, finish, on_episode, backend: str, address) -> None:
    """The evaluations as jobs on ``backend``'s workers; ``finish`` writes each one's file here as it comes back."""
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
        raise exc  # as the serial run would (on Ray, a RayTaskError that is also the job's error): the rest is cancelled

    run_jobs(_evaluate_one, jobs, workers, on_result, on_error, backend=backend, address=address)
