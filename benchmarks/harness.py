"""Timing step loops in interleaved rounds, peak memory, and the ``Measurement`` row.

Load on these shared machines drifts by up to 25% within a run, so rows are not measured one after another:
:func:`measure_rounds` times every row once per round (peers and ours alternating, in the order given, reversed every
other round), takes each row's median over the rounds, and keeps the per-round rates so that a ratio can be the
median of per-round ratios against the peer timed in the same round (:func:`paired_ratio`).

What is timed is a :class:`Runner`: :class:`EnvRunner` steps a Gymnasium ``Env`` or ``VectorEnv`` with pre-sampled
random actions (``benchmarks.training`` has one for PPO). Nothing here knows the peers or the targets.
"""

from __future__ import annotations

import itertools
import math
import statistics
import sys
import time
import tracemalloc
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

__all__ = [
    "Case",
    "EnvRunner",
    "Measurement",
    "Runner",
    "env_case",
    "measure_env_steps",
    "measure_rounds",
    "not_measured",
    "one_line",
    "paired_ratio",
    "peak_memory_mb",
    "progress",
    "run_steps",
    "serpentine",
]

# Pre-sampled actions per repeat, counted in single-env actions, so a batched action of 1024 counts 1024.
_ACTION_BLOCK = 10_000
# The timed loop reads the clock about this often; often enough that a slow env does not overshoot by much,
# rarely enough that reading the clock costs nothing next to a ~9 µs CartPole step.
_CHECK_INTERVAL_S = 0.01
_WARMUP_SECONDS = 0.1
_WARMUP_MAX_STEPS = 200
#: Random steps taken in the untimed memory run, after building and resetting the env.
MEMORY_STEPS_SINGLE = 100
MEMORY_STEPS_VECTOR = 10

Clock = Callable[[], float]

# Each call of measure_rounds gets its own number, so that only rows timed in the same rounds are paired.
_sessions = itertools.count(1)


@dataclass
class Measurement:
    """One row of a table; rows that were skipped or failed have NaN rates and say why in ``note``.

    ``per_repeat`` holds the rate of each round; rows with the same ``session`` were timed in the same rounds, so
    their ratio is taken round by round (:func:`paired_ratio`).
    """

    name: str
    setting: str
    steps_per_second: float
    us_per_step: float
    peak_memory_mb: float | None
    note: str = ""
    num_envs: int = 1
    vector: bool = False
    per_repeat: tuple[float, ...] = field(default_factory=tuple)
    session: int | None = None

    @property
    def ok(self) -> bool:
        """Whether the row holds a real rate."""
        return math.isfinite(self.steps_per_second) and self.steps_per_second > 0


def not_measured(name: str, setting: str, note: str, *, vector: bool = False) -> Measurement:
    """A row for a peer or env that was skipped or failed, so it is listed rather than dropped."""
    return Measurement(name, setting, math.nan, math.nan, None, note, vector=vector)


def paired_ratio(row: Measurement, peer: Measurement | None) -> float | None:
    """``row``'s rate over ``peer``'s: the median of per-round ratios when both were timed in the same rounds.

    Rows from different runs (or a ``peer`` of ``None``, or a failed row) fall back to the ratio of the medians, or
    ``None``.
    """
    if peer is None or not row.ok or not peer.ok:
        return None
    same_rounds = (
        row.session is not None
        and row.session == peer.session
        and len(row.per_repeat) == len(peer.per_repeat) > 0
        and all(rate > 0 for rate in peer.per_repeat)
    )
    if same_rounds:
        return statistics.median(mine / theirs for mine, theirs in zip(row.per_repeat, peer.per_repeat, strict=True))
    return row.steps_per_second / peer.steps_per_second


# ------------------------------------------------------------------------------------------------ runners


class Runner(Protocol):
    """Something that can be timed repeatedly: built, warmed up once, then one ``timed_repeat`` per round."""

    num_envs: int
    vector: bool

    def warm_up(self) -> None: ...

    def timed_repeat(self) -> float:
        """Time one repeat and return its rate (env-steps, timesteps, ... per second)."""
        ...

    def close(self) -> None: ...


def _num_envs(env: Any) -> tuple[int, bool]:
    """How many envs one ``step`` advances, and whether ``env`` is batched (and so resets itself)."""
    num_envs = getattr(env, "num_envs", None)
    if num_envs is not None:
        return int(num_envs), True
    return 1, False


def run_steps(env: Any, actions: Sequence[Any], vector: bool) -> None:
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


class EnvRunner:
    """Steps ``make_fn()`` with random actions from its own seeded action space.

    A Gymnasium ``Env`` is reset on terminated or truncated inside the timing; anything with ``num_envs`` (a
    ``VectorEnv``, a batched adapter) is assumed to reset itself, and its rate counts env-steps (vector steps x
    ``num_envs``). Actions are pre-sampled before each repeat, so sampling stays outside the timed loop.
    """

    def __init__(
        self, make_fn: Callable[[], Any], *, min_seconds: float, seed: int = 0, clock: Clock = time.perf_counter
    ) -> None:
        if min_seconds <= 0:
            raise ValueError(f"min_seconds must be > 0, got {min_seconds}")
        self.min_seconds = min_seconds
        self.clock = clock
        self.env = make_fn()
        self.num_envs, self.vector = _num_envs(self.env)
        self.env.reset(seed=seed)
        self.env.action_space.seed(seed)
        self.check_every = 1
        self.block = 1

    def warm_up(self) -> None:
        """Untimed steps (numba compilation, caches, lazy setup), and a step-time estimate to size the loop."""
        env, sample, clock = self.env, self.env.action_space.sample, self.clock
        # The first step may compile or allocate lazily; keep it out of the estimate.
        run_steps(env, [sample()], self.vector)
        steps, elapsed, start = 0, 0.0, clock()
        while steps < _WARMUP_MAX_STEPS and elapsed < _WARMUP_SECONDS:
            run_steps(env, [sample()], self.vector)
            steps += 1
            elapsed = clock() - start
        step_seconds = elapsed / max(steps, 1)
        self.check_every = max(1, min(1024, int(_CHECK_INTERVAL_S / max(step_seconds, 1e-9))))
        self.block = max(self.check_every, _ACTION_BLOCK // self.num_envs)

    def timed_repeat(self) -> float:
        """Step for at least ``min_seconds``, cycling through a fresh block of actions; return env-steps/s."""
        sample = self.env.action_space.sample
        actions = [sample() for _ in range(self.block)]
        chunks = [actions[i : i + self.check_every] for i in range(0, len(actions), self.check_every)]
        env, vector, clock, min_seconds = self.env, self.vector, self.clock, self.min_seconds
        steps = 0
        start = clock()
        while True:
            for chunk in chunks:
                run_steps(env, chunk, vector)
                steps += len(chunk)
                elapsed = clock() - start
                if elapsed >= min_seconds:
                    return steps * self.num_envs / elapsed

    def close(self) -> None:
        self.env.close()


def peak_memory_mb(make_fn: Callable[[], Any], *, steps: int | None = None, seed: int = 0) -> float:
    """Peak traced allocations (MB) while building ``make_fn()``, resetting it and taking ``steps`` random steps.

    Run this after the env's modules are imported, so imports are not counted, and apart from any timing, since
    tracemalloc slows steps. Allocations outside Python's allocator (MuJoCo's, torch's) are not seen.
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
            steps = MEMORY_STEPS_VECTOR if vector else MEMORY_STEPS_SINGLE
        run_steps(env, [env.action_space.sample() for _ in range(steps)], vector)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        if env is not None:
            env.close()
        if not was_tracing:
            tracemalloc.stop()
    return max(peak - baseline, 0) / 1e6


# -------------------------------------------------------------------------------------------------- rounds


@dataclass
class Case:
    """A row to measure: how to build its runner, and optionally how to measure its memory.

    ``skip`` (a note such as "skipped: mujoco not installed") lists the row without timing it. ``describe`` turns
    the finished measurement into a note (agent-steps/s, µs per vector step) when the row has no note of its own.
    """

    name: str
    setting: str
    start: Callable[[], Runner] | None = None
    memory: Callable[[], float] | None = None
    vector: bool = False
    note: str = ""
    skip: str = ""
    describe: Callable[[Measurement], str] | None = None

    @property
    def label(self) -> str:
        return f"{self.name} [{self.setting}]"


def env_case(
    name: str,
    setting: str,
    make_fn: Callable[[], Any],
    *,
    min_seconds: float,
    seed: int = 0,
    vector: bool = False,
    measure_memory: bool = True,
    clock: Clock = time.perf_counter,
) -> Case:
    """A case stepping ``make_fn()`` with :class:`EnvRunner`, with its memory measured by :func:`peak_memory_mb`;
    its note gives the time per vector step (``dataclasses.replace`` the case's ``describe`` for another)."""
    return Case(
        name,
        setting,
        start=lambda: EnvRunner(make_fn, min_seconds=min_seconds, seed=seed, clock=clock),
        memory=(lambda: peak_memory_mb(make_fn, seed=seed)) if measure_memory else None,
        vector=vector,
        describe=_vector_step_note,
    )


def _vector_step_note(row: Measurement) -> str:
    if not row.vector:
        return ""
    return f"{row.num_envs} envs; {1e6 * row.num_envs / row.steps_per_second:,.0f} µs per vector step"


def serpentine(count: int, round_index: int) -> list[int]:
    """The order of the rows in a round: as given in even rounds, reversed in odd ones.

    Reversing every other round keeps peers and ours alternating, while no row is always timed early or late in a
    round (a drift within a round then biases a ratio one way in one round and the other way in the next).
    """
    order = list(range(count))
    return order if round_index % 2 == 0 else order[::-1]


def measure_rounds(
    cases: Sequence[Case],
    *,
    repeats: int,
    on_repeat: Callable[[int, Case, float], None] | None = None,
) -> list[Measurement]:
    """Time every case once per round for ``repeats`` rounds; return one row per case, in the order given.

    Every runner is built and warmed up first; then each round times the cases in :func:`serpentine` order, so the
    order given should alternate peers and ours. A row's rate is its median over the rounds, ``per_repeat`` keeps
    each round's rate for :func:`paired_ratio`. Memory is measured last, in separate untimed runs. A case that
    fails is reported as a row with a one-line error, and the others go on. ``on_repeat(round, case, rate)`` is
    called after each timed repeat.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    session = next(_sessions)
    timing = _Timing()
    try:
        _warm_up(cases, timing)
        for round_index in range(repeats):
            progress(f"round {round_index + 1}/{repeats} ...")
            _time_round(cases, round_index, timing, on_repeat)
    finally:
        shape = {index: (runner.num_envs, runner.vector) for index, runner in timing.runners.items()}
        for runner in timing.runners.values():
            _close_quietly(runner)
    errors, rates = timing.errors, timing.rates

    rows = []
    for index, case in enumerate(cases):
        if case.skip:
            rows.append(not_measured(case.name, case.setting, case.skip, vector=case.vector))
        elif index in errors or index not in shape:
            rows.append(not_measured(case.name, case.setting, errors.get(index, "not measured"), vector=case.vector))
        else:
            rows.append(_finished_row(case, rates[index], shape[index], session))
    return rows


@dataclass
class _Timing:
    """The rounds so far, by index into the cases: each timed case's runner and rates, and the failures."""

    runners: dict[int, Runner] = field(default_factory=dict)
    errors: dict[int, str] = field(default_factory=dict)
    rates: dict[int, list[float]] = field(default_factory=dict)


def _warm_up(cases: Sequence[Case], timing: _Timing) -> None:
    """Build and warm up the runner of every case to time (a failure is noted in ``timing.errors``)."""
    for index, case in enumerate(cases):
        if case.skip or case.start is None:
            continue
        progress(f"warming up {case.label} ...")
        runner = None
        try:
            runner = case.start()
            runner.warm_up()
        except Exception as exc:  # noqa: BLE001 - a broken env must not stop the other rows
            timing.errors[index] = f"error: {one_line(exc)}"
            progress(f"  failed: {one_line(exc)}")
            if runner is not None:
                _close_quietly(runner)
            continue
        timing.runners[index] = runner
        timing.rates[index] = []


def _time_round(cases: Sequence[Case], round_index: int, timing: _Timing, on_repeat) -> None:
    """One timed repeat of every runner in :func:`serpentine` order; a runner that fails is closed and dropped."""
    for index in serpentine(len(cases), round_index):
        runner = timing.runners.get(index)
        if runner is None:
            continue
        try:
            rate = runner.timed_repeat()
        except Exception as exc:  # noqa: BLE001
            timing.errors[index] = f"error in round {round_index + 1}: {one_line(exc)}"
            progress(f"  {cases[index].label} failed: {one_line(exc)}")
            _close_quietly(timing.runners.pop(index))
            continue
        timing.rates[index].append(rate)
        if on_repeat is not None:
            on_repeat(round_index, cases[index], rate)


def _finished_row(case: Case, rates: list[float], shape: tuple[int, bool], session: int) -> Measurement:
    num_envs, vector = shape
    rate = statistics.median(rates)
    row = Measurement(
        name=case.name,
        setting=case.setting,
        steps_per_second=rate,
        us_per_step=1e6 / rate,
        peak_memory_mb=None,
        note=case.note,
        num_envs=num_envs,
        vector=vector,
        per_repeat=tuple(rates),
        session=session,
    )
    if case.memory is not None:
        try:
            row.peak_memory_mb = case.memory()
        except Exception as exc:  # noqa: BLE001
            row.note = "; ".join(filter(None, [row.note, f"memory run failed: {one_line(exc)}"]))
    if not row.note and case.describe is not None:
        row.note = case.describe(row)
    return row


def _close_quietly(runner: Runner) -> None:
    try:
        runner.close()
    except Exception:  # noqa: BLE001 - closing must not hide the measurement
        pass


def measure_env_steps(
    make_fn: Callable[[], Any],
    *,
    min_seconds: float = 2.0,
    repeats: int = 3,
    seed: int = 0,
    name: str = "env",
    setting: str = "",
    measure_memory: bool = True,
) -> Measurement:
    """One env on its own: median steps/s over ``repeats`` runs of at least ``min_seconds``, and peak memory.

    For ratios, put the env and its peer in one :func:`measure_rounds` call instead, so they share rounds.
    """
    case = env_case(name, setting, make_fn, min_seconds=min_seconds, seed=seed, measure_memory=measure_memory)
    (row,) = measure_rounds([case], repeats=repeats)
    if not row.ok:
        raise RuntimeError(f"{name}: {row.note}")
    return row


def one_line(exc: BaseException) -> str:
    """An exception as one line: its type and the first line of its message."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def progress(message: str) -> None:
    """Progress goes to stderr, so that stdout stays a clean Markdown table."""
    print(message, file=sys.stderr, flush=True)
