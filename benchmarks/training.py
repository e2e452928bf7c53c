"""Training speed: Stable-Baselines3 PPO timesteps/s on our environments against PPO on CartPole-v1.

The target is that the environment is never the bottleneck (the PPO row of ``benchmarks.targets``, a ratio to PPO
on CartPole). The PPO rows are timed
in interleaved rounds like the step rows (CartPole, then ours, the order reversed every other round), each round
running rollouts and gradient epochs, as a user training on the environment pays both.

``python -m benchmarks.throughput`` includes these rows; ``python -m benchmarks.training [--only SUBSTRING]
[--quick]`` measures and prints them alone (no step rows, nothing written).

Two settings, all rows in one :func:`~benchmarks.harness.measure_rounds` call (one session, so ratios pair rounds):

- 1 env (``gym.make``), n_steps 512, 4 epochs: the single-env rows (``vector`` False), against CartPole the same way;
- the 8-env setting of ``configs/ppo.yml`` (:data:`VEC_CONFIG_ID`'s entry: n_envs, n_steps, batch size, epochs,
  VecNormalize), each Buckybot id trained through the native VecEnv adapter
  (``make_training_vec_env(..., vec_env="native")``) and through SB3's ``DummyVecEnv`` of the single env
  (``vec_env="dummy"``), against CartPole-v1 in a ``DummyVecEnv`` at the same settings. These rows are marked
  ``vector`` so that the report takes their ratio to the 8-env CartPole row. Every id uses the one entry (the
  Explore entry's longer n_steps would need a second CartPole peer, and the report pairs one peer per kind).
"""

from __future__ import annotations

import argparse
import importlib
import platform
import time
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import gymnasium as gym

from benchmarks.harness import Case, Measurement, measure_rounds
from benchmarks.peers import CARTPOLE
from benchmarks.targets import Kind, target_for

__all__ = [
    "PPO_SETTING",
    "VEC_CONFIG_ID",
    "PPORunner",
    "VecPPORunner",
    "main",
    "measure_training",
    "vec_setting",
]

_N_STEPS = 512
PPO_SETTING = f"SB3 PPO MlpPolicy, 1 env, n_steps {_N_STEPS}, 4 epochs (timesteps/s)"
#: The configs/ppo.yml entry whose settings the 8-env rows use (BuckybotGoal-v0's entry is the same).
VEC_CONFIG_ID = "polyenvs/BuckybotWallFollow-v0"
#: How the 8-env rows build their VecEnv: (vec_env argument of make_training_vec_env, label).
VEC_KINDS = (("native", "native VecEnv adapter"), ("dummy", "DummyVecEnv"))


def _set_one_thread() -> None:
    import torch

    torch.set_num_threads(1)  # two threads on these 2-core machines are intermittently 10-100x slower


class PPORunner:
    """A PPO model on one ``gym.make`` env; each repeat learns ``timesteps`` more and returns timesteps/s."""

    num_envs = 1
    vector = False

    def __init__(self, env_id: str, *, timesteps: int, seed: int = 0) -> None:
        from stable_baselines3 import PPO

        _set_one_thread()
        self.timesteps = timesteps
        self.env = gym.make(env_id)
        self.model = PPO(
            "MlpPolicy", self.env, n_steps=_N_STEPS, batch_size=64, n_epochs=4, seed=seed, device="cpu", verbose=0
        )

    def warm_up(self) -> None:
        """One rollout and its epochs: compilation, torch's lazy set-up."""
        self.model.learn(total_timesteps=_N_STEPS)

    def timed_repeat(self) -> float:
        start = time.perf_counter()
        self.model.learn(total_timesteps=self.timesteps, reset_num_timesteps=False)
        return self.timesteps / (time.perf_counter() - start)

    def close(self) -> None:
        self.env.close()


def _vec_config(config: str | Path | None, overrides: Mapping[str, Any] | None) -> tuple[Any, dict[str, Any]]:
    """The configs/ppo.yml entry of :data:`VEC_CONFIG_ID` and its PPO arguments with ``overrides`` applied."""
    from polyenvs.training.config import default_config_path, load_config

    cfg = load_config(config if config is not None else default_config_path("ppo"), VEC_CONFIG_ID, "ppo")
    return cfg, {**cfg.hyperparams, **dict(overrides or {})}


def vec_setting(config: str | Path | None = None, overrides: Mapping[str, Any] | None = None, label: str = "") -> str:
    """The setting column of an 8-env row: the config entry's numbers, and how the VecEnv is built."""
    cfg, hyper = _vec_config(config, overrides)
    normalize = ", VecNormalize" if cfg.normalize else ""
    how = f" via {label}" if label else ""
    return (
        f"SB3 PPO MlpPolicy, {cfg.n_envs} envs{how}, n_steps {hyper.get('n_steps')}, batch {hyper.get('batch_size')},"
        f" {hyper.get('n_epochs')} epochs{normalize} (configs/ppo.yml; timesteps/s)"
    )


class VecPPORunner:
    """PPO at the 8-env setting of configs/ppo.yml on ``make_training_vec_env(env_id, n_envs, vec_env=...)``.

    Each repeat learns at least ``timesteps`` more (whole rollouts) and returns the timesteps done per second.
    """

    vector = True

    def __init__(
        self,
        env_id: str,
        *,
        vec_env: str,
        timesteps: int,
        seed: int = 0,
        config: str | Path | None = None,
        overrides: Mapping[str, Any] | None = None,
    ) -> None:
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import VecNormalize

        from polyenvs.training.vec_adapter import make_training_vec_env

        _set_one_thread()
        cfg, hyper = _vec_config(config, overrides)
        self.num_envs = cfg.n_envs
        self.timesteps = timesteps
        self.rollout = int(hyper.get("n_steps", 2048)) * cfg.n_envs
        venv = make_training_vec_env(env_id, cfg.n_envs, seed=seed, vec_env=vec_env)
        if cfg.normalize:
            venv = VecNormalize(venv, **cfg.normalize_kwargs)
        self.venv = venv
        self.model = PPO(cfg.policy, venv, seed=seed, device="cpu", verbose=0, **hyper)

    def warm_up(self) -> None:
        """One rollout and its epochs."""
        self.model.learn(total_timesteps=self.rollout)

    def timed_repeat(self) -> float:
        before = self.model.num_timesteps
        start = time.perf_counter()
        self.model.learn(total_timesteps=self.timesteps, reset_num_timesteps=False)
        return (self.model.num_timesteps - before) / (time.perf_counter() - start)

    def close(self) -> None:
        self.venv.close()


def measure_training(
    env_ids: Sequence[str],
    *,
    timesteps: int,
    repeats: int,
    seed: int = 0,
    vec: bool = True,
    vec_timesteps: int | None = None,
    config: str | Path | None = None,
    vec_overrides: Mapping[str, Any] | None = None,
) -> tuple[list[Measurement], list[str]]:
    """PPO on CartPole-v1 and on each id of ``env_ids`` that has a PPO target, in rounds; and notes.

    With ``vec``, also the 8-env setting of configs/ppo.yml: CartPole-v1 (DummyVecEnv), then each id through the
    native VecEnv adapter and through DummyVecEnv (ids without a native vector env get the DummyVecEnv row only).
    ``vec_timesteps`` (default 4 x ``timesteps``) is the least an 8-env row learns per round, in whole rollouts;
    ``vec_overrides`` replaces PPO arguments of the config entry (tests shrink n_steps and epochs).
    """
    missing = [name for name in ("torch", "stable_baselines3", "yaml") if not _imports(name)]
    if missing:
        return [], [f'training speed skipped: {", ".join(missing)} not installed (pip install "polyenvs[train]")']
    ids = [env_id for env_id in env_ids if target_for(env_id, Kind.PPO) is not None]
    cases = [Case(env_id, PPO_SETTING, start=_starter(env_id, timesteps, seed)) for env_id in [CARTPOLE, *ids]]
    notes: list[str] = []
    if vec:
        from polyenvs.evaluation.episodes import resolve_env

        per_round = vec_timesteps if vec_timesteps is not None else 4 * timesteps
        common = {"timesteps": per_round, "seed": seed, "config": config, "overrides": vec_overrides}
        cases.append(
            Case(
                CARTPOLE,
                vec_setting(config, vec_overrides, "DummyVecEnv"),
                start=_vec_starter(CARTPOLE, "dummy", common),
                vector=True,
            )
        )
        for env_id in ids:
            for vec_env, label in VEC_KINDS:
                if vec_env == "native" and not resolve_env(env_id).native_vector:
                    notes.append(f"{env_id}: no native vector env, so no adapter row")
                    continue
                setting = vec_setting(config, vec_overrides, label)
                cases.append(Case(env_id, setting, start=_vec_starter(env_id, vec_env, common), vector=True))
    return measure_rounds(cases, repeats=repeats), notes


def _starter(env_id: str, timesteps: int, seed: int) -> Any:
    return lambda: PPORunner(env_id, timesteps=timesteps, seed=seed)


def _vec_starter(env_id: str, vec_env: str, common: dict[str, Any]) -> Any:
    return lambda: VecPPORunner(env_id, vec_env=vec_env, **common)


def _imports(module: str) -> bool:
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """Measure the PPO rows alone and print their table (the step rows are ``benchmarks.throughput``'s)."""
    from benchmarks.ours import polyenvs_cases
    from benchmarks.report import format_notes, format_training_table

    parser = argparse.ArgumentParser(prog="python -m benchmarks.training", description=main.__doc__)
    parser.add_argument("--only", metavar="SUBSTRING", help="only our envs whose id contains SUBSTRING")
    parser.add_argument("--quick", action="store_true", help="2 rounds of 512 (1 env) / 2048 (8 envs) timesteps")
    parser.add_argument("--repeats", type=int, default=3, help="interleaved rounds (default 3)")
    parser.add_argument("--timesteps", type=int, default=2048, help="1-env timesteps per round (default 2048)")
    args = parser.parse_args(argv)
    repeats, timesteps = (2, 512) if args.quick else (args.repeats, args.timesteps)
    cases, notes = polyenvs_cases(only=args.only, min_seconds=0.1, seed=0)
    env_ids = list(dict.fromkeys(case.name for case in cases if not case.vector and not case.skip))
    rows, training_notes = measure_training(env_ids, timesteps=timesteps, repeats=repeats)
    print(format_training_table(rows))
    if notes or training_notes:
        print()
        print(format_notes([*notes, *training_notes]))
    print(
        f"\n{repeats} interleaved rounds; 1-env rows learn {timesteps} timesteps per round, 8-env rows at least"
        f" {4 * timesteps}. Machine: {platform.platform()}, {platform.processor() or 'CPU'}; "
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC."
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
