"""Train one agent with Stable-Baselines3 / sb3-contrib into one output directory.

A run is described by one :class:`TrainRequest` (``polyenvs train`` builds it from its flags), whose fields are
checked when it is made (algorithm, counts, keyword arguments); :func:`train` checks the rest the caller could get
wrong (the id, the config, the output directory, the action space) before it builds the training environments,
then trains on the id's native vector env through :class:`~polyenvs.training.vec_adapter.NativeVecEnvAdapter`
where it has one (SB3's ``DummyVecEnv`` otherwise), and writes the directory described in :mod:`polyenvs.training`.
``run.json`` is written first with ``"completed": false`` and rewritten at the end, so a directory whose run.json
says completed holds a finished model; a re-run into it returns at once, which is how sweeps skip finished jobs.

Every ``checkpoint_every`` timesteps the model (and its VecNormalize statistics) is saved and run.json records the
timesteps reached, so a run killed outright (``kill -9``, the machine lost) keeps its last checkpoint. Ctrl-C
(``KeyboardInterrupt``) during training saves the model trained so far, with ``"completed": false`` and the
timesteps reached, and raises :class:`TrainingInterrupted` (a ``KeyboardInterrupt``) naming the directory. Either
way a request with ``resume=True`` continues the run from its saved model up to the requested timesteps
(``reset_num_timesteps`` false, as SB3 continues a loaded model; an off-policy algorithm starts again with an empty
replay buffer), and ``overwrite=True`` trains it again from the start. While a run trains, its directory is locked
(``flock``): a second run into it is refused, and the lock goes with the process however it ends.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import KW_ONLY, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from polyenvs.core.extras import install_hint
from polyenvs.core.layouts import LAYOUTS
from polyenvs.errors import InputError, check_count, shown
from polyenvs.evaluation.protocol import COUNTED_TRAINING_LAYOUTS as PROTOCOL_TRAINING_LAYOUTS
from polyenvs.files import (
    LOCK_FILE,
    check_writable_directory,
    directory_lock,
    lock_holder,
    temp_path_for,
    write_json_atomic,
)
from polyenvs.limits import MAX_N_ENVS, MAX_SEED, MAX_TIMESTEPS
from polyenvs.registry import ALL_IDS, bare_id
from polyenvs.training import DEFAULT_CHECKPOINT_EVERY

if TYPE_CHECKING:
    from baselines.residual import ResidualSpec
    from polyenvs.training.bc import BehaviourCloning

__all__ = [
    "DEFAULT_CHECKPOINT_EVERY",
    "RUN_FILE",
    "TrainRequest",
    "TrainingInterrupted",
    "check_out_dir",
    "check_same_residual",
    "finished_run",
    "interrupted_note",
    "read_run",
    "saved_timesteps",
    "train",
]

RUN_FILE = "run.json"
MODEL_FILE = "model.zip"
VECNORMALIZE_FILE = "vecnormalize.pkl"
TENSORBOARD_DIR = "tb"
#: The learning curve (polyenvs.training.callbacks.LearningCurveCallback): small, committed with an agent.
CURVE_FILE = "curve.json"
#: What a run writes: removed when a run is trained again from the start (anything else is left alone).
_RUN_ENTRIES = (RUN_FILE, MODEL_FILE, VECNORMALIZE_FILE, TENSORBOARD_DIR, CURVE_FILE)
#: Temporary files of atomic writes (polyenvs.files.temp_path_for) and the lock: not a run's content.
_TEMPORARY = re.compile(r"\..+\.tmp(\..*)?")
#: A checkpoint's statistics waiting for their rename into place, named by the model's timesteps (a temporary too).
_PENDING_STATISTICS = re.compile(rf"\.{re.escape(VECNORMALIZE_FILE)}\.at-(\d+)\.tmp")


class TrainingInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped training; the partial model was saved in ``out_dir`` after ``timesteps`` steps."""

    def __init__(self, out_dir: Path, timesteps: int):
        super().__init__(f"training interrupted after {timesteps} timesteps; the partial model is in {out_dir}")
        self.out_dir, self.timesteps = out_dir, timesteps


# ------------------------------------------------------------------------------------------------- run files


def read_run(out_dir: str | Path) -> dict[str, Any] | None:
    """The run.json of ``out_dir``, or None if it has none or it cannot be read."""
    try:
        document = json.loads((Path(out_dir) / RUN_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return document if isinstance(document, dict) else None


def finished_run(out_dir: str | Path, env_id: str, algo: str, seed: int) -> dict[str, Any] | None:
    """run.json of ``out_dir`` if it records a completed run of (env_id, algo, seed) with its model present."""
    run = read_run(out_dir)
    if (
        run is not None
        and run.get("completed") is True
        and (run.get("env_id"), run.get("algo"), run.get("seed")) == (bare_id(env_id), algo, seed)
        and (Path(out_dir) / MODEL_FILE).is_file()
    ):
        return run
    return None


def _content(out_dir: Path) -> list[Path]:
    """The entries of ``out_dir`` other than temporary files (a write or a lock a killed run left behind)."""
    return [p for p in out_dir.iterdir() if not _TEMPORARY.fullmatch(p.name)]


def _same_job(run: dict[str, Any], env_id: str, algo: str, seed: int) -> bool:
    return (run.get("env_id"), run.get("algo"), run.get("seed")) == (bare_id(env_id), algo, seed)


def _progress(run: dict[str, Any], out_dir: Path) -> str:
    """``N of M timesteps``: N the saved model's count (run.json's may lag it by the moment between the two)."""
    saved = saved_timesteps(out_dir)
    return (
        f"{saved if saved is not None else run.get('timesteps', 0)} of {run.get('requested_timesteps', '?')} timesteps"
    )


def check_out_dir(
    out_dir: Path, env_id: str, algo: str, seed: int, *, resume: bool = False, overwrite: bool = False
) -> str:
    """What training (env_id, algo, seed) into ``out_dir`` will do; InputError (one line) if it cannot.

    Returns ``"new"`` (absent or empty), ``"finished"`` (a finished run of the same job: nothing to do),
    ``"resume"`` (``resume``, and an interrupted run of the same job with a saved model), ``"restart"``
    (``resume``, and an interrupted run of the same job that saved no model yet) or ``"overwrite"``
    (``overwrite``, and a run of any job). Refused: a file, a directory with files but no run.json, a directory
    another process is training into, a run that is not this one's to take over without ``overwrite``.
    """
    out_dir = Path(out_dir)
    if resume and overwrite:
        raise InputError("resume and overwrite exclude each other: --resume continues a run, --overwrite restarts it")
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"output directory {out_dir} is a file")
    if out_dir.is_dir() and _content(out_dir):
        holder = lock_holder(out_dir)
        if holder is not None:
            raise InputError(f"output directory {out_dir} is being trained into by {holder}; wait for it or stop it")
        run = read_run(out_dir)
        if run is None:
            raise InputError(
                f"output directory {out_dir} holds files and no run.json; choose another --out or remove it"
            )
        job = f"{run.get('env_id')} {run.get('algo')} seed {run.get('seed')}"
        if overwrite:
            return "overwrite"
        if finished_run(out_dir, env_id, algo, seed) is not None:
            return "finished"
        if run.get("completed") is True:
            raise InputError(
                f"output directory {out_dir} holds a finished run of {job}; choose another --out, or --overwrite to "
                "replace it"
            )
        if not _same_job(run, env_id, algo, seed):
            raise InputError(
                f"output directory {out_dir} holds an unfinished or interrupted run of {job}; choose another --out, "
                "or --overwrite to replace it"
            )
        saved = (out_dir / MODEL_FILE).is_file()
        if resume:
            return "resume" if saved else "restart"
        if saved:
            raise InputError(
                f"output directory {out_dir} holds an interrupted run ({_progress(run, out_dir)} saved); --resume to continue "
                "it, or --overwrite to train it again from the start"
            )
        raise InputError(
            f"output directory {out_dir} holds an interrupted run that saved no model yet; --overwrite (or --resume) "
            "to train it again from the start"
        )
    check_writable_directory(out_dir, "output directory")
    return "new"


def interrupted_note(out_dir: str | Path) -> str | None:
    """For an interrupted run in ``out_dir``: what resuming it does (a sentence), else None."""
    run = read_run(out_dir)
    if run is None or run.get("completed") is True:
        return None
    if (Path(out_dir) / MODEL_FILE).is_file():
        return f"interrupted at {_progress(run, Path(out_dir))}: resuming it from its saved model"
    return "interrupted before it saved a model: training it again from the start"


def _remove_temporaries(out_dir: Path) -> None:
    """Remove the temporary files a killed run left in ``out_dir`` (called with its lock held)."""
    for path in out_dir.iterdir():
        if _TEMPORARY.fullmatch(path.name) and path.name != LOCK_FILE and path.is_file():
            path.unlink(missing_ok=True)


def _clear_run(out_dir: Path) -> None:
    """Remove what a run wrote in ``out_dir``; anything else stays."""
    for name in _RUN_ENTRIES:
        path = out_dir / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists() or path.is_symlink():
            path.unlink()


#: Settings of a run that must not change when it resumes (the hyperparameters are compared apart).
_RESUME_KEYS = ("n_envs", "env_kwargs", "residual", "residual_log_std")


def _check_resumable(out_dir: Path, previous: dict[str, Any], run: dict[str, Any]) -> None:
    """The resumed run trains as the interrupted one did: same n_envs, env_kwargs and hyperparameters."""
    run = json.loads(json.dumps(run))  # as run.json holds it: tuples as lists
    for key in _RESUME_KEYS:
        if previous.get(key) != run.get(key):
            raise InputError(
                f"cannot resume {out_dir}: it trained with {key}={previous.get(key)!r}, this run asks for "
                f"{run.get(key)!r}; --overwrite to train it again from the start"
            )
    old = {k: v for k, v in (previous.get("hyperparams") or {}).items() if k not in ("n_timesteps", "n_envs")}
    new = {k: v for k, v in run["hyperparams"].items() if k not in ("n_timesteps", "n_envs")}
    for key in sorted(set(old) | set(new)):
        if old.get(key) != new.get(key):
            raise InputError(
                f"cannot resume {out_dir}: its {key} was {old.get(key)!r}, the config now says {new.get(key)!r}; "
                "--overwrite to train it again from the start"
            )


def versions() -> dict[str, str | None]:
    """Versions of Python and the packages a trained model depends on."""
    from importlib import metadata

    import polyenvs

    found: dict[str, str | None] = {"python": platform.python_version(), "polyenvs": polyenvs.__version__}
    for name, dist in (
        ("gymnasium", "gymnasium"),
        ("stable_baselines3", "stable-baselines3"),
        ("sb3_contrib", "sb3-contrib"),
        ("torch", "torch"),
        ("numpy", "numpy"),
    ):
        try:
            found[name] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            found[name] = None
    return found


def git_commit() -> str | None:
    """The commit of the checkout polyenvs runs from, or None (an installed copy, no git)."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return None
    try:
        done = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10, check=False
        )
    except (OSError, subprocess.SubprocessError):
        return None
    commit = done.stdout.strip()
    return commit if done.returncode == 0 and commit else None


def _check_extras(progress_bar: bool, tensorboard: bool) -> None:
    import importlib.util

    if progress_bar and (importlib.util.find_spec("tqdm") is None or importlib.util.find_spec("rich") is None):
        raise InputError(f"the progress bar needs tqdm and rich: {install_hint('train')} (or --no-progress)")
    if tensorboard and importlib.util.find_spec("tensorboard") is None:
        raise InputError(f"TensorBoard logging needs tensorboard: {install_hint('train')}")


# ------------------------------------------------------------------------------------------------------ train


@dataclass(frozen=True)
class TrainRequest:
    """One run for :func:`train`, each setting named once: its field, default and meaning below.

    ``TrainRequest("polyenvs/BuckybotGoal-v0", "ppo", out_dir="runs/goal", timesteps=100_000)``; ``polyenvs train``
    builds one from its flags. The fields are checked when the request is made: a bad value raises
    :class:`~polyenvs.errors.InputError` naming the field (what needs the environment, the config or the output
    directory is checked by :func:`train`, before it builds anything). ``env_id`` is kept without Gymnasium's
    ``module:`` prefix, ``out_dir`` as a :class:`~pathlib.Path` and ``env_kwargs`` as a dict of its own.
    """

    #: A registered id (``polyenvs/BuckybotWallFollow-v0``).
    env_id: str
    #: ``"ppo"``, ``"dqn"``, ``"maskable_ppo"`` (discrete actions), ``"sac"``, ``"td3"`` (continuous).
    algo: str
    _: KW_ONLY  # the rest by name only: two settings of one type cannot swap places unseen
    #: The output directory, which must not exist, be empty, or hold a finished run of the same (env_id, algo,
    #: seed), returned without training (or, with ``resume`` / ``overwrite``, a run to continue / to replace).
    out_dir: Path
    #: An RL Zoo-format YAML file (by default ``configs/<algo>.yml``), whose entry for ``env_id`` gives
    #: n_timesteps, n_envs, normalize, env_wrapper, frame_stack, policy and the hyperparameters.
    config: str | Path | None = None
    #: Train this many steps instead of the config's n_timesteps.
    timesteps: int | None = None
    #: The training seed (torch, the action sampling and sub-environment i's episodes, seeded seed + i).
    seed: int = 0
    #: Parallel environments instead of the config's n_envs.
    n_envs: int | None = None
    #: The environment's constructor keywords (``{"floor_plan": "office"}``).
    env_kwargs: dict[str, Any] | None = None
    #: The layouts the episodes are drawn from (recorded in run.json's ``env_kwargs``), ``"train"`` (the Procgen
    #: protocol: the leaderboard judges agents on the held-out ``"test"`` layouts and counts only those trained
    #: so), ``"default"`` or ``"test"``. ``None``: ``env_kwargs``' ``layouts``, else the config's ``env_kwargs``'
    #: (RL Zoo's key), else ``"train"``.
    layouts: str | None = None
    #: Continue an interrupted run of the same job in ``out_dir`` from its saved model (the last checkpoint, or
    #: what Ctrl-C saved) up to the requested timesteps; with no saved model, train it again from the start. The
    #: config, n_envs and env_kwargs must be those it trained with.
    resume: bool = False
    #: Replace any run in ``out_dir`` (finished or not, of any job) and train again from the start.
    overwrite: bool = False
    #: Save the model (and run.json's timesteps) every this many timesteps; 0 saves only at the end and on Ctrl-C.
    checkpoint_every: int = DEFAULT_CHECKPOINT_EVERY
    #: A :class:`polyenvs.training.bc.BehaviourCloning` to fit a new model to demonstrations before it learns (a
    #: resumed run keeps its model); run.json records it under ``"bc"``.
    pretrain: BehaviourCloning | None = None
    #: A :class:`baselines.residual.ResidualSpec`, to train a correction of that hand baseline
    #: (:mod:`polyenvs.training.residual`), recorded in run.json's ``residual``.
    residual: ResidualSpec | None = None
    #: A residual agent's starting log standard deviation (by default the config's).
    residual_log_std: float | None = None
    #: ``"auto"`` (the native vector env where the id has one and the config wraps no single env), ``"native"``
    #: or ``"dummy"`` (SB3's ``DummyVecEnv`` of ``gym.make``).
    vec_env: str = "auto"
    #: The torch device (``"cpu"``, where small MLPs train faster).
    device: str = "cpu"
    #: The command line recorded in run.json (by default ``sys.argv``).
    command: str | None = None
    #: Show SB3's progress bar (tqdm and rich).
    progress_bar: bool = False
    #: Write TensorBoard logs under ``out_dir/tb``.
    tensorboard: bool = True
    #: SB3's verbosity (1 prints its table of training statistics).
    verbose: int = 0
    #: Extra SB3 callbacks.
    callbacks: Sequence[Any] = ()

    def __post_init__(self):
        from baselines.algorithms import get_algo

        get_algo(self.algo)
        if not isinstance(self.env_id, str):
            raise InputError(f"env_id must be a string, got {self.env_id!r}")
        checked = {
            "env_id": bare_id(self.env_id),
            "seed": check_count("seed", self.seed, 0, MAX_SEED),
            "timesteps": _optional_count("timesteps", self.timesteps, 1, MAX_TIMESTEPS),
            "n_envs": _optional_count("n_envs", self.n_envs, 1, MAX_N_ENVS),
            "checkpoint_every": check_count("checkpoint_every", self.checkpoint_every, 0, MAX_TIMESTEPS),
            "env_kwargs": _own_kwargs(self.env_kwargs),
            "out_dir": Path(self.out_dir),
        }
        _check_layouts(self.layouts, checked["env_kwargs"])
        if self.vec_env not in ("auto", "native", "dummy"):
            raise InputError(f"vec_env must be 'auto', 'native' or 'dummy', got {self.vec_env!r}")
        _check_residual_request(self.residual, self.residual_log_std)
        for name, value in checked.items():  # stored once all passed: a request that raises was never made
            object.__setattr__(self, name, value)


def train(request: TrainRequest) -> Path:
    """Train ``request.algo`` on ``request.env_id`` and write ``request.out_dir``; return ``out_dir``.

    Raises:
        InputError: before any environment is built, for anything the caller got wrong.
        TrainingInterrupted: after Ctrl-C, once the partial model is saved.
    """
    import polyenvs  # noqa: F401  (registers the ids)

    out_dir = request.out_dir
    action = check_out_dir(
        out_dir, request.env_id, request.algo, request.seed, resume=request.resume, overwrite=request.overwrite
    )
    if action == "finished":
        check_same_residual(out_dir, request.residual)
        return out_dir
    job = _plan(request, action)
    model, interrupted = _build_and_train(job)
    if interrupted:
        raise TrainingInterrupted(out_dir, int(model.num_timesteps))
    return out_dir


@dataclass
class _Job:
    """One run to train: the request, its config, the run.json to write and the interrupted run it resumes."""

    request: TrainRequest
    cfg: Any
    wrappers: list
    run: dict[str, Any]
    previous: dict[str, Any] | None
    #: The environment, resolved once (its name, keywords, kind and spaces), for everything that builds it.
    target: Any


def _optional_count(name: str, value, minimum: int, maximum: int) -> int | None:
    """``value`` checked by :func:`~polyenvs.errors.check_count`, or None (the config's)."""
    return None if value is None else check_count(name, value, minimum, maximum)


def _own_kwargs(env_kwargs) -> dict[str, Any]:
    """A copy of ``env_kwargs`` (None: no keywords), so that the caller's dict is neither kept nor changed."""
    if env_kwargs is not None and not isinstance(env_kwargs, dict):
        raise InputError(f"env_kwargs must be a dict, got {env_kwargs!r}")
    return dict(env_kwargs or {})


def _check_layouts(layouts, env_kwargs: dict) -> None:
    """``layouts`` is None or one of the environments' layouts, and says what ``env_kwargs`` says, if anything."""
    if layouts is None:
        return
    if layouts not in LAYOUTS:
        raise InputError(f"layouts must be one of {', '.join(map(repr, LAYOUTS))}, got {shown(layouts)}")
    if env_kwargs.get("layouts", layouts) != layouts:
        raise InputError(f"layouts is {layouts!r} but env_kwargs' layouts is {env_kwargs['layouts']!r}: give one")


def training_layouts(request_layouts: str | None, request_kwargs: dict, config_kwargs: dict, env_id: str) -> str | None:
    """The layouts a run trains on: the caller's (``layouts``, else ``env_kwargs``' own), else the config's
    ``env_kwargs``', else the Procgen protocol's training layouts for a polyenvs id (None for another
    Gymnasium id, which takes no ``layouts``)."""
    for given in (request_layouts, request_kwargs.get("layouts"), config_kwargs.get("layouts")):
        if given is not None:
            return given
    return PROTOCOL_TRAINING_LAYOUTS if bare_id(env_id) in ALL_IDS else None


def check_same_residual(out_dir: Path, residual) -> None:
    """A finished run counts as this job's only if it corrects the same baseline (or none, as this one)."""
    from baselines.residual import ResidualSpec

    wanted = residual.to_json() if residual is not None else None
    done = (read_run(out_dir) or {}).get("residual")
    with contextlib.suppress(ValueError):  # a run recorded before a field existed: that field's default
        done = ResidualSpec.from_json(done).to_json() if done is not None else None
    if done != wanted:
        raise InputError(
            f"output directory {out_dir} holds a finished run with residual {done!r}, not {wanted!r}; choose another "
            "--out, or --overwrite to replace it"
        )


def _check_residual_request(residual, log_std) -> None:
    from baselines.residual import ResidualSpec

    if residual is not None and not isinstance(residual, ResidualSpec):
        raise InputError(f"residual must be a baselines.residual.ResidualSpec, got {residual!r}")
    if residual is None and log_std is not None:
        raise InputError("residual_log_std needs residual")


def _plan(request: TrainRequest, action: str) -> _Job:
    """Check the environment, the config and (``action == "resume"``) the run to resume; the run.json to write."""
    from baselines.algorithms import check_action_space
    from polyenvs.evaluation.episodes import resolve_env
    from polyenvs.training.config import default_config_path, load_config

    env_id, algo, out_dir = request.env_id, request.algo, request.out_dir
    # Resolved once (an unknown id or bad keywords raise InputError here, before the config is read), and again
    # only where the config adds keywords of its own, which may change the spaces: checked under the command line's.
    target = resolve_env(env_id, request.env_kwargs)
    check_action_space(algo, env_id, target.action_space)  # a parallel env's: one robot's
    config_path = Path(request.config) if request.config is not None else default_config_path(algo)
    cfg = load_config(config_path, env_id, algo)
    layouts = training_layouts(request.layouts, request.env_kwargs, cfg.env_kwargs, env_id)
    env_kwargs = {**cfg.env_kwargs, **request.env_kwargs, **({"layouts": layouts} if layouts is not None else {})}
    if env_kwargs != request.env_kwargs:
        target = resolve_env(env_id, env_kwargs)
        check_action_space(algo, env_id, target.action_space)
    _check_extras(request.progress_bar, request.tensorboard)
    wrappers = cfg.wrapper_callables()
    if request.residual is not None:  # innermost: it needs the env's own spaces and id
        if cfg.frame_stack is not None:  # the loaded agent asks its network every hold ticks, on one frame
            raise InputError(f"{cfg.path}: {env_id}: --residual learns on single frames; drop frame_stack")
        wrappers = [_residual_wrapper(request, target), *wrappers]
    n_envs = request.n_envs if request.n_envs is not None else cfg.n_envs
    requested = request.timesteps if request.timesteps is not None else cfg.n_timesteps
    if request.vec_env == "native" and wrappers:
        raise InputError(f"{cfg.path}: {env_id}: env_wrapper wraps single envs: it needs vec_env='dummy' or 'auto'")
    hyperparams = cfg.resolved()
    hyperparams.update(n_envs=n_envs, n_timesteps=requested)
    command = request.command
    run: dict[str, Any] = {
        "env_id": env_id,
        "algo": algo,
        "seed": request.seed,
        "timesteps": 0,
        "requested_timesteps": requested,
        "n_envs": n_envs,
        "env_kwargs": env_kwargs,
        "hyperparams": hyperparams,
        "config_file": str(cfg.path),
        "vec_env": None,
        "command": command if command is not None else shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "versions": versions(),
        "git_commit": git_commit(),
        "wall_clock_s": 0.0,
        "completed": False,
    }
    if request.residual is not None:
        run.update(residual=request.residual.to_json(), residual_log_std=request.residual_log_std)
    if request.pretrain is not None:  # the dataset checked against the environment, before any training
        if request.residual is not None:
            raise InputError("pretrain and residual exclude each other: clone a plain policy, or learn a residual")
        run["bc"] = request.pretrain.check(algo, target, cfg.frame_stack)
    previous = read_run(out_dir) if action == "resume" else None
    if previous is not None and "bc" in previous:  # a resumed run goes on from the model it cloned then
        run["bc"] = previous["bc"]
    if previous is not None:
        _finish_checkpoint(out_dir)
        _check_resumable(out_dir, previous, run)
        if cfg.normalize and not (out_dir / VECNORMALIZE_FILE).is_file():
            raise InputError(
                f"cannot resume {out_dir}: it has a model but no {VECNORMALIZE_FILE} (the config normalises); "
                "--overwrite to train it again from the start"
            )
    return _Job(request=request, cfg=cfg, wrappers=wrappers, run=run, previous=previous, target=target)


def _residual_wrapper(request: TrainRequest, target):
    """The residual wrapper of ``request`` for ``target``, checked (InputError)."""
    from polyenvs.training.residual import check_residual, residual_wrapper

    check_residual(request.residual, target, request.vec_env, request.residual_log_std)
    return residual_wrapper(request.residual, target.env_id, target.parallel)


def _build_and_train(job: _Job) -> tuple[Any, bool]:
    """Build the training vector env and the model (or load the one to resume), train it, save it; close the env.

    Returns the model and whether Ctrl-C interrupted training."""
    import torch

    from polyenvs.training.vec_adapter import make_training_vec_env

    request, run = job.request, job.run
    torch.set_num_threads(1)  # small MLPs: more threads only contend (intermittently 10-100x slower on 2 cores)
    venv = make_training_vec_env(
        job.target, run["n_envs"], seed=request.seed, wrappers=job.wrappers, vec_env=request.vec_env
    )
    try:
        run["vec_env"] = type(_innermost(venv)).__name__
        venv = _wrap_vec_env(job, venv)
        model = _load_model(job, venv) if job.previous is not None else _new_model(job, venv)
        if job.previous is None and request.pretrain is not None:
            run["bc"].update(request.pretrain.pretrain(model))
        interrupted = _learn_and_save(job, model)
    finally:
        venv.close()
    return model, interrupted


def _wrap_vec_env(job: _Job, venv):
    """``venv`` stacked (the config's frame_stack) and normalised (the resumed run's statistics, or new ones)."""
    from stable_baselines3.common.vec_env import VecFrameStack, VecNormalize

    cfg = job.cfg
    if cfg.frame_stack is not None:
        venv = VecFrameStack(venv, cfg.frame_stack)
    if cfg.normalize and job.previous is not None:
        venv = VecNormalize.load(str(job.request.out_dir / VECNORMALIZE_FILE), venv)
        venv.training = True
    elif cfg.normalize:
        venv = VecNormalize(venv, **cfg.normalize_kwargs)
    return venv


def _tensorboard_log(request: TrainRequest) -> str | None:
    return str(request.out_dir / TENSORBOARD_DIR) if request.tensorboard else None


def _load_model(job: _Job, venv):
    """The interrupted run's saved model on ``venv``, reseeded; InputError if it does not load or fit its statistics."""
    from baselines.algorithms import algo_class

    request = job.request
    out_dir = request.out_dir
    cls = algo_class(request.algo)
    try:
        model = cls.load(out_dir / MODEL_FILE, env=venv, device=request.device, verbose=request.verbose,
                         tensorboard_log=_tensorboard_log(request))  # fmt: skip
    except (OSError, ValueError, KeyError, RuntimeError) as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(
            f"cannot resume {out_dir}: its {MODEL_FILE} does not load ({message}); --overwrite to train it "
            "again from the start"
        ) from exc
    model.set_random_seed(request.seed)
    marked = getattr(model.get_vec_normalize_env(), "saved_at_timesteps", model.num_timesteps)
    if marked != model.num_timesteps:  # the process died between the two renames: vanishingly rare
        raise InputError(
            f"cannot resume {out_dir}: its {MODEL_FILE} ({model.num_timesteps} timesteps) and "
            f"{VECNORMALIZE_FILE} ({marked}) were saved apart; --overwrite to train it again from the start"
        )
    return model


def _new_model(job: _Job, venv):
    """A new model of the config's policy and hyperparameters on ``venv``; InputError if the algorithm rejects them."""
    from baselines.algorithms import algo_class

    request, cfg = job.request, job.cfg
    cls = algo_class(request.algo)
    try:
        model = cls(
            cfg.policy, venv, seed=request.seed, device=request.device, verbose=request.verbose,
            tensorboard_log=_tensorboard_log(request), **cfg.hyperparams,
        )  # fmt: skip
    except (AssertionError, ValueError, TypeError) as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(
            f"{cfg.path}: {request.env_id}: {cls.__name__} rejected the hyperparameters: {message}"
        ) from exc
    if request.residual is not None:
        from polyenvs.training.residual import start_at_the_base

        start_at_the_base(model, request.residual_log_std)
    return model


def _learn_and_save(job: _Job, model) -> bool:
    """Under the directory's lock: write run.json, train (checkpoints; Ctrl-C caught), save. True if interrupted."""
    from baselines.algorithms import algo_class
    from polyenvs.training.callbacks import CheckpointCallback, EpisodeMetricsCallback, LearningCurveCallback

    request, run, previous = job.request, job.run, job.previous
    out_dir = request.out_dir
    out_dir.mkdir(parents=True, exist_ok=True)
    with directory_lock(out_dir, "trained into"):
        _remove_temporaries(out_dir)
        if previous is not None:
            run.update(
                command=previous.get("command", run["command"]),
                resumed_at=[*previous.get("resumed_at", []), int(model.num_timesteps)],
                timesteps=int(model.num_timesteps),
                wall_clock_s=float(previous.get("wall_clock_s", 0.0)),
            )
        else:
            _clear_run(out_dir)  # an interrupted run trained again, or one overwritten
        write_json_atomic(out_dir / RUN_FILE, run)
        trained_before = float(run["wall_clock_s"])

        # ---- training
        metrics = EpisodeMetricsCallback()
        curve = LearningCurveCallback(metrics, out_dir / CURVE_FILE, resume_from=_read_curve(out_dir, previous))
        start = time.monotonic()
        checkpoints = (
            [CheckpointCallback(request.checkpoint_every, lambda: _save(model, out_dir, run, trained_before, start))]
            if request.checkpoint_every
            else []
        )
        interrupted = False
        remaining = run["requested_timesteps"] - int(model.num_timesteps)
        try:
            if remaining > 0:
                model.learn(
                    total_timesteps=remaining,
                    callback=[metrics, curve, *checkpoints, *request.callbacks],
                    progress_bar=request.progress_bar,
                    tb_log_name=algo_class(request.algo).__name__,
                    reset_num_timesteps=previous is None,
                )
        except KeyboardInterrupt:
            interrupted = True

        # ---- the directory: model, statistics, then run.json (which marks it finished)
        run.update(episode_metrics=metrics.means())
        _save(model, out_dir, run, trained_before, start, completed=not interrupted)
    return interrupted


def _read_curve(out_dir: Path, previous: dict[str, Any] | None) -> dict | None:
    """The curve an interrupted run wrote, when this run resumes it (None for a fresh run or a missing file)."""
    if previous is None:
        return None
    try:
        return json.loads((out_dir / CURVE_FILE).read_text())
    except (OSError, ValueError):
        return None


def _save(model, out_dir: Path, run: dict[str, Any], trained_before: float, start: float, completed=False) -> None:
    """Save the model and its VecNormalize statistics, then run.json (timesteps, time; completed).

    Both files are written and synced in full under temporary names before either is renamed into place, the
    model first; the statistics' temporary name holds the model's timesteps, so a process killed between the two
    renames leaves them to be renamed when the run resumes (:func:`_finish_checkpoint`), and a process killed at any
    other moment leaves the two of one checkpoint (the statistics are marked with the model's timesteps, which
    resuming checks)."""
    normalizer = model.get_vec_normalize_env()
    targets = [out_dir / MODEL_FILE] + ([out_dir / VECNORMALIZE_FILE] if normalizer is not None else [])
    pending = out_dir / f".{VECNORMALIZE_FILE}.at-{int(model.num_timesteps)}.tmp"
    temporary = [temp_path_for(targets[0], keep_suffix=True)] + ([pending] if normalizer is not None else [])
    try:
        model.save(temporary[0])
        if normalizer is not None:
            normalizer.saved_at_timesteps = int(model.num_timesteps)  # pickled with the statistics
            normalizer.save(temporary[1])
        for tmp in temporary:
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
        for tmp, target in zip(temporary, targets, strict=True):
            os.replace(tmp, target)
    finally:
        for tmp in temporary:
            tmp.unlink(missing_ok=True)
    run.update(
        timesteps=int(model.num_timesteps),
        wall_clock_s=round(trained_before + time.monotonic() - start, 3),
        completed=completed,
    )
    write_json_atomic(out_dir / RUN_FILE, run)


def _finish_checkpoint(out_dir: Path) -> None:
    """Rename into place the statistics of a checkpoint whose model was renamed when the process was killed (before
    the statistics' own rename), so that the run resumes from that checkpoint; older pending ones are left to
    :func:`_remove_temporaries`."""
    saved = saved_timesteps(out_dir)
    for path in out_dir.iterdir():
        match = _PENDING_STATISTICS.fullmatch(path.name)
        if match is not None and int(match[1]) == saved:
            os.replace(path, out_dir / VECNORMALIZE_FILE)


def saved_timesteps(out_dir: str | Path) -> int | None:
    """The timesteps of the model saved in ``out_dir`` (read from model.zip without loading it), or None."""
    import zipfile

    try:
        with zipfile.ZipFile(Path(out_dir) / MODEL_FILE) as archive:
            value = json.loads(archive.read("data")).get("num_timesteps")
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return None
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _innermost(venv):
    while hasattr(venv, "venv"):
        inner = venv.venv
        if not hasattr(inner, "step_wait"):  # the adapter's venv is the Gymnasium vector env
            break
        venv = inner
    return venv
