"""``polyenvs sweep``: train and evaluate every (environment, algorithm, seed) as independent jobs.

``polyenvs sweep --envs ID... --algos ALGO... --seeds S... [--timesteps N] [--config-dir DIR] [--backend local|ray]
[--address ADDR] [--jobs N] [--out DIR] [--episodes N]``

A job is :func:`polyenvs.training.train.train` of its :meth:`Job.request` into
``<out>/agents/<env id with / as __>/<algo>/seed<N>/`` (the layout of ``benchmarks/agents``) followed by
:func:`polyenvs.evaluation.episodes.evaluate` of that model on the leaderboard's evaluation seeds, written atomically
to ``<out>/results/<env id with / as __>__agent__<algo>__seed<N>.json`` (the leaderboard's result file for that
agent). The jobs run on a local process pool (``--jobs`` workers, one torch thread each) or, with ``--backend ray``,
as Ray tasks (one CPU each) on a local Ray instance or, with ``--address``, on a running cluster; the pool or Ray
schedules them (:func:`polyenvs.pool.run_jobs`, which the leaderboard's evaluations run on too). Jobs are
reproducible from their seeds, and a re-run skips what is done: ``train`` returns a finished run without training,
and a readable result file for the same number of episodes is kept. A job that was interrupted (Ctrl-C, or the sweep killed outright: its run.json says completed false) is resumed from its last saved
model (the request's ``resume=True``: the checkpoint every ``DEFAULT_CHECKPOINT_EVERY`` timesteps, or what Ctrl-C
saved), or trained again from the start if it saved none; its run.json lists the timesteps it resumed at
(``resumed_at``).

Every flag is checked before any job starts (one-line :class:`~polyenvs.errors.InputError`, exit 2; the flags are
:mod:`polyenvs.commands.sweep`'s). A failing
job is reported with its error in one line and the command exits 1 once the others finish; Ctrl-C stops the jobs
(a run interrupted mid-training keeps its partial model, ``run.json``: completed false, which a re-run resumes) and
exits 130.
"""

from __future__ import annotations

import itertools
import shlex
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from polyenvs.errors import InputError, shown
from polyenvs.files import check_writable_directory
from polyenvs.pool import one_line, run_jobs
from polyenvs.registry import bare_id, slug
from polyenvs.training import DEFAULT_CHECKPOINT_EVERY

if TYPE_CHECKING:
    from polyenvs.training.train import TrainRequest

__all__ = [
    "DEFAULT_SWEEP_DIR",
    "Job",
    "describe_result",
    "done_before",
    "plan_jobs",
    "run_job",
    "run_sweep",
    "summary_table",
]

#: Where ``polyenvs sweep`` writes by default (gitignored, like every run's output).
DEFAULT_SWEEP_DIR = Path("runs/sweep")


@dataclass(frozen=True)
class Job:
    """One (environment, algorithm, seed): where it trains, where its evaluation goes, and how."""

    env_id: str
    algo: str
    seed: int
    config: str
    timesteps: int | None
    episodes: int
    out_dir: str
    result_file: str
    checkpoint_every: int = DEFAULT_CHECKPOINT_EVERY

    @property
    def name(self) -> str:
        return f"{self.env_id} {self.algo} seed{self.seed}"

    def request(self) -> TrainRequest:
        """What :func:`~polyenvs.training.train.train` is asked to do for this job."""
        from polyenvs.training.train import TrainRequest

        return TrainRequest(
            self.env_id,
            self.algo,
            out_dir=Path(self.out_dir),
            config=self.config,
            timesteps=self.timesteps,
            seed=self.seed,
            checkpoint_every=self.checkpoint_every,
            resume=True,  # an interrupted run (Ctrl-C, or the sweep killed) continues from its saved model
            tensorboard=False,
            command=self.command(),
        )

    def command(self) -> str:
        """The ``polyenvs train`` command that trains this job alone (recorded in run.json)."""
        argv = ["polyenvs", "train", self.env_id, "--algo", self.algo, "--config", self.config]
        if self.timesteps is not None:
            argv += ["--timesteps", str(self.timesteps)]
        if self.checkpoint_every != DEFAULT_CHECKPOINT_EVERY:
            argv += ["--checkpoint-every", str(self.checkpoint_every)]
        return shlex.join([*argv, "--seed", str(self.seed), "--out", self.out_dir, "--no-progress"])


# ------------------------------------------------------------------------------------------------------- jobs


def run_job(job: Job) -> dict[str, Any]:
    """Train ``job`` (or find it finished), evaluate it (or find its result) and return what happened.

    Runs in a worker process. Returns ``{"job", "trained", "train_s", "evaluated", "iqm", "mean", "episodes"}``,
    or ``{"job", "error"}`` with the error in one line; Ctrl-C propagates.
    """
    from polyenvs.evaluation.agents import training_layouts
    from polyenvs.evaluation.episodes import evaluate
    from polyenvs.evaluation.protocol import EVAL_SEED
    from polyenvs.evaluation.results import load_result, provenance
    from polyenvs.evaluation.statistics import interquartile_mean
    from polyenvs.files import write_json_atomic
    from polyenvs.training.train import finished_run, read_run, train

    out_dir, result_file = Path(job.out_dir), Path(job.result_file)
    try:
        trained = finished_run(out_dir, job.env_id, job.algo, job.seed) is None
        before = read_run(out_dir) or {}
        train(job.request())
        run_doc = read_run(out_dir) or {}
        resumed = run_doc.get("resumed_at", [])
        resumed_from = resumed[-1] if trained and len(resumed) > len(before.get("resumed_at", [])) else None
        doc, _ = load_result(result_file, job.env_id, str(out_dir), job.episodes)
        evaluated = doc is None
        if doc is None:
            doc = evaluate(job.env_id, str(out_dir), episodes=job.episodes, seed=EVAL_SEED)
            doc["n_episodes"] = job.episodes
            doc["agent"] = {
                "algo": job.algo,
                "label": job.algo,
                "training_seed": job.seed,
                "timesteps": run_doc.get("timesteps"),
                "requested_timesteps": run_doc.get("requested_timesteps"),
                "completed": run_doc.get("completed"),
                "training_layouts": training_layouts(run_doc),
            }
            doc.update(provenance())
            write_json_atomic(result_file, doc)
        returns = [float(e["return"]) for e in doc["episodes"]]
    except Exception as exc:  # reported by the driver, which carries on with the other jobs
        return {"job": asdict(job), "error": one_line(exc)}
    return {
        "job": asdict(job),
        "trained": trained,
        "resumed_from": resumed_from,
        "train_s": float(run_doc.get("wall_clock_s", 0.0)),
        "evaluated": evaluated,
        "iqm": interquartile_mean(returns),
        "mean": sum(returns) / len(returns),
        "episodes": len(returns),
    }


# -------------------------------------------------------------------------------------------------- checking


def plan_jobs(
    envs: list[str],
    algos: list[str],
    seeds: list[int],
    *,
    out: Path,
    config_dir: Path | None = None,
    timesteps: int | None = None,
    episodes: int = 10,
    checkpoint_every: int = DEFAULT_CHECKPOINT_EVERY,
) -> list[Job]:
    """Check everything about a sweep (ids, algorithms, configs, output directories) and list its jobs.

    Raises :class:`InputError` (one line) for anything that cannot work, before any job starts.
    """
    import polyenvs  # noqa: F401  (registers the ids)

    ids = _checked_ids(envs)
    _check_algos(algos)
    configs = _config_files(algos, config_dir)
    _check_config_entries(ids, configs)
    out = Path(out).absolute()
    check_writable_directory(out, "--out")
    jobs = []
    for env_id, algo, seed in itertools.product(dict.fromkeys(ids), configs, dict.fromkeys(seeds)):
        out_dir = out / "agents" / slug(env_id) / algo / f"seed{seed}"
        _check_job_dir(out_dir, env_id, algo, seed)
        result = out / "results" / f"{slug(env_id)}__agent__{algo}__seed{seed}.json"
        jobs.append(
            Job(env_id, algo, seed, str(configs[algo]), timesteps, episodes, str(out_dir), str(result),
                checkpoint_every)
        )  # fmt: skip
    return jobs


def _checked_ids(envs: list[str]) -> list[str]:
    """``envs`` without Gymnasium's ``module:`` prefix; InputError (naming ``--envs``) for an unknown id."""
    from polyenvs.evaluation.rollout import unknown_id_help
    from polyenvs.registry import ALL_IDS

    ids = []
    for env_id in envs:
        bare = bare_id(env_id)
        if bare not in ALL_IDS:
            hint = unknown_id_help(bare)
            raise InputError(
                f"--envs: unknown environment id {shown(env_id)!r}{': ' + hint if hint else ''} (run 'polyenvs list' "
                "for the ids)"
            )
        ids.append(bare)
    return ids


def _check_algos(algos: list[str]) -> None:
    from baselines.algorithms import get_algo

    for algo in algos:
        try:
            get_algo(algo)
        except InputError as exc:
            raise InputError(f"--algos: {exc}") from None


def _config_files(algos: list[str], config_dir: Path | None) -> dict[str, Path]:
    """``{algo: its config file}``, each algorithm once, in the order given: ``config_dir/<algo>.yml``, or the
    shipped config without ``config_dir``."""
    if config_dir is not None and not Path(config_dir).is_dir():
        raise InputError(f"--config-dir {config_dir}: no such directory")
    return {algo: _config_file(algo, config_dir) for algo in dict.fromkeys(algos)}


def _config_file(algo: str, config_dir: Path | None) -> Path:
    from polyenvs.training.config import default_config_path

    if config_dir is None:
        try:
            return default_config_path(algo).absolute()
        except InputError as exc:
            raise InputError(f"--algos {algo}: {exc}".replace("--config FILE", "--config-dir DIR")) from None
    path = Path(config_dir) / f"{algo}.yml"
    if not path.is_file():
        raise InputError(f"--config-dir: config file {path} does not exist (one <algo>.yml per algorithm)")
    return path.absolute()


def _check_config_entries(ids: list[str], configs: dict[str, Path]) -> None:
    """Every algorithm fits every id's actions, and its config has a valid entry for it."""
    from baselines.algorithms import check_action_space
    from polyenvs.evaluation.episodes import make_env
    from polyenvs.evaluation.rollout import agent_spaces
    from polyenvs.training.config import load_config

    for env_id in dict.fromkeys(ids):
        probe = make_env(env_id)
        try:
            for algo, path in configs.items():
                check_action_space(algo, env_id, agent_spaces(probe)[1])
                load_config(path, env_id, algo)  # a missing entry or a bad value: InputError
        finally:
            probe.close()


def _check_job_dir(out_dir: Path, env_id: str, algo: str, seed: int) -> None:
    """A job's training directory can be used: an interrupted run there is resumed; any other run, or files that
    are no run, stop the sweep before any job (one line)."""
    from polyenvs.training.train import check_out_dir

    try:
        check_out_dir(out_dir, env_id, algo, seed, resume=True)
    except InputError as exc:
        message = str(exc).replace("; choose another --out or remove it", "; remove it")
        message = message.replace("; choose another --out, or --overwrite to replace it", "; remove it")
        raise InputError(message) from None


# -------------------------------------------------------------------------------------------------- the sweep


def _format_table(header: list[str], rows: list[list[str]]) -> list[str]:
    cells = [header, *rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    return ["  ".join(f"{c:<{w}}" for c, w in zip(r, widths, strict=True)).rstrip() for r in cells]


def describe_result(result: dict) -> str:
    job = result["job"]
    name = f"{job['env_id']} {job['algo']} seed{job['seed']}"
    if "error" in result:
        return f"{name}: FAILED: {result['error']}"
    trained = f"trained in {result['train_s']:.1f} s" if result["trained"] else "trained before"
    if result.get("resumed_from") is not None:
        trained = f"resumed at {result['resumed_from']} timesteps, {trained}"
    evaluated = "evaluated" if result["evaluated"] else "evaluated before"
    return (
        f"{name}: {trained}; {evaluated}: IQM return {result['iqm']:.4g}, mean {result['mean']:.4g} "
        f"({result['episodes']} episodes)"
    )


def done_before(job: Job) -> dict[str, Any] | None:
    """:func:`run_job`'s result for a job whose run is finished and whose result file is usable, else None."""
    from polyenvs.evaluation.results import load_result
    from polyenvs.evaluation.statistics import interquartile_mean
    from polyenvs.training.train import finished_run

    if finished_run(job.out_dir, job.env_id, job.algo, job.seed) is None:
        return None
    doc, _ = load_result(Path(job.result_file), job.env_id, job.out_dir, job.episodes)
    if doc is None:
        return None
    returns = [float(e["return"]) for e in doc["episodes"]]
    return {
        "job": asdict(job),
        "trained": False,
        "resumed_from": None,
        "train_s": 0.0,
        "evaluated": False,
        "iqm": interquartile_mean(returns),
        "mean": sum(returns) / len(returns),
        "episodes": len(returns),
    }


def run_sweep(
    jobs: list[Job], *, backend: str = "local", workers: int = 1, address: str | None = None, printer=print
) -> list[dict]:
    """Run ``jobs`` on ``backend``; print one line per finished job; return their results in ``jobs``' order.

    Jobs already done (finished run, usable result file) are reported at once without starting a worker.
    """
    results: dict[tuple, dict] = {}

    def report(result: dict) -> None:
        job = result["job"]
        results[(job["env_id"], job["algo"], job["seed"])] = result
        printer(describe_result(result))

    todo = []
    for job in jobs:
        result = done_before(job)
        if result is None:
            todo.append(job)
        else:
            report(result)

    def died(job: Job, exc: BaseException) -> None:  # run_job reports its own errors: the worker died
        report({"job": asdict(job), "error": one_line(exc)})

    run_jobs(run_job, todo, workers, lambda _, result: report(result), died, backend=backend, address=address)
    return [results[(j.env_id, j.algo, j.seed)] for j in jobs if (j.env_id, j.algo, j.seed) in results]


def summary_table(results: list[dict]) -> list[str]:
    rows = []
    for r in results:
        job = r["job"]
        if "error" in r:
            status, train_s, iqm, mean = "FAILED", "-", "-", "-"
        else:
            status = ("resumed" if r.get("resumed_from") is not None else "trained") if r["trained"] else "done before"
            train_s = f"{r['train_s']:.1f}" if r["trained"] else "-"
            iqm, mean = f"{r['iqm']:.4g}", f"{r['mean']:.4g}"
        rows.append([job["env_id"], job["algo"], str(job["seed"]), status, train_s, iqm, mean])
    return _format_table(["environment", "algo", "seed", "status", "train s", "IQM return", "mean return"], rows)
