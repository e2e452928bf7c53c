"""Train one agent with Stable-Baselines3 / sb3-contrib into one output directory.

:func:`train` checks everything the caller could get wrong (algorithm, id, counts, keyword arguments, the config,
the output directory, the action space) before it builds the training environments, then trains on the id's
native vector env through :class:`~polyenvs.training.vec_adapter.NativeVecEnvAdapter` where it has one (SB3's
``DummyVecEnv`` otherwise), and writes the directory described in :mod:`polyenvs.training`. ``run.json`` is written
first with ``"completed": false`` and rewritten at the end, so a directory whose run.json says completed holds a
finished model; a re-run into it returns at once, which is how sweeps skip finished jobs.

Ctrl-C (``KeyboardInterrupt``) during training saves the model trained so far, with ``"completed": false`` and the
timesteps reached, and raises :class:`TrainingInterrupted` (a ``KeyboardInterrupt``) naming the directory.
"""

from __future__ import annotations

import json
import platform
import shlex
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from polyenvs.evaluation import InputError, atomic_path, check_count, check_writable_directory, write_json_atomic

__all__ = ["RUN_FILE", "TrainingInterrupted", "check_out_dir", "finished_run", "read_run", "train"]

RUN_FILE = "run.json"
MODEL_FILE = "model.zip"
VECNORMALIZE_FILE = "vecnormalize.pkl"
TENSORBOARD_DIR = "tb"


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
        and (run.get("env_id"), run.get("algo"), run.get("seed")) == (env_id.split(":", 1)[-1], algo, seed)
        and (Path(out_dir) / MODEL_FILE).is_file()
    ):
        return run
    return None


def check_out_dir(out_dir: Path, env_id: str, algo: str, seed: int) -> bool:
    """True if ``out_dir`` is a finished run of the same job; InputError if it cannot be used; else False."""
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"output directory {out_dir} is a file")
    if out_dir.is_dir() and any(out_dir.iterdir()):
        if finished_run(out_dir, env_id, algo, seed) is not None:
            return True
        run = read_run(out_dir)
        if run is None:
            what = "holds files and no run.json"
        elif run.get("completed") is not True:
            what = "holds an unfinished or interrupted run"
        else:
            what = f"holds a finished run of {run.get('env_id')} {run.get('algo')} seed {run.get('seed')}"
        raise InputError(f"output directory {out_dir} {what}; choose another --out or remove it")
    check_writable_directory(out_dir, "output directory")
    return False


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
        raise InputError('the progress bar needs tqdm and rich: pip install "polyenvs[train]" (or --no-progress)')
    if tensorboard and importlib.util.find_spec("tensorboard") is None:
        raise InputError('TensorBoard logging needs tensorboard: pip install "polyenvs[train]"')


# ------------------------------------------------------------------------------------------------------ train


def train(
    env_id: str,
    algo: str,
    *,
    config: str | Path | None = None,
    timesteps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    env_kwargs: dict | None = None,
    out_dir: str | Path,
    progress_bar: bool = False,
    tensorboard: bool = True,
    command: str | None = None,
    vec_env: str = "auto",
    device: str = "cpu",
    verbose: int = 0,
    callbacks: Sequence[Any] = (),
) -> Path:
    """Train ``algo`` on ``env_id`` and write ``out_dir``; return ``out_dir``.

    Args:
        env_id: a registered id (``polyenvs/BuckybotWallFollow-v0``).
        algo: ``"ppo"``, ``"dqn"``, ``"maskable_ppo"`` (discrete actions), ``"sac"``, ``"td3"`` (continuous).
        config: an RL Zoo-format YAML file (default ``configs/<algo>.yml``); its entry for ``env_id`` gives
            n_timesteps, n_envs, normalize, env_wrapper, policy and the hyperparameters.
        timesteps: train this many steps instead of the config's n_timesteps.
        seed: the training seed (torch, the action sampling and sub-environment i's episodes, seeded seed + i).
        n_envs: parallel environments instead of the config's n_envs.
        env_kwargs: the environment's constructor keywords (``{"floor_plan": "office"}``).
        out_dir: the output directory: must not exist, be empty, or hold a finished run of the same (env_id,
            algo, seed), which is returned without training.
        progress_bar: show SB3's progress bar (tqdm and rich).
        tensorboard: write TensorBoard logs under ``out_dir/tb``.
        command: the command line recorded in run.json (default: ``sys.argv``).
        vec_env: ``"auto"`` (the native vector env where the id has one and the config wraps no single env),
            ``"native"`` or ``"dummy"`` (SB3's ``DummyVecEnv`` of ``gym.make``).
        device: torch device (``"cpu"``: small MLPs train faster there).
        verbose: SB3's verbosity (1 prints its table of training statistics).
        callbacks: extra SB3 callbacks.

    Raises:
        InputError: before any environment is built, for anything the caller got wrong.
        TrainingInterrupted: after Ctrl-C, once the partial model is saved.
    """
    import polyenvs  # noqa: F401  (registers the ids)
    from polyenvs.evaluation import make_env
    from polyenvs.rollout import agent_spaces
    from polyenvs.training.algos import check_action_space, get_algo
    from polyenvs.training.config import default_config_path, load_config

    # ---- everything the caller could get wrong, before any work
    get_algo(algo)
    if not isinstance(env_id, str):
        raise InputError(f"env_id must be a string, got {env_id!r}")
    env_id = env_id.split(":", 1)[-1]
    seed = check_count("seed", seed, 0)
    if timesteps is not None:
        timesteps = check_count("timesteps", timesteps, 1)
    if n_envs is not None:
        n_envs = check_count("n_envs", n_envs, 1)
    if env_kwargs is not None and not isinstance(env_kwargs, dict):
        raise InputError(f"env_kwargs must be a dict, got {env_kwargs!r}")
    env_kwargs = dict(env_kwargs or {})
    if vec_env not in ("auto", "native", "dummy"):
        raise InputError(f"vec_env must be 'auto', 'native' or 'dummy', got {vec_env!r}")
    out_dir = Path(out_dir)
    if check_out_dir(out_dir, env_id, algo, seed):
        return out_dir
    probe = make_env(env_id, env_kwargs)  # an unknown id or bad keyword arguments raise InputError here
    try:
        check_action_space(algo, env_id, agent_spaces(probe)[1])  # a parallel env's: one robot's
    finally:
        probe.close()
    config_path = Path(config) if config is not None else default_config_path(algo)
    cfg = load_config(config_path, env_id, algo)
    if cfg.env_kwargs:  # the config's keywords under the command line's: check them together
        env_kwargs = {**cfg.env_kwargs, **env_kwargs}
        make_env(env_id, env_kwargs).close()
    _check_extras(progress_bar, tensorboard)
    wrappers = cfg.wrapper_callables()
    n_envs = n_envs if n_envs is not None else cfg.n_envs
    requested = timesteps if timesteps is not None else cfg.n_timesteps
    if vec_env == "native" and wrappers:
        raise InputError(f"{cfg.path}: {env_id}: env_wrapper wraps single envs: it needs vec_env='dummy' or 'auto'")

    # ---- the environments and the model
    import torch
    from stable_baselines3.common.vec_env import VecFrameStack, VecNormalize

    from polyenvs.training.algos import algo_class
    from polyenvs.training.callbacks import EpisodeMetricsCallback
    from polyenvs.training.vec_adapter import make_training_vec_env

    torch.set_num_threads(1)  # small MLPs: more threads only contend (intermittently 10-100x slower on 2 cores)
    venv = make_training_vec_env(env_id, n_envs, seed=seed, env_kwargs=env_kwargs, wrappers=wrappers, vec_env=vec_env)
    try:
        if cfg.frame_stack is not None:
            venv = VecFrameStack(venv, cfg.frame_stack)
        if cfg.normalize:
            venv = VecNormalize(venv, **cfg.normalize_kwargs)
        cls = algo_class(algo)
        try:
            model = cls(
                cfg.policy, venv, seed=seed, device=device, verbose=verbose,
                tensorboard_log=str(out_dir / TENSORBOARD_DIR) if tensorboard else None, **cfg.hyperparams,
            )  # fmt: skip
        except (AssertionError, ValueError, TypeError) as exc:
            message = " ".join(str(exc).split()) or type(exc).__name__
            raise InputError(f"{cfg.path}: {env_id}: {cls.__name__} rejected the hyperparameters: {message}") from exc

        hyperparams = cfg.resolved()
        hyperparams.update(n_envs=n_envs, n_timesteps=requested)
        run: dict[str, Any] = {
            "env_id": env_id,
            "algo": algo,
            "seed": seed,
            "timesteps": 0,
            "requested_timesteps": requested,
            "n_envs": n_envs,
            "env_kwargs": env_kwargs,
            "hyperparams": hyperparams,
            "config_file": str(cfg.path),
            "vec_env": type(_innermost(venv)).__name__,
            "command": command if command is not None else shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]]),
            "versions": versions(),
            "git_commit": git_commit(),
            "wall_clock_s": 0.0,
            "completed": False,
        }
        out_dir.mkdir(parents=True, exist_ok=True)
        write_json_atomic(out_dir / RUN_FILE, run)

        # ---- training
        metrics = EpisodeMetricsCallback()
        start = time.monotonic()
        interrupted = False
        try:
            model.learn(
                total_timesteps=requested,
                callback=[metrics, *callbacks],
                progress_bar=progress_bar,
                tb_log_name=cls.__name__,
            )
        except KeyboardInterrupt:
            interrupted = True
        elapsed = time.monotonic() - start

        # ---- the directory: model, statistics, then run.json (which marks it finished)
        with atomic_path(out_dir / MODEL_FILE, keep_suffix=True) as tmp:
            model.save(tmp)
        normalizer = model.get_vec_normalize_env()
        if normalizer is not None:
            with atomic_path(out_dir / VECNORMALIZE_FILE) as tmp:
                normalizer.save(tmp)
        run.update(
            timesteps=int(model.num_timesteps),
            wall_clock_s=round(elapsed, 3),
            completed=not interrupted,
            episode_metrics=metrics.means(),
        )
        write_json_atomic(out_dir / RUN_FILE, run)
    finally:
        venv.close()
    if interrupted:
        raise TrainingInterrupted(out_dir, int(model.num_timesteps))
    return out_dir


def _innermost(venv):
    while hasattr(venv, "venv"):
        inner = venv.venv
        if not hasattr(inner, "step_wait"):  # the adapter's venv is the Gymnasium vector env
            break
        venv = inner
    return venv
