"""Environment throughput against peer environments, measured in one process run.

Every figure that matters is a ratio to a peer measured in the same run (CartPole-v1, its native vector env,
MiniGrid), because these shared machines drift by up to 25% between runs. See the performance spec
(``performance.md``) for the peers and the targets.

Usable as a library (``measure_env_steps``, ``run``, ``format_table``, ``format_report``) or from the repo root::

    python -m benchmarks.throughput [--quick] [--only SUBSTRING] [--no-write] [--output PATH]
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import math
import os
import platform
import statistics
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import gymnasium as gym

DEFAULT_OUTPUT = Path(__file__).resolve().parent / "THROUGHPUT.md"

VECTOR_NUM_ENVS = 1024
SETTING_MAKE = "`gym.make` (default wrappers)"
SETTING_VECTOR = f"native vector env, {VECTOR_NUM_ENVS} envs (env-steps/s)"
CARTPOLE = "CartPole-v1"
MINIGRID = "MiniGrid-Empty-8x8-v0"

# Pre-sampled actions per repeat, counted in single-env actions, so a batched action of 1024 counts 1024.
_ACTION_BLOCK = 10_000
# The timed loop reads the clock about this often; often enough that a slow env does not overshoot by much,
# rarely enough that reading the clock costs nothing next to a ~9 µs CartPole step.
_CHECK_INTERVAL_S = 0.01
_WARMUP_SECONDS = 0.1
_WARMUP_MAX_STEPS = 200
_MEMORY_STEPS_SINGLE = 100
_MEMORY_STEPS_VECTOR = 10


@dataclass
class Measurement:
    """One row of the table; rows that were skipped or failed have NaN rates and say why in ``note``."""

    name: str
    setting: str
    steps_per_second: float
    us_per_step: float
    peak_memory_mb: float | None
    note: str = ""
    num_envs: int = 1
    vector: bool = False
    per_repeat: tuple[float, ...] = field(default_factory=tuple)

    @property
    def ok(self) -> bool:
        """Whether the row holds a real rate."""
        return math.isfinite(self.steps_per_second) and self.steps_per_second > 0


@dataclass(frozen=True)
class Target:
    """A row's target from the performance spec: minimum ratios to the peers and a memory budget."""

    vs_cartpole: float
    vs_minigrid: float | None = None
    max_memory_mb: float | None = None

    def describe(self, vector: bool) -> str:
        """The target as the table shows it."""
        peer = "CartPole vector env" if vector else CARTPOLE
        parts = [f">= {self.vs_cartpole:g}x {peer}"]
        if self.vs_minigrid is not None:
            parts.append(f">= {self.vs_minigrid:g}x MiniGrid")
        if self.max_memory_mb is not None:
            parts.append(f"< {self.max_memory_mb:g} MB")
        return ", ".join(parts)


# (id prefix, vector?) -> target, from the performance spec; families not listed here have no row target.
TARGETS: dict[tuple[str, bool], Target] = {
    ("polyenvs/Buckybot", False): Target(vs_cartpole=0.5, vs_minigrid=10.0, max_memory_mb=5.0),
    ("polyenvs/Bumper", False): Target(vs_cartpole=0.1, max_memory_mb=5.0),
    ("polyenvs/Buckybot", True): Target(vs_cartpole=0.1, max_memory_mb=200.0),
}


def target_for(name: str, vector: bool) -> Target | None:
    """The spec's target for an environment id, looked up by id prefix."""
    for (prefix, is_vector), target in TARGETS.items():
        if is_vector == vector and name.startswith(prefix):
            return target
    return None


# --------------------------------------------------------------------------------------------------- measuring


def _num_envs(env: Any) -> tuple[int, bool]:
    """How many envs one ``step`` advances, and whether ``env`` is batched (and so resets itself)."""
    if isinstance(env, gym.vector.VectorEnv) or hasattr(env, "num_envs"):
        return int(env.num_envs), True
    return 1, False


def _run_steps(env: Any, actions: Sequence[Any], vector: bool) -> None:
    """Step through ``actions``, resetting a single env when its episode ends."""
    step = env.step
    if vector:
        for action in actions:
            step(action)
        return
    reset = env.reset
    for action in actions:
        _, _, terminated, truncated, _ = step(action)
        if terminated or truncated:
            reset()


def _warm_up(env: Any, vector: bool) -> float:
    """Run untimed steps (JIT compilation, caches, lazy setup) and return a rough seconds-per-step estimate."""
    sample = env.action_space.sample
    # The first step may compile or allocate lazily; keep it out of the estimate.
    _run_steps(env, [sample()], vector)
    steps = 0
    start = time.perf_counter()
    elapsed = 0.0
    while steps < _WARMUP_MAX_STEPS and elapsed < _WARMUP_SECONDS:
        _run_steps(env, [sample()], vector)
        steps += 1
        elapsed = time.perf_counter() - start
    return elapsed / max(steps, 1)


def _timed_repeat(env: Any, actions: list[Any], check_every: int, min_seconds: float, vector: bool) -> float:
    """Step for at least ``min_seconds``, cycling through ``actions``; return env.step calls per second."""
    chunks = [actions[i : i + check_every] for i in range(0, len(actions), check_every)]
    clock = time.perf_counter
    steps = 0
    start = clock()
    while True:
        for chunk in chunks:
            _run_steps(env, chunk, vector)
            steps += len(chunk)
            elapsed = clock() - start
            if elapsed >= min_seconds:
                return steps / elapsed


def peak_memory_mb(make_fn: Callable[[], Any], *, steps: int | None = None, seed: int = 0) -> float:
    """Peak traced allocations (MB) while building ``make_fn()``, resetting it and taking ``steps`` random steps.

    Run this after the env's modules are imported, so imports are not counted; allocations outside Python's
    allocator (MuJoCo's, torch's) are not seen by tracemalloc.
    """
    was_tracing = tracemalloc.is_tracing()
    if not was_tracing:
        tracemalloc.start()
    tracemalloc.reset_peak()
    baseline = tracemalloc.get_traced_memory()[0]
    env = None
    try:
        env = make_fn()
        _, vector = _num_envs(env)
        env.reset(seed=seed)
        env.action_space.seed(seed)
        if steps is None:
            steps = _MEMORY_STEPS_VECTOR if vector else _MEMORY_STEPS_SINGLE
        _run_steps(env, [env.action_space.sample() for _ in range(steps)], vector)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        if env is not None:
            env.close()
        if not was_tracing:
            tracemalloc.stop()
    return max(peak - baseline, 0) / 1e6


def measure_env_steps(
    make_fn: Callable[[], Any],
    *,
    min_seconds: float = 2.0,
    repeats: int = 3,
    seed: int = 0,
    name: str | None = None,
    setting: str = "",
    note: str = "",
    measure_memory: bool = True,
) -> Measurement:
    """Median steps/s over ``repeats`` runs of at least ``min_seconds`` each, with random actions.

    ``make_fn()`` may return a Gymnasium ``Env`` (reset on terminated or truncated, inside the timing) or a
    ``VectorEnv`` (assumed to reset itself), whose rate is counted in env-steps (vector steps x ``num_envs``).
    Actions come from the env's own seeded action space, pre-sampled before each repeat so that sampling stays
    outside the timed loop. Peak memory is measured in a separate untimed run, since tracemalloc slows steps.
    """
    if min_seconds <= 0 or repeats < 1:
        raise ValueError("min_seconds must be > 0 and repeats >= 1")
    env = make_fn()
    try:
        num_envs, vector = _num_envs(env)
        if name is None:
            spec = getattr(env, "spec", None)
            name = spec.id if spec is not None else type(env).__name__
        env.reset(seed=seed)
        env.action_space.seed(seed)
        step_seconds = _warm_up(env, vector)
        check_every = max(1, min(1024, int(_CHECK_INTERVAL_S / max(step_seconds, 1e-9))))
        block = max(check_every, _ACTION_BLOCK // num_envs)
        rates = []
        for _ in range(repeats):
            actions = [env.action_space.sample() for _ in range(block)]
            rates.append(_timed_repeat(env, actions, check_every, min_seconds, vector) * num_envs)
    finally:
        env.close()
    rate = statistics.median(rates)
    peak = peak_memory_mb(make_fn, seed=seed) if measure_memory else None
    if vector and not note:
        note = f"{num_envs} envs; {1e6 * num_envs / rate:,.0f} µs per vector step"
    return Measurement(
        name=name,
        setting=setting,
        steps_per_second=rate,
        us_per_step=1e6 / rate,
        peak_memory_mb=peak,
        note=note,
        num_envs=num_envs,
        vector=vector,
        per_repeat=tuple(rates),
    )


def not_measured(name: str, setting: str, note: str, *, vector: bool = False) -> Measurement:
    """A row for a peer or env that was skipped or failed, so it is listed rather than dropped."""
    return Measurement(name, setting, math.nan, math.nan, None, note, vector=vector)


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def safe_measure(
    name: str, setting: str, make_fn: Callable[[], Any], *, vector: bool = False, **kwargs: Any
) -> Measurement:
    """``measure_env_steps`` that turns an exception into a row with a one-line error note."""
    _progress(f"measuring {name} [{setting}] ...")
    try:
        return measure_env_steps(make_fn, name=name, setting=setting, **kwargs)
    except Exception as exc:  # noqa: BLE001 - a broken env must not stop the other rows
        _progress(f"  failed: {_one_line(exc)}")
        return not_measured(name, setting, f"error: {_one_line(exc)}", vector=vector)


def _progress(message: str) -> None:
    # Progress goes to stderr so that stdout stays a clean Markdown table.
    print(message, file=sys.stderr, flush=True)


def _missing(package: str) -> bool:
    try:
        importlib.import_module(package)
    except ImportError:
        return True
    return False


# ---------------------------------------------------------------------------------------- adapters for peers


class _ParallelEnvAsGym:
    """A PettingZoo parallel env seen as one Gymnasium-style env whose step is a joint step of all agents."""

    def __init__(self, env: Any) -> None:
        self.env = env
        self.action_space = gym.spaces.Dict({agent: env.action_space(agent) for agent in env.possible_agents})

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        return self.env.reset(seed=seed, options=options)

    def step(self, actions: dict):
        live = self.env.agents
        if len(live) != len(actions):
            actions = {agent: actions[agent] for agent in live}
        obs, rewards, terminations, _, infos = self.env.step(actions)
        # The episode is over once no agent is left, which is when PettingZoo expects a reset.
        done = not self.env.agents
        return obs, rewards, done and any(terminations.values()), done and not any(terminations.values()), infos

    def close(self) -> None:
        self.env.close()


class _VmasActions:
    """Random batched actions for every VMAS agent, with the Gymnasium ``seed``/``sample`` interface."""

    def __init__(self, env: Any) -> None:
        self.env = env

    def seed(self, seed: int | None = None) -> None:
        import torch

        if seed is not None:
            torch.manual_seed(seed)

    def sample(self) -> list:
        return [self.env.get_random_action(agent) for agent in self.env.agents]


class _VmasBatch:
    """A VMAS environment stepped as a batch, resetting finished sub-environments itself like a VectorEnv."""

    def __init__(self, env: Any) -> None:
        self.env = env
        self.num_envs = env.num_envs
        self.action_space = _VmasActions(env)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self.env.seed(seed)
        return self.env.reset(), {}

    def step(self, actions: list):
        obs, rewards, dones, infos = self.env.step(actions)
        if dones.all():
            self.env.reset()
        elif dones.any():
            for index in dones.nonzero().flatten().tolist():
                self.env.reset_at(index)
        return obs, rewards, dones, dones, infos

    def close(self) -> None:
        pass


def _make_mpe2_spread(n_agents: int) -> Callable[[], Any]:
    def make() -> Any:
        from mpe2 import simple_spread_v3

        return _ParallelEnvAsGym(simple_spread_v3.parallel_env(N=n_agents))

    return make


def _make_vmas_navigation() -> Any:
    import torch
    import vmas

    # The spec measures VMAS with one torch thread: two threads run 10-100x slower on these 2-core machines.
    torch.set_num_threads(1)
    env = vmas.make_env(
        scenario="navigation", num_envs=VECTOR_NUM_ENVS, device="cpu", continuous_actions=True, n_agents=4, seed=0
    )
    return _VmasBatch(env)


# ------------------------------------------------------------------------------------------------- the rows


def measure_peers(*, min_seconds: float, repeats: int, seed: int = 0) -> list[Measurement]:
    """The peer rows: CartPole (single and vector) and MiniGrid always, the others when their package imports."""
    kw: dict[str, Any] = {"min_seconds": min_seconds, "repeats": repeats, "seed": seed}
    rows = [safe_measure(CARTPOLE, SETTING_MAKE, lambda: gym.make(CARTPOLE), **kw)]

    if _missing("minigrid"):
        rows.append(not_measured(MINIGRID, SETTING_MAKE, "skipped: minigrid not installed"))
    else:
        rows.append(safe_measure(MINIGRID, SETTING_MAKE, lambda: gym.make(MINIGRID), **kw))

    rows.append(
        safe_measure(
            CARTPOLE,
            SETTING_VECTOR,
            lambda: gym.make_vec(CARTPOLE, num_envs=VECTOR_NUM_ENVS, vectorization_mode="vector_entry_point"),
            vector=True,
            **kw,
        )
    )

    ant_setting = "`gym.make`, frame_skip 5"
    if _missing("mujoco"):
        rows.append(not_measured("Ant-v5", ant_setting, "skipped: mujoco not installed"))
    else:
        rows.append(safe_measure("Ant-v5", ant_setting, lambda: gym.make("Ant-v5"), **kw))

    for n_agents in (3, 20):
        name, setting = "mpe2 simple_spread_v3", f"N = {n_agents}, joint steps/s"
        if _missing("mpe2"):
            rows.append(not_measured(name, setting, "skipped: mpe2 not installed"))
            continue
        row = safe_measure(name, setting, _make_mpe2_spread(n_agents), **kw)
        if row.ok:
            row.note = f"{row.steps_per_second * n_agents:,.0f} agent-steps/s"
        rows.append(row)

    name, setting = "VMAS navigation", f"{VECTOR_NUM_ENVS} envs x 4 agents, 1 torch thread (env-steps/s)"
    if _missing("vmas"):
        rows.append(not_measured(name, setting, "skipped: vmas not installed", vector=True))
    else:
        rows.append(safe_measure(name, setting, _make_vmas_navigation, vector=True, **kw))
    return rows


@dataclass
class Registry:
    """What ``polyenvs.registry`` offers, or notes on why it offers nothing yet."""

    env_ids: list[str] = field(default_factory=list)
    vector_benchmarks: dict[str, Callable[[int], Any]] | None = None
    notes: list[str] = field(default_factory=list)


def load_registry() -> Registry:
    """Import ``polyenvs.registry`` (which registers the Gymnasium ids), tolerating a registry not written yet."""
    result = Registry()
    try:
        importlib.import_module("polyenvs")
        registry = importlib.import_module("polyenvs.registry")
    except ModuleNotFoundError as exc:
        if exc.name in ("polyenvs", "polyenvs.registry"):
            result.notes.append(f"`{exc.name}` does not exist yet: only the peers were measured.")
        else:
            result.notes.append(f"importing polyenvs.registry failed ({_one_line(exc)}): only the peers were measured.")
        result.notes.append("no native vector env yet.")
        return result
    except Exception as exc:  # noqa: BLE001 - a half-written registry must not hide the peers
        result.notes.append(f"importing polyenvs.registry failed ({_one_line(exc)}): only the peers were measured.")
        result.notes.append("no native vector env yet.")
        return result

    env_ids = getattr(registry, "ENV_IDS", None)
    if env_ids is None:
        result.notes.append("`polyenvs.registry.ENV_IDS` does not exist yet: no polyenvs environment was measured.")
    else:
        result.env_ids = [str(env_id) for env_id in env_ids]
    vector_benchmarks = getattr(registry, "VECTOR_BENCHMARKS", None)
    if vector_benchmarks is None:
        result.notes.append("no native vector env yet (`polyenvs.registry.VECTOR_BENCHMARKS` does not exist).")
    else:
        result.vector_benchmarks = dict(vector_benchmarks)
    return result


def measure_polyenvs(
    registry: Registry, *, only: str | None, min_seconds: float, repeats: int, seed: int = 0
) -> tuple[list[Measurement], list[str]]:
    """Rows for our environments (``gym.make`` with default wrappers, then the native vector envs) and notes."""
    kw: dict[str, Any] = {"min_seconds": min_seconds, "repeats": repeats, "seed": seed}
    notes: list[str] = []
    env_ids = [env_id for env_id in registry.env_ids if only is None or only in env_id]
    vector = registry.vector_benchmarks or {}
    vector_ids = [env_id for env_id in vector if only is None or only in env_id]
    if only is not None and (registry.env_ids or vector) and not (env_ids or vector_ids):
        notes.append(f"no polyenvs environment id contains {only!r}.")

    rows = [safe_measure(env_id, SETTING_MAKE, _maker(env_id), **kw) for env_id in env_ids]
    for env_id in vector_ids:
        make_vector = vector[env_id]
        rows.append(safe_measure(env_id, SETTING_VECTOR, lambda f=make_vector: f(VECTOR_NUM_ENVS), vector=True, **kw))
    return rows, notes


def _maker(env_id: str) -> Callable[[], Any]:
    return lambda: gym.make(env_id)


def run(
    *, min_seconds: float = 2.0, repeats: int = 3, only: str | None = None, seed: int = 0
) -> tuple[list[Measurement], list[str]]:
    """Measure the peers and our environments in one run; return the rows and general notes."""
    rows = measure_peers(min_seconds=min_seconds, repeats=repeats, seed=seed)
    registry = load_registry()
    ours, notes = measure_polyenvs(registry, only=only, min_seconds=min_seconds, repeats=repeats, seed=seed)
    return rows + ours, registry.notes + notes


# ------------------------------------------------------------------------------------------ training speed

#: Training rows measured against PPO on CartPole-v1 in the same run (performance spec): id -> minimum ratio.
TRAINING_TARGETS = {"polyenvs/BuckybotWallFollow-v0": 0.8}


def measure_ppo(env_id: str, *, timesteps: int, seed: int = 0) -> Measurement:
    """Stable-Baselines3 PPO (MlpPolicy, one env, one torch thread) timesteps per second on ``env_id``.

    The rollout and the gradient epochs are both timed, as a user training on the environment pays both.
    """
    import torch
    from stable_baselines3 import PPO

    torch.set_num_threads(1)  # two threads on these 2-core machines are intermittently 10-100x slower
    env = gym.make(env_id)
    model = PPO("MlpPolicy", env, n_steps=512, batch_size=64, n_epochs=4, seed=seed, device="cpu", verbose=0)
    model.learn(total_timesteps=512)  # warm-up: first rollout, compilation, torch's lazy set-up
    start = time.perf_counter()
    model.learn(total_timesteps=timesteps, reset_num_timesteps=False)
    rate = timesteps / (time.perf_counter() - start)
    env.close()
    return Measurement(env_id, "SB3 PPO MlpPolicy, 1 env, n_steps 512, 4 epochs (timesteps/s)", rate, 1e6 / rate, None)


def measure_training(env_ids: Sequence[str], *, timesteps: int, seed: int = 0) -> tuple[list[Measurement], list[str]]:
    """PPO on CartPole-v1 and on each id of ``env_ids`` that has a training target; notes say what was skipped."""
    if _missing("stable_baselines3") or _missing("torch"):
        return [], ['training speed skipped: stable-baselines3 / torch not installed (pip install "polyenvs[train]")']
    rows = []
    for env_id in [CARTPOLE, *[e for e in env_ids if e in TRAINING_TARGETS]]:
        _progress(f"PPO on {env_id} ...")
        try:
            rows.append(measure_ppo(env_id, timesteps=timesteps, seed=seed))
        except Exception as exc:  # a failing row is reported, not fatal
            rows.append(not_measured(env_id, "SB3 PPO", f"error: {_one_line(exc)}"))
    return rows, []


def format_training_table(rows: Sequence[Measurement]) -> str:
    """PPO timesteps/s per environment and the ratio to PPO on CartPole-v1 in the same run."""
    cartpole = _reference(rows, CARTPOLE, vector=False)
    lines = [
        "| name | setting | timesteps/s | vs PPO on CartPole | target | meets target |",
        "| --- | --- | ---: | ---: | --- | --- |",
    ]
    for row in rows:
        ratio = _ratio(row, cartpole)
        target = TRAINING_TARGETS.get(row.name)
        meets = "" if target is None or ratio is None else ("yes" if ratio >= target else "no")
        cells = [row.name, row.setting, _fmt_rate(row.steps_per_second), _fmt_ratio(ratio)]
        cells += ["" if target is None else f">= {target:g}x PPO on CartPole", meets]
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return "\n".join(lines)


# ----------------------------------------------------------------------------------------------- formatting


def _reference(rows: Iterable[Measurement], name: str, vector: bool) -> Measurement | None:
    for row in rows:
        if row.name == name and row.vector == vector and row.ok:
            return row
    return None


def _ratio(row: Measurement, peer: Measurement | None) -> float | None:
    if peer is None or not row.ok:
        return None
    return row.steps_per_second / peer.steps_per_second


def _fmt_rate(value: float) -> str:
    return f"{value:,.0f}" if math.isfinite(value) else "—"


def _fmt_us(value: float) -> str:
    if not math.isfinite(value):
        return "—"
    for limit, digits in ((100, 0), (10, 1), (1, 2)):
        if value >= limit:
            return f"{value:.{digits}f}"
    return f"{value:.3f}"


def _fmt_ratio(value: float | None) -> str:
    if value is None:
        return ""
    for limit, digits in ((100, 0), (10, 1), (0.01, 2)):
        if value >= limit:
            return f"{value:.{digits}f}x"
    return f"{value:.4f}x"


def _meets(target: Target, row: Measurement, vs_cartpole: float | None, vs_minigrid: float | None) -> str:
    """'yes' when every check that could be made passes; blank when the row or its CartPole peer is missing."""
    if vs_cartpole is None:
        return ""
    checks = [vs_cartpole >= target.vs_cartpole]
    if target.vs_minigrid is not None and vs_minigrid is not None:
        checks.append(vs_minigrid >= target.vs_minigrid)
    if target.max_memory_mb is not None and row.peak_memory_mb is not None:
        checks.append(row.peak_memory_mb < target.max_memory_mb)
    return "yes" if all(checks) else "no"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def format_table(rows: Sequence[Measurement]) -> str:
    """The rows as a Markdown table, with ratios to the peers measured in the same run."""
    cartpole = _reference(rows, CARTPOLE, vector=False)
    cartpole_vector = _reference(rows, CARTPOLE, vector=True)
    minigrid = _reference(rows, MINIGRID, vector=False)
    header = (
        "| name | setting | steps/s | µs/step | vs CartPole | vs MiniGrid | peak MB | target | meets target | note |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | --- | --- | --- |",
    )
    lines = list(header)
    for row in rows:
        vs_cartpole = _ratio(row, cartpole_vector if row.vector else cartpole)
        vs_minigrid = None if row.vector else _ratio(row, minigrid)
        target = target_for(row.name, row.vector)
        cells = [
            row.name,
            row.setting,
            _fmt_rate(row.steps_per_second),
            _fmt_us(row.us_per_step),
            _fmt_ratio(vs_cartpole),
            _fmt_ratio(vs_minigrid),
            "" if row.peak_memory_mb is None else f"{row.peak_memory_mb:.2f}",
            "" if target is None else target.describe(row.vector),
            "" if target is None else _meets(target, row, vs_cartpole, vs_minigrid),
            row.note,
        ]
        lines.append("| " + " | ".join(_cell(cell) for cell in cells) + " |")
    return "\n".join(lines)


def format_notes(notes: Sequence[str]) -> str:
    """General notes (missing registry, no vector env yet) as a Markdown list, or an empty string."""
    return "\n".join(f"- {note}" for note in notes)


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _versions() -> str:
    names = ("numpy", "gymnasium", "minigrid", "mujoco", "pettingzoo", "mpe2", "vmas", "torch", "numba")
    found = []
    for name in names:
        try:
            found.append(f"{name} {importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            continue
    return ", ".join(found)


def format_report(
    rows: Sequence[Measurement],
    notes: Sequence[str],
    *,
    min_seconds: float,
    repeats: int,
    quick: bool,
    command: str,
    date: datetime | None = None,
    training: Sequence[Measurement] = (),
) -> str:
    """The whole THROUGHPUT.md: how the numbers were made, the machine, the table and the notes."""
    date = date or datetime.now(UTC)
    plural = "" if repeats == 1 else "s"
    mode = " **Quick mode**: too short to be more than a smoke test." if quick else ""
    preamble = f"""# Throughput

Written by `{command}` on {date:%Y-%m-%d %H:%M} UTC; rerun it rather than editing this file.{mode}

How the numbers were made:

- Each figure is the median of {repeats} repeat{plural} of at least {min_seconds:g} s, all rows in one process run.
- Random actions from each environment's own action space (seeded), pre-sampled in blocks before each repeat so that
  sampling stays outside the timed loop; resets on terminated or truncated are included in the timing (vector envs
  reset themselves). An untimed warm-up (JIT compilation, lazy setup) comes first.
- µs/step is 1e6 / steps/s. Vector rows count env-steps: vector steps x the number of envs.
- Compare ratios, not absolute figures: these machines are shared and drift by up to 25% between runs. "vs CartPole"
  is the ratio to `CartPole-v1` via `gym.make` for single-env rows, to CartPole's native vector env
  ({VECTOR_NUM_ENVS} envs) for vector rows; "vs MiniGrid" is the ratio to `{MINIGRID}`.
- Peak MB: the peak of tracemalloc-traced allocations while building the env, resetting it and taking
  {_MEMORY_STEPS_SINGLE} steps ({_MEMORY_STEPS_VECTOR} for vector envs), in a separate untimed run after the imports.
  Memory allocated outside Python's allocator (MuJoCo's, torch's) is not seen.
- Targets are those of the performance spec; "meets target" checks every ratio and memory budget that could be
  measured in this run.

Machine: {platform.platform()}, {_cpu_model()}, {os.cpu_count()} CPUs; Python {platform.python_version()};
{_versions()}.

"""
    text = preamble + format_table(rows) + "\n"
    if training:
        text += (
            "\n## Training speed\n\nPPO timesteps per second (rollouts and gradient epochs, after a 512-step warm-up),"
            " against PPO on CartPole-v1 in the same run: the environment should never be the bottleneck.\n\n"
        )
        text += format_training_table(training) + "\n"
    if notes:
        text += "\nNotes:\n\n" + format_notes(notes) + "\n"
    return text


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same directory, so readers never see half."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as tmp:
            tmp.write(text)
            tmp.flush()
            os.fsync(tmp.fileno())
        os.replace(tmp_name, path)
    except BaseException:
        Path(tmp_name).unlink(missing_ok=True)
        raise


# --------------------------------------------------------------------------------------------- command line


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.throughput",
        description="Measure polyenvs environments against peer environments and write benchmarks/THROUGHPUT.md.",
    )
    parser.add_argument("--quick", action="store_true", help="0.3 s x 1 repeat per row instead of 2 s x 3")
    parser.add_argument("--only", metavar="SUBSTRING", help="only our envs whose id contains SUBSTRING (peers always)")
    parser.add_argument("--no-write", action="store_true", help="print the table without writing the report")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help=f"report path (default: {DEFAULT_OUTPUT})")
    parser.add_argument("--no-training", action="store_true", help="skip the PPO training-speed rows")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the Markdown table and write the report; return the exit status."""
    args = _parser().parse_args(argv)
    min_seconds, repeats = (0.3, 1) if args.quick else (2.0, 3)
    try:
        rows, notes = run(min_seconds=min_seconds, repeats=repeats, only=args.only)
        training: list[Measurement] = []
        if not args.no_training:
            env_ids = [r.name for r in rows if r.name.startswith("polyenvs/") and not r.vector]
            training, training_notes = measure_training(env_ids, timesteps=1024 if args.quick else 4096)
            notes = list(notes) + training_notes
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130

    print(format_table(rows))
    if training:
        print()
        print(format_training_table(training))
    if notes:
        print()
        print(format_notes(notes))

    if not args.no_write:
        command = " ".join(["python -m benchmarks.throughput", *(sys.argv[1:] if argv is None else argv)])
        report = format_report(
            rows, notes, min_seconds=min_seconds, repeats=repeats, quick=args.quick, command=command, training=training
        )
        try:
            write_atomically(args.output, report)
        except OSError as exc:
            print(f"error: could not write {args.output}: {exc.strerror or exc}", file=sys.stderr)
            return 1
        print(f"\nwrote {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    if not __package__:
        # Run as a script (python benchmarks/throughput.py): make the repo root importable for polyenvs.
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    raise SystemExit(main())
