"""The ``polyenvs train`` subcommand.

``polyenvs train ENV_ID --algo ALGO [--config FILE] [--timesteps N] [--seed S] [--n-envs N] [--env-kwargs JSON] [--layouts L]
[--out DIR] [--resume | --overwrite] [--checkpoint-every N] [--progress/--no-progress] [--residual NAME
[--residual-scale S] [--residual-log-std L] [--residual-hold K]] [--bc-from DATASET [--bc-epochs N] [--bc-log-std X]]``

The flags build one :class:`~polyenvs.training.train.TrainRequest`, which
:func:`~polyenvs.training.train.train` runs. Every flag is checked before any work: a bad value raises
:class:`~polyenvs.errors.InputError`, which the command line prints as one line (exit 2).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from polyenvs.commands.flags import add_progress_flag, float_flag, int_flag, is_terminal, parse_json_object
from polyenvs.errors import InputError
from polyenvs.limits import MAX_N_ENVS, MAX_SEED, MAX_TIMESTEPS
from polyenvs.registry import bare_id

__all__ = ["add_parser", "default_out_dir", "run"]

#: Where ``polyenvs train`` writes by default (gitignored, like every run's output).
DEFAULT_TRAIN_DIR = Path("runs/train")


def default_out_dir(env_id: str, algo: str, seed: int) -> Path:
    """``runs/train/<EnvName>/<algo>/seed<S>`` (``EnvName``: the id without its namespace)."""
    return DEFAULT_TRAIN_DIR / bare_id(env_id).split("/")[-1] / algo / f"seed{seed}"


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``train`` subcommand to an ``argparse`` subparsers object; ``args.func`` is :func:`run`."""
    from baselines.algorithms import ALGOS
    from polyenvs.training.train import DEFAULT_CHECKPOINT_EVERY

    p = subparsers.add_parser(
        "train",
        help="train an agent with Stable-Baselines3 (needs polyenvs[train])",
        description="Train an agent with Stable-Baselines3 / sb3-contrib on hyperparameters from an RL Zoo-format "
        "config, on the id's native vector env where it has one. Writes DIR/model.zip, DIR/vecnormalize.pkl (when "
        "the config normalises), DIR/run.json (config, seed, command, versions, git commit), the learning curve "
        "in DIR/curve.json and TensorBoard logs in DIR/tb. The model is saved every --checkpoint-every timesteps and on Ctrl-C (run.json: completed false); "
        "--resume continues such a run, --overwrite trains it again. A DIR that holds a finished run of the same "
        "id, algorithm and seed is left as it is (unless --overwrite).",
    )
    p.add_argument("env_id", help="environment id (polyenvs list)")
    p.add_argument("--algo", required=True, help=f"one of {', '.join(ALGOS)}")
    p.add_argument(
        "--config", default=None, help="RL Zoo-format YAML file (default: the configs/ALGO.yml shipped with polyenvs)"
    )
    p.add_argument(
        "--timesteps",
        default=None,
        help=f"training steps, 1 to {MAX_TIMESTEPS:,} (default: the config's n_timesteps)",
    )
    p.add_argument("--seed", default="0", help=f"training seed, 0 to {MAX_SEED} (default 0)")
    p.add_argument(
        "--n-envs", default=None, help=f"parallel environments, 1 to {MAX_N_ENVS} (default: the config's n_envs)"
    )
    p.add_argument("--env-kwargs", default="{}", help="JSON object of environment keyword arguments")
    p.add_argument(
        "--layouts",
        default=None,
        help="the layouts the episodes are drawn from: train (the default, Procgen's protocol: the leaderboard "
        "judges agents on the held-out test layouts and counts only those trained on train), default or test; "
        "recorded in run.json's env_kwargs (also --env-kwargs' layouts, or the config's env_kwargs)",
    )
    p.add_argument(
        "--out", default=None, metavar="DIR", help=f"output directory (default {DEFAULT_TRAIN_DIR}/ENV/ALGO/seedS)"
    )
    again = p.add_mutually_exclusive_group()
    again.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted run in DIR from its saved model (the last checkpoint or what Ctrl-C saved) "
        "up to the requested timesteps; with no saved model, train it from the start",
    )
    again.add_argument(
        "--overwrite", action="store_true", help="replace the run in DIR (finished or not): train from the start"
    )
    p.add_argument(
        "--checkpoint-every",
        default=str(DEFAULT_CHECKPOINT_EVERY),
        help=f"save the model every this many timesteps, so that a killed run can --resume; 0: only at the end "
        f"and on Ctrl-C (default {DEFAULT_CHECKPOINT_EVERY})",
    )
    add_bc_flags(p)
    add_progress_flag(p)
    _add_residual_flags(p)
    p.set_defaults(func=run)
    return p


def add_bc_flags(parser) -> None:
    """``--bc-from``, ``--bc-epochs``, ``--bc-log-std``: behaviour cloning before training (:mod:`polyenvs.training.bc`)."""
    from polyenvs.limits import MAX_BC_EPOCHS
    from polyenvs.training.bc import DEFAULT_BC_EPOCHS

    parser.add_argument(
        "--bc-from",
        default=None,
        metavar="DATASET",
        help="pretrain the policy on the demonstrations in DATASET (a directory polyenvs collect wrote, of this id) "
        "before training: VecNormalize statistics from them, the actions' log-likelihood, the value head on their "
        "returns (ppo, maskable_ppo)",
    )
    parser.add_argument(
        "--bc-epochs",
        default=None,
        help=f"passes over the demonstrations, 1 to {MAX_BC_EPOCHS} (default {DEFAULT_BC_EPOCHS}; needs --bc-from)",
    )
    parser.add_argument(
        "--bc-log-std",
        default=None,
        help="Box actions: the Gaussian's log standard deviation after cloning, -20 to 2 (PPO's exploration from "
        "there; default: what the fit learned; needs --bc-from)",
    )


def behaviour_cloning(args: argparse.Namespace):
    """The :class:`~polyenvs.training.bc.BehaviourCloning` the flags ask for, its dataset read; or None."""
    from polyenvs.limits import MAX_BC_EPOCHS
    from polyenvs.training.bc import BC_ALGOS, DEFAULT_BC_EPOCHS, BehaviourCloning

    epochs = int_flag("--bc-epochs", args.bc_epochs, 1, MAX_BC_EPOCHS)
    log_std = float_flag("--bc-log-std", args.bc_log_std, -20.0, 2.0)
    if args.bc_from is None:
        for flag, value in (("--bc-epochs", epochs), ("--bc-log-std", log_std)):
            if value is not None:
                raise InputError(f"{flag} needs --bc-from (the demonstrations to clone)")
        return None
    if args.residual is not None:  # a residual agent observes the base action too: not the demonstrations' space
        raise InputError("--bc-from and --residual exclude each other: clone a plain policy, or learn a residual")
    if args.algo not in BC_ALGOS:
        raise InputError(f"--bc-from pretrains an actor-critic policy: --algo must be one of {', '.join(BC_ALGOS)}")
    bc = BehaviourCloning(Path(args.bc_from), epochs or DEFAULT_BC_EPOCHS, log_std=log_std, flag="--bc-from")
    bc.demonstrations()
    return bc


def _add_residual_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--residual",
        default=None,
        metavar="NAME",
        help="train a residual agent: a correction of this hand baseline's actions (paper, a name polyenvs list "
        "gives the id, or a directory polyenvs tune wrote), started at the baseline; Box actions (Gymnasium ids and "
        "the PettingZoo swarms)",
    )
    p.add_argument("--residual-scale", default=None, help="the correction is S x the agent's action, 0 < S <= 2 "
                   "(default 0.5)")  # fmt: skip
    p.add_argument(
        "--residual-log-std",
        default=None,
        help="the residual agent's starting log standard deviation, -10 to 1 (default: the config's)",
    )
    p.add_argument(
        "--residual-hold",
        default=None,
        metavar="K",
        help="the agent decides every K control ticks and its correction is held for them, the baseline re-run "
        "every tick (default 1; 5 on a beast: 50 ms decisions)",
    )


def _residual_flags(args: argparse.Namespace):
    """``(ResidualSpec or None, log_std or None)`` of the residual flags; InputError for a bad one."""
    from baselines.residual import MAX_HOLD, MAX_SCALE, ResidualSpec
    from polyenvs.training.residual import MAX_LOG_STD, MIN_LOG_STD

    scale = float_flag("--residual-scale", args.residual_scale, 0.0, MAX_SCALE)
    log_std = float_flag("--residual-log-std", args.residual_log_std, MIN_LOG_STD, MAX_LOG_STD)
    hold = int_flag("--residual-hold", args.residual_hold, 1, MAX_HOLD)
    if args.residual is None:
        if scale is not None or log_std is not None or hold is not None:
            raise InputError("--residual-scale, --residual-log-std and --residual-hold need --residual NAME")
        return None, None
    if scale == 0:
        raise InputError("--residual-scale must be > 0, got 0")
    if not args.residual:
        raise InputError("--residual needs a baseline's name, got ''")
    return ResidualSpec(args.residual, 0.5 if scale is None else scale, hold=1 if hold is None else hold), log_std


def training_request(args: argparse.Namespace):
    """The :class:`~polyenvs.training.train.TrainRequest` the flags ask for; InputError (naming the flag) for a bad
    one, before any work."""
    from baselines.algorithms import get_algo
    from polyenvs.training.train import TrainRequest

    get_algo(args.algo)
    timesteps = int_flag("--timesteps", args.timesteps, 1, MAX_TIMESTEPS)
    seed = int_flag("--seed", args.seed, 0, MAX_SEED)
    n_envs = int_flag("--n-envs", args.n_envs, 1, MAX_N_ENVS)
    checkpoint_every = int_flag("--checkpoint-every", args.checkpoint_every, 0, MAX_TIMESTEPS)
    env_kwargs = parse_json_object(args.env_kwargs, "--env-kwargs")
    residual, residual_log_std = _residual_flags(args)
    algo_dir = args.algo if residual is None else f"{args.algo}_residual_{residual.baseline}"
    return TrainRequest(
        args.env_id,
        args.algo,
        out_dir=Path(args.out) if args.out is not None else default_out_dir(args.env_id, algo_dir, seed),
        config=args.config,
        timesteps=timesteps,
        seed=seed,
        n_envs=n_envs,
        env_kwargs=env_kwargs,
        layouts=args.layouts,
        resume=getattr(args, "resume", False),
        overwrite=getattr(args, "overwrite", False),
        checkpoint_every=checkpoint_every,
        pretrain=behaviour_cloning(args),
        residual=residual,
        residual_log_std=residual_log_std,
        progress_bar=args.progress if args.progress is not None else is_terminal(sys.stderr),
    )


def run(args: argparse.Namespace) -> int:
    """Run ``polyenvs train`` for parsed ``args``; 0 when trained (or already finished), 130 after Ctrl-C."""
    request = training_request(args)

    from polyenvs.training.train import (
        TrainingInterrupted,
        check_out_dir,
        check_same_residual,
        interrupted_note,
        read_run,
        train,
    )

    out_dir, seed = request.out_dir, request.seed
    try:
        action = check_out_dir(
            out_dir, args.env_id, args.algo, seed, resume=request.resume, overwrite=request.overwrite
        )
    except InputError as exc:  # name the flags, as the command line spells them
        raise InputError(str(exc).replace("resume and overwrite", "--resume and --overwrite")) from None
    if action == "finished":
        check_same_residual(out_dir, request.residual)
        print(f"{out_dir} already holds a finished run of {args.env_id} {args.algo} seed {seed}: nothing to do")
        return 0
    if action in ("resume", "restart"):
        print(f"{out_dir}: {interrupted_note(out_dir)}")
    start = time.monotonic()
    try:
        train(request)
    except TrainingInterrupted as stop:
        print(
            f"polyenvs train: interrupted after {stop.timesteps} timesteps; saved the partial model in "
            f"{stop.out_dir} (run.json: completed false); the same command with --resume continues it",
            file=sys.stderr,
        )
        return 130
    doc = read_run(out_dir) or {}
    steps, seconds = doc.get("timesteps", 0), doc.get("wall_clock_s", time.monotonic() - start)
    rate = f", {steps / seconds:,.0f} steps/s" if seconds else ""
    print(f"trained {args.algo} on {doc.get('env_id', args.env_id)}: {steps} timesteps in {seconds:.1f} s{rate}")
    for name, value in (doc.get("episode_metrics") or {}).items():
        print(f"  {name} (last episodes' mean): {value:.4g}")
    print(f"wrote {out_dir}")
    return 0
