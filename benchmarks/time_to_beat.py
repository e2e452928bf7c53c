"""Time to beat the paper: wall-clock time for PPO (configs/ppo.yml) to outscore the paper's wall follower.

PPO trains on ``polyenvs/BuckybotWallFollow-v0`` with its configs/ppo.yml entry (seed 0), built as ``polyenvs train``
builds it (``make_training_vec_env``, VecNormalize, the entry's hyperparameters), in chunks of ``chunk`` timesteps
continuing one model (``model.learn(..., reset_num_timesteps=False)``; a chunk ends on a whole rollout). After each
chunk the model and its VecNormalize statistics are saved to a scratch training directory and evaluated by
:func:`polyenvs.evaluation.episodes.evaluate` (which loads them through ``baselines.trained``: deterministic actions,
observations normalised with the saved statistics) on the published seeds ``EVAL_SEED, EVAL_SEED + 1, ...``. The
paper's policy is evaluated once on the same seeds. The run stops at the first chunk whose PPO IQM of the episode
returns exceeds the paper's, or at the budget.

Reported: the timesteps, the training time alone and training plus PPO evaluations (the paper's own evaluation is
timed apart) until then. From the repo root::

    python -m benchmarks.time_to_beat [--budget 300000] [--chunk 25000] [--episodes 20] [--seed 0] [--keep-going]
        [--json PATH]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import sys
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

__all__ = ["Chunk", "Race", "TimeToBeat", "format_result", "main", "time_to_beat"]

ENV_ID = "polyenvs/BuckybotWallFollow-v0"


@dataclass
class Chunk:
    """The state after one training chunk (times cumulative from the start of training)."""

    timesteps: int
    ppo_iqm: float
    ppo_mean: float
    train_s: float
    eval_s: float

    @property
    def total_s(self) -> float:
        return self.train_s + self.eval_s


@dataclass
class TimeToBeat:
    """What :func:`time_to_beat` measured. ``beaten`` is the first chunk whose PPO IQM exceeded the paper's."""

    env_id: str
    paper_policy: str
    paper_iqm: float
    paper_mean: float
    paper_eval_s: float
    seeds: list[int]
    budget: int
    chunk: int
    seed: int
    chunks: list[Chunk] = field(default_factory=list)

    @property
    def beaten(self) -> Chunk | None:
        return next((c for c in self.chunks if c.ppo_iqm > self.paper_iqm), None)

    def to_json(self) -> dict[str, Any]:
        beaten = self.beaten
        doc = asdict(self)
        doc["beaten"] = None if beaten is None else {**asdict(beaten), "total_s": beaten.total_s}
        return doc


def _returns_iqm(document: Mapping[str, Any]) -> tuple[float, float]:
    from polyenvs.evaluation.statistics import interquartile_mean

    returns = [episode["return"] for episode in document["episodes"]]
    return interquartile_mean(returns), float(sum(returns) / len(returns))


@dataclass(frozen=True)
class Race:
    """What :func:`time_to_beat` runs: PPO on ``env_id`` (seed ``seed``, its ``config`` entry, by default
    configs/ppo.yml's, with ``overrides`` replacing PPO arguments: tests shrink n_steps, on a ``vec_env`` as
    ``polyenvs train`` picks it) in chunks of ``chunk`` timesteps up to ``budget``, each chunk evaluated on
    ``episodes`` episodes from ``eval_seed`` (default: the published seeds) against ``paper_policy``; it stops at the
    first chunk that beats the paper unless ``stop_when_beaten`` is False."""

    env_id: str = ENV_ID
    budget: int = 300_000
    chunk: int = 25_000
    seed: int = 0
    episodes: int = 20
    eval_seed: int | None = None
    paper_policy: str = "paper"
    config: str | Path | None = None
    vec_env: str = "auto"
    overrides: Mapping[str, Any] | None = None
    stop_when_beaten: bool = True


def time_to_beat(race: Race, on_chunk: Callable[[Chunk, float], None] | None = None) -> TimeToBeat:
    """Train PPO in chunks until its IQM on the evaluation seeds exceeds the paper policy's, or the budget's steps
    (:class:`Race`). ``on_chunk(chunk, paper_iqm)`` is called after each chunk's evaluation."""
    import polyenvs  # noqa: F401  (registers the ids)
    from polyenvs.errors import check_count
    from polyenvs.evaluation.episodes import evaluate
    from polyenvs.evaluation.protocol import EVAL_SEED
    from polyenvs.registry import bare_id

    budget, chunk = check_count("budget", race.budget, 1), check_count("chunk", race.chunk, 1)
    eval_seed = EVAL_SEED if race.eval_seed is None else race.eval_seed
    race = dataclasses.replace(race, env_id=bare_id(race.env_id), budget=budget, chunk=chunk, eval_seed=eval_seed)

    start = time.perf_counter()
    paper = evaluate(race.env_id, race.paper_policy, episodes=race.episodes, seed=eval_seed)
    paper_iqm, paper_mean = _returns_iqm(paper)
    result = TimeToBeat(
        race.env_id, race.paper_policy, paper_iqm, paper_mean, time.perf_counter() - start, list(paper["seeds"]),
        budget, chunk, race.seed,
    )  # fmt: skip
    _train_in_chunks(race, result, on_chunk)
    return result


def _train_in_chunks(race: Race, result: TimeToBeat, on_chunk) -> None:
    """Train and evaluate chunk after chunk into ``result.chunks`` (the race's ids and counts checked already)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from polyenvs.training.config import default_config_path, load_config
    from polyenvs.training.vec_adapter import make_training_vec_env

    torch.set_num_threads(1)  # small MLPs: more threads only contend on these 2-core machines
    env_id, seed = race.env_id, race.seed
    cfg = load_config(race.config if race.config is not None else default_config_path("ppo"), env_id, "ppo")
    venv = make_training_vec_env(env_id, cfg.n_envs, seed=seed, wrappers=cfg.wrapper_callables(), vec_env=race.vec_env)
    train_s = eval_s = 0.0
    try:
        if cfg.normalize:
            venv = VecNormalize(venv, **cfg.normalize_kwargs)
        hyper = {**cfg.hyperparams, **dict(race.overrides or {})}
        model = PPO(cfg.policy, venv, seed=seed, device="cpu", verbose=0, **hyper)
        run = {"env_id": env_id, "algo": "ppo", "seed": seed, "hyperparams": cfg.resolved()}
        with tempfile.TemporaryDirectory(prefix="time_to_beat_") as scratch:
            out = Path(scratch)
            while model.num_timesteps < race.budget:
                tick = time.perf_counter()
                model.learn(
                    total_timesteps=min(race.chunk, race.budget - model.num_timesteps), reset_num_timesteps=False
                )
                train_s += time.perf_counter() - tick

                tick = time.perf_counter()
                document = _evaluate_chunk(race, model, out, run)
                eval_s += time.perf_counter() - tick

                iqm, mean = _returns_iqm(document)
                done = Chunk(int(model.num_timesteps), iqm, mean, train_s, eval_s)
                result.chunks.append(done)
                if on_chunk is not None:
                    on_chunk(done, result.paper_iqm)
                if race.stop_when_beaten and iqm > result.paper_iqm:
                    break
    finally:
        venv.close()


def _evaluate_chunk(race: Race, model, out: Path, run: dict) -> dict:
    """Save the model as a training directory in ``out`` and evaluate it (the evaluation's document)."""
    from polyenvs.evaluation.episodes import evaluate

    model.save(out / "model.zip")
    normalizer = model.get_vec_normalize_env()
    if normalizer is not None:
        normalizer.save(str(out / "vecnormalize.pkl"))
    (out / "run.json").write_text(json.dumps({**run, "timesteps": int(model.num_timesteps)}))
    return evaluate(race.env_id, str(out), episodes=race.episodes, seed=race.eval_seed)


def format_result(result: TimeToBeat) -> str:
    """The chunks as a Markdown table and a one-line verdict."""
    lines = [
        f"Paper policy (`{result.paper_policy}`) on seeds {result.seeds[0]}..{result.seeds[-1]}: IQM return"
        f" {result.paper_iqm:.2f} (mean {result.paper_mean:.2f}; evaluated in {result.paper_eval_s:.1f} s).",
        "",
        "| timesteps | PPO IQM return | PPO mean return | beats paper | training s | training + evaluation s |",
        "| ---: | ---: | ---: | --- | ---: | ---: |",
    ]
    for c in result.chunks:
        beats = "yes" if c.ppo_iqm > result.paper_iqm else "no"
        lines.append(
            f"| {c.timesteps:,} | {c.ppo_iqm:.2f} | {c.ppo_mean:.2f} | {beats} | {c.train_s:.1f} | {c.total_s:.1f} |"
        )
    beaten = result.beaten
    lines.append("")
    if beaten is None:
        lines.append(f"PPO did not exceed the paper's IQM within {result.budget:,} timesteps.")
    else:
        lines.append(
            f"PPO first exceeded the paper's IQM after {beaten.timesteps:,} timesteps: {beaten.train_s:.1f} s of"
            f" training, {beaten.total_s:.1f} s with the evaluations after each chunk."
        )
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.time_to_beat",
        description="Wall-clock time for PPO (configs/ppo.yml) to beat the paper's policy on the evaluation seeds.",
    )
    parser.add_argument("--env", default=ENV_ID, help=f"environment id (default {ENV_ID})")
    parser.add_argument(
        "--budget", type=int, default=300_000, help="timesteps to train at most, in whole rollouts (default 300000)"
    )
    parser.add_argument("--chunk", type=int, default=25_000, help="timesteps between evaluations (default 25000)")
    parser.add_argument("--episodes", type=int, default=20, help="evaluation episodes (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    parser.add_argument("--vec-env", choices=("auto", "native", "dummy"), default="auto")
    parser.add_argument(
        "--keep-going", action="store_true", help="train the whole budget, evaluating each chunk, after beating it"
    )
    parser.add_argument("--json", type=Path, help="also write the result as JSON to this path")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from polyenvs.errors import InputError

    def progress(c: Chunk, paper_iqm: float) -> None:
        print(
            f"{c.timesteps:>8,} steps: PPO IQM {c.ppo_iqm:8.2f} vs paper {paper_iqm:8.2f}"
            f"  ({c.train_s:.1f} s training, {c.total_s:.1f} s with evaluations)",
            file=sys.stderr,
            flush=True,
        )

    try:
        race = Race(
            args.env, budget=args.budget, chunk=args.chunk, seed=args.seed, episodes=args.episodes,
            vec_env=args.vec_env, stop_when_beaten=not args.keep_going,
        )  # fmt: skip
        result = time_to_beat(race, on_chunk=progress)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    print(format_result(result))
    print(f"\nMachine: {platform.platform()}; date {datetime.now(UTC):%Y-%m-%d %H:%M} UTC")
    if args.json is not None:
        args.json.write_text(json.dumps(result.to_json(), indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
