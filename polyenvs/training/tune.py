"""Tuning a hand baseline on the training layouts (``polyenvs tune``; the ``tune`` extra: Optuna).

A black-box search over the parameters the baseline declares tunable (:attr:`baselines.base.Policy.tunables`, listed
by :func:`baselines.factory.tunable_parameters`), with Optuna's TPE or CMA-ES sampler and its median pruner. The
objective is the environment's task score (:class:`polyenvs.registry.Score`: its metric, aggregated as the
leaderboard aggregates it) over a fixed set of episodes on the training layouts, the same episodes for every trial:
seeds :func:`tuning_seeds` of the tuning seed, apart from the leaderboard's. The first trial is the baseline as it
ships (the paper's values), so the search never ends below it on its own objective. ``limits`` constrain episode
metrics' means (the beasts' ``mean_power_w`` at most the first trial's: "on the same power"): TPE's constrained
search, and the best trial is the best that keeps them.

The study lives in an Optuna storage: ``<out>/study.db`` (SQLite), or ``storage``, a URL several workers on several
machines share. Each trial's sampler is seeded from the tuning seed and the number of trials finished before it, so
a study killed (even with -9) and run again picks up where it stopped and asks what it would have asked: the trial
that was running is marked failed and asked again. After every trial ``<out>/tuned.json`` is rewritten atomically:
the best parameters so far (the directory is then a policy, :mod:`baselines.tuned`), the history, the command, the
wall clock and the versions; ``completed`` says whether every trial has run.
"""

from __future__ import annotations

import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from baselines.factory import TunableParameter, paper_policy, tunable_parameters
from baselines.table import hand_baselines
from baselines.tuned import TUNED_FILE, read_tuned
from polyenvs.errors import InputError
from polyenvs.evaluation.episodes import make_agent, make_env
from polyenvs.evaluation.protocol import old_versions_quietly
from polyenvs.evaluation.rollout import final_metrics, is_parallel, run_episode
from polyenvs.evaluation.statistics import interquartile_mean
from polyenvs.files import directory_lock, write_json_atomic
from polyenvs.registry import Score, bare_id, entry
from polyenvs.training.train import git_commit, versions

__all__ = ["DEFAULT_EPISODES", "SAMPLERS", "STUDY_FILE", "TuneRequest", "check_request", "tune", "tuning_seeds"]

#: Training episodes per trial (the objective's), unless the request says otherwise.
DEFAULT_EPISODES = 20
#: The layouts a tuning draws its episodes from: those agents train on.
TUNE_LAYOUTS = "train"
#: The study's SQLite file in the output directory (where no ``storage`` URL is given).
STUDY_FILE = "study.db"
SAMPLERS = ("tpe", "cmaes")
#: A limit that is the first trial's own mean of the metric.
FIRST = "first"
#: Tuning seed S runs episodes ``SEED_BASE + S * SEED_STRIDE + i``: far from the leaderboard's (1000 on) and apart
#: for each tuning seed, so that the tuning runs are independent runs.
SEED_BASE, SEED_STRIDE = 1_000_000, 10_000
#: A ceiling reached lifts the objective by this much plus the tie-break's share (:func:`_objective_value`).
_CEILING_LIFT = 1.0


@dataclass(frozen=True)
class TuneRequest:
    """One tuning into one output directory; ``policy`` is a hand baseline's name or ``"paper"``."""

    env_id: str
    policy: str
    trials: int
    seed: int
    out: Path
    episodes: int = DEFAULT_EPISODES
    sampler: str = "tpe"
    storage: str | None = None
    env_kwargs: dict = field(default_factory=dict)
    command: str | None = None
    #: Episode metric -> the most its mean over a trial's episodes may be: a number, or :data:`FIRST` (the first
    #: trial's mean, the baseline as it ships, on the same episodes).
    limits: dict = field(default_factory=dict)


@dataclass(frozen=True)
class _Target:
    """What a request resolves to, checked before any trial: the bare id, the baseline's name, what it may tune,
    the score and the keywords the training layouts add."""

    env_id: str
    baseline: str
    space: list[TunableParameter]
    score: Score
    env_kwargs: dict


def tuning_seeds(seed: int, episodes: int) -> list[int]:
    """The episode seeds of tuning seed ``seed``: the same for every trial of its study."""
    first = SEED_BASE + seed * SEED_STRIDE
    return list(range(first, first + episodes))


def check_request(request: TuneRequest) -> _Target:
    """Everything about ``request`` that can be wrong, checked before any work: :class:`InputError` (one line)."""
    env_id = bare_id(request.env_id)
    try:
        score = entry(env_id).score
    except KeyError:
        raise InputError(f"unknown environment id {env_id!r} (run 'polyenvs list' for ours)") from None
    if score is None:
        raise InputError(f"{env_id} has no task score to tune for")
    names = hand_baselines(env_id).names
    baseline = paper_policy(env_id) if request.policy == "paper" else request.policy
    if baseline not in names:
        choices = ", ".join([*names, "paper"] if names else names) or "none"
        raise InputError(f"--policy {request.policy}: not a hand baseline of {env_id} (choose from {choices})")
    space = tunable_parameters(baseline, env_id)
    if not space:
        raise InputError(f"--policy {baseline}: declares no tunable parameters")
    if request.sampler not in SAMPLERS:
        raise InputError(f"--sampler must be one of {', '.join(SAMPLERS)}, got {request.sampler!r}")
    if "layouts" in request.env_kwargs:
        raise InputError(f"--env-kwargs: a tuning runs on layouts={TUNE_LAYOUTS!r}; do not set layouts")
    if request.limits and request.sampler != "tpe":
        raise InputError("--max-mean needs --sampler tpe (Optuna's CMA-ES sampler takes no constraints)")
    for metric, limit in request.limits.items():
        if limit != FIRST and (isinstance(limit, bool) or not isinstance(limit, int | float) or not np.isfinite(limit)):
            raise InputError(f"--max-mean {metric}: the limit must be a finite number or {FIRST!r}, got {limit!r}")
    env_kwargs = {**request.env_kwargs, "layouts": TUNE_LAYOUTS}
    _check_same_study(request, env_id, str(baseline))
    with old_versions_quietly():
        names = _metric_names(make_env(env_id, env_kwargs))  # a rejected keyword raises there, before the study
    unknown = sorted(set(request.limits) - names)
    if unknown:
        raise InputError(
            f"--max-mean {unknown[0]}: {env_id} has no such episode metric (it has {', '.join(sorted(names))})"
        )
    return _Target(env_id, str(baseline), space, score, env_kwargs)


def _metric_names(env) -> set[str]:
    """The episode metrics ``env`` reports (after one step of sampled actions), and closes it."""
    try:
        if is_parallel(env):
            env.reset(seed=0)
            _, _, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
            swarm = getattr(env.unwrapped, "episode_metrics", None)
            return set(swarm() if swarm is not None else next(iter(infos.values())).get("episode_metrics", {}))
        env.reset(seed=0)
        return set(final_metrics(env, env.step(env.action_space.sample())[4]))
    finally:
        env.close()


def _check_same_study(request: TuneRequest, env_id: str, baseline: str) -> None:
    """An output directory that holds a tuning already must hold this one (to go on with), not another."""
    if not (request.out / TUNED_FILE).is_file():
        return
    try:
        doc = read_tuned(request.out)
    except ValueError as exc:
        raise InputError(f"--out {request.out}: {exc}") from None
    ours = {"env_id": env_id, "policy": baseline, "seed": request.seed, "sampler": request.sampler}
    for key, value in ours.items():
        if doc.get(key) != value:
            raise InputError(
                f"--out {request.out} holds a tuning with {key} {doc.get(key)!r}, not {value!r}: give another directory"
            )
    if doc.get("objective", {}).get("episodes") != request.episodes:
        raise InputError(f"--out {request.out} holds a tuning of {doc['objective']['episodes']} episodes per trial")


def _optuna():
    try:
        import optuna
    except ModuleNotFoundError:
        raise InputError('polyenvs tune needs Optuna: pip install "polyenvs[tune]"') from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna


def _sampler(optuna, request: TuneRequest, seed: int):
    if request.sampler == "cmaes":
        return optuna.samplers.CmaEsSampler(seed=seed, warn_independent_sampling=False)
    return optuna.samplers.TPESampler(seed=seed)  # it reads the constraints a trial sets


def _feasible(trial) -> bool:
    return all(c <= 0 for c in trial.user_attrs.get("constraints", []))


def _aggregate(score: Score, values: list[float]) -> float:
    return float(np.mean(values)) if score.aggregate == "mean" else interquartile_mean(values)


def _objective_value(score: Score, value: float, tie: float | None) -> float:
    """What the study maximises: the score in its better direction; at the score's ceiling, above every score below
    it by :data:`_CEILING_LIFT`, plus the tie-break's mean squashed into (0, 1) in its better direction (so that
    among trials at the ceiling the tie-break orders them, as the leaderboard ranks)."""
    signed = score.sign * value
    if score.ceiling is None or value != score.ceiling or tie is None:
        return signed
    t = score.tie_sign * tie
    return signed + _CEILING_LIFT + 0.5 * (1.0 + t / (1.0 + abs(t)))


class _Objective:
    """One trial: the baseline with the trial's parameters over the tuning's episodes."""

    def __init__(self, optuna, target: _Target, env, request: TuneRequest):
        self.optuna, self.target, self.env, self.request = optuna, target, env, request
        self.seeds = tuning_seeds(request.seed, request.episodes)

    def __call__(self, trial) -> float:
        target, score = self.target, self.target.score
        params = {p.name: trial.suggest_float(p.name, p.low, p.high) for p in target.space}
        try:
            agent = make_agent(target.baseline, target.env_id, self.env, seed=self.request.seed, policy_kwargs=params)
        except InputError as exc:  # a combination the baseline refuses (a turn band upside down)
            trial.set_user_attr("refused", str(exc))
            for metric in self.request.limits:
                trial.set_constraint(metric, float("inf"))
            raise self.optuna.TrialPruned() from None
        values, ties, limited = [], [], {m: [] for m in self.request.limits}
        for step, seed in enumerate(self.seeds):
            metrics = run_episode(self.env, agent, seed)["metrics"]
            values.append(float(metrics[score.metric]))
            if score.tie_break is not None and score.tie_break in metrics:
                ties.append(float(metrics[score.tie_break]))
            for metric, seen in limited.items():
                seen.append(float(metrics[metric]))
            trial.report(score.sign * float(np.mean(values)), step)
            if trial.should_prune():
                self._constrain(trial, limited)
                raise self.optuna.TrialPruned()
        self._constrain(trial, limited)
        value = _aggregate(score, values)
        tie = float(np.mean(ties)) if ties else None
        trial.set_user_attr("score", value)
        trial.set_user_attr("tie", tie)
        return _objective_value(score, value, tie)

    def _constrain(self, trial, limited: dict[str, list[float]]) -> None:
        """Set the trial's constraints (Optuna's, which TPE reads, and ours to report): how far the limited metrics'
        means over its episodes are over their limits (the first trial's own means for a limit of :data:`FIRST`)."""
        if not limited:
            return
        means = {metric: float(np.mean(seen)) for metric, seen in limited.items()}
        done = trial.study.get_trials(deepcopy=False, states=(self.optuna.trial.TrialState.COMPLETE,))
        first = done[0].user_attrs["means"] if done else means  # the first is the baseline as it ships
        over = [means[m] - (first[m] if limit == FIRST else limit) for m, limit in self.request.limits.items()]
        trial.set_user_attr("means", means)
        trial.set_user_attr("constraints", over)
        for metric, value in zip(self.request.limits, over, strict=True):
            trial.set_constraint(metric, value)


def _study(optuna, request: TuneRequest, target: _Target):
    """The request's study, created (its first trial the baseline as it ships) or loaded to go on."""
    storage = request.storage or f"sqlite:///{(request.out / STUDY_FILE).absolute()}"
    name = f"{target.env_id}:{target.baseline}:seed{request.seed}"
    pruner = optuna.pruners.MedianPruner(n_startup_trials=5, n_warmup_steps=max(1, request.episodes // 2))
    study = optuna.create_study(
        storage=storage, study_name=name, direction="maximize", pruner=pruner, load_if_exists=True
    )
    states = optuna.trial.TrialState
    if request.storage is None:  # ours alone: a trial left running was killed with the process
        for trial in study.get_trials(deepcopy=False, states=(states.RUNNING,)):
            study.tell(trial.number, state=states.FAIL)
    if not study.get_trials(deepcopy=False, states=(states.COMPLETE, states.PRUNED, states.WAITING)):
        study.enqueue_trial({p.name: p.start for p in target.space})  # (again, if the kill cut it short)
    return study


def _finished(optuna, study) -> int:
    states = optuna.trial.TrialState
    return len(study.get_trials(deepcopy=False, states=(states.COMPLETE, states.PRUNED)))


def _history(study) -> list[dict]:
    return [
        {
            "number": t.number,
            "state": t.state.name.lower(),
            "params": t.params,
            "value": t.value,
            "score": t.user_attrs.get("score"),
            "tie": t.user_attrs.get("tie"),
            **({"means": t.user_attrs["means"], "feasible": _feasible(t)} if "means" in t.user_attrs else {}),
            **({"refused": t.user_attrs["refused"]} if "refused" in t.user_attrs else {}),
        }
        for t in study.get_trials(deepcopy=False)
    ]


def _document(optuna, request: TuneRequest, target: _Target, study, wall_clock_s: float) -> dict:
    """tuned.json: the best parameters so far and everything needed to judge and repeat how they were found."""
    complete = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    feasible = [t for t in complete if _feasible(t)]
    best = max(feasible, key=lambda t: t.value) if feasible else None  # max keeps the earliest of equals
    start = {p.name: p.start for p in target.space}
    seeds = tuning_seeds(request.seed, request.episodes)
    return {
        "env_id": target.env_id,
        "policy": target.baseline,
        "params": best.params if best is not None else start,
        "paper_params": start,
        "space": {p.name: {"low": p.low, "high": p.high, "unit": p.unit, "source": p.source} for p in target.space},
        "best": None
        if best is None
        else {
            "trial": best.number,
            "score": best.user_attrs.get("score"),
            "tie": best.user_attrs.get("tie"),
        },  # fmt: skip
        "objective": {
            "metric": target.score.metric,
            "aggregate": target.score.aggregate,
            "direction": target.score.direction,
            "tie_break": target.score.tie_break,
            "episodes": request.episodes,
            "episode_seeds": [seeds[0], seeds[-1]],
            "limits": request.limits,
        },
        "env_kwargs": target.env_kwargs,
        "seed": request.seed,
        "sampler": request.sampler,
        "trials": request.trials,
        "finished_trials": _finished(optuna, study),
        "completed": _finished(optuna, study) >= request.trials,
        "history": _history(study),
        "command": request.command or shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "wall_clock_s": round(wall_clock_s, 3),
        "versions": {**versions(), "optuna": optuna.__version__},
        "git_commit": git_commit(),
    }


def tune(request: TuneRequest, progress=print) -> dict:
    """Run (or go on with) the study of ``request`` until it has ``request.trials`` finished trials; returns the
    tuned.json document. ``progress(line)`` gets a line per trial."""
    optuna = _optuna()
    target = check_request(request)
    request.out.mkdir(parents=True, exist_ok=True)
    with directory_lock(request.out, "tuned into"):  # a second process would fail this one's running trial
        return _run_study(optuna, request, target, progress)


def _run_study(optuna, request: TuneRequest, target: _Target, progress) -> dict:
    study = _study(optuna, request, target)
    tuned_file = request.out / TUNED_FILE
    before = _previous_wall_clock(tuned_file)
    started = time.monotonic()
    with old_versions_quietly():
        env = make_env(target.env_id, target.env_kwargs)
    try:
        objective = _Objective(optuna, target, env, request)
        while (done := _finished(optuna, study)) < request.trials:
            study.sampler = _sampler(optuna, request, request.seed * 1_000_003 + done)
            study.optimize(objective, n_trials=1)
            trial = study.trials[-1]
            doc = _document(optuna, request, target, study, before + time.monotonic() - started)
            write_json_atomic(tuned_file, doc)
            progress(f"trial {trial.number} ({trial.state.name.lower()}): score {trial.user_attrs.get('score')}")
    finally:
        env.close()
    doc = _document(optuna, request, target, study, before + time.monotonic() - started)
    write_json_atomic(tuned_file, doc)
    return doc


def _previous_wall_clock(tuned_file: Path) -> float:
    """The wall clock a resumed study had spent before (0 for a new one)."""
    if not tuned_file.is_file():
        return 0.0
    try:
        return float(read_tuned(tuned_file.parent).get("wall_clock_s", 0.0))
    except ValueError:
        return 0.0
