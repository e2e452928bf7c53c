"""Evaluate a policy on an environment over fixed seeds, and write results atomically.

The same seeds for every policy make comparisons paired; per-episode returns and task metrics (from
``info["episode_metrics"]``) are kept so a leaderboard can compute any statistic later.

Conventions every command and family inherits from here: user input that cannot work raises ``InputError`` (a
``ValueError``) before any episode runs (a trained model's path is checked against the environment then too);
policies whose ``predict`` takes ``action_masks`` (MaskablePPO models) get ``info["action_mask"]`` at every step,
others never see it; every result file is written through ``atomic_path`` (a hidden,
gitignored temp file in the same folder, renamed into place, with the usual file mode), so an interrupted run
never leaves a half-written file under its real name.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import tempfile
from collections.abc import Callable, Iterator
from decimal import Decimal, InvalidOperation
from numbers import Integral
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from polyenvs.rollout import policy_action, run_episode

__all__ = [
    "InputError",
    "add_progress_flag",
    "atomic_path",
    "check_count",
    "check_writable_directory",
    "evaluate",
    "float_flag",
    "int_flag",
    "interquartile_mean",
    "iqm_with_ci",
    "is_terminal",
    "iqm_with_stratified_ci",
    "make_agent",
    "make_env",
    "parse_json_object",
    "policy_action",
    "temp_path_for",
    "write_json_atomic",
    "write_text_atomic",
]


class InputError(ValueError):
    """A bad argument from the caller (unknown id or policy, bad keyword arguments, seeds, counts).

    Distinct from a ``ValueError`` raised while an environment runs, which is a bug: the command line prints an
    ``InputError`` as one line and lets anything else show its traceback.
    """


def parse_json_object(text: str, name: str) -> dict:
    """A command-line flag's JSON object (``--env-kwargs``, ``--policy-kwargs``); else an :class:`InputError`."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{name} is not valid JSON: {exc.msg} (got {_shown(text)!r})") from None
    except ValueError as exc:  # an integer past Python's 4300-digit limit for reading one
        raise InputError(f"{name}: {str(exc).split(';')[0]}") from None
    if not isinstance(value, dict):
        raise InputError(f"{name} must be a JSON object, got {text!r}")
    return value


def check_writable_directory(directory: Path, flag: str, shown: Path | None = None) -> None:
    """``directory`` exists and we can create files in it, or it can be created: else an :class:`InputError`.

    Creates nothing: a non-existent directory is judged by its nearest existing ancestor, and writability by
    creating (and at once deleting) an anonymous file, which also works where permission bits do not tell
    (root, read-only or virtual file systems such as /proc).
    """
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise InputError(f"{flag} {shown or directory}: {directory} is not a directory")
    existing = directory.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(f"{flag} {shown or directory}: cannot create {directory}: {existing} is not a directory")
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as exc:
        raise InputError(f"{flag} {shown or directory}: cannot write in {existing}: {exc.strerror or exc}") from None


def is_terminal(stream) -> bool:
    """Whether ``stream`` is an interactive terminal (progress bars are drawn only there)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


#: Upper limits of the command line's numbers: far above any real use, low enough that a slip of the keyboard
#: (``--episodes 99999999999``) is refused at once instead of running for ever or filling the memory.
MAX_SEED = 2**32 - 1  # numpy's legacy seeding, which Stable-Baselines3 uses, takes no more
MAX_EPISODES = 100_000
MAX_TIMESTEPS = 10**10
MAX_N_ENVS = 1024
MAX_JOBS = 1024
MAX_STEPS = 100_000  # steps of one recorded episode (the longest registered episode is 8000 steps)
MAX_FRAMES = 3_000  # frames a recording holds in memory (up to 2 MB each)
MAX_RUNS = 10_000
MAX_BUMPS = 1_000
MAX_PARTICLES = 1_000_000
MAX_EPISODE_STEPS = 1_000_000  # an ``--env-kwargs`` max_episode_steps (what gym.make's TimeLimit takes)


#: What a number flag may look like: Python's decimal literals (``1000``, ``1_000``, ``1e3``, ``2.5e3``, ``.5``).
_NUMBER = re.compile(r"[+-]?(?:\d(?:_?\d)*(?:\.(?:\d(?:_?\d)*)?)?|\.\d(?:_?\d)*)(?:[eE][+-]?\d(?:_?\d)*)?", re.ASCII)


def _shown(text) -> str:
    text = str(text).strip()
    return text if len(text) <= 40 else f"{text[:12]}...{text[-12:]} ({len(text)} characters)"


def _flag_number(flag: str, text, kind: str) -> Decimal:
    stripped = str(text).strip()
    if stripped.lower().lstrip("+-") in ("inf", "infinity", "nan"):
        raise InputError(f"{flag} must be a finite number, got {_shown(text)!r}")
    if not _NUMBER.fullmatch(stripped):
        raise InputError(f"{flag} must be {kind}, got {_shown(text)!r}")
    literal = stripped.replace("_", "")
    try:
        return Decimal(literal)  # exact, however long
    except InvalidOperation:  # an exponent beyond Decimal's own (1e99999999999999999999): as large or small
        mantissa, _, exponent = literal.lower().partition("e")
        if Decimal(mantissa) == 0:
            return Decimal(0)
        sign = "-" if mantissa.startswith("-") else ""
        return Decimal(f"{sign}1e{'-' if exponent.startswith('-') else ''}999999")


def int_flag(flag: str, text: str | None, minimum: int, maximum: int) -> int | None:
    """The integer of a command-line flag, ``minimum <= value <= maximum``; ``None`` stays ``None``.

    The one parser of every command's integer flags: ``1000``, ``1_000``, ``1e3`` and ``1000.0`` all read as
    1000 (exactly: no float rounding); anything else raises :class:`InputError` naming the flag.
    """
    if text is None:
        return None
    number = _flag_number(flag, text, "an integer")
    if number < minimum:
        raise InputError(f"{flag} must be >= {minimum}, got {_shown(text)}")
    if number > maximum:
        raise InputError(f"{flag} must be <= {maximum}, got {_shown(text)}")
    if number != number.to_integral_value():
        raise InputError(f"{flag} must be an integer, got {_shown(text)!r}")
    return int(number)


def float_flag(flag: str, text: str | None, minimum: float, maximum: float) -> float | None:
    """The number of a command-line flag, ``minimum <= value <= maximum`` (same formats as :func:`int_flag`)."""
    if text is None:
        return None
    number = _flag_number(flag, text, "a number")
    if not Decimal(str(minimum)) <= number <= Decimal(str(maximum)):
        raise InputError(f"{flag} must be between {minimum:g} and {maximum:g}, got {_shown(text)}")
    return float(number)


def add_progress_flag(parser) -> None:
    """``--progress`` / ``--no-progress`` on an ``argparse`` parser (default ``None``: when stderr is a terminal)."""
    import argparse

    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show a progress bar (default: when stderr is a terminal)",
    )


def check_count(name: str, value, minimum: int, maximum: int | None = None) -> int:
    """An integer (not a bool, float or string) in ``[minimum, maximum]``; raises :class:`InputError`.

    For values given in Python; the command line's flags go through :func:`int_flag`."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, Integral):
        raise InputError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise InputError(f"{name} must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise InputError(f"{name} must be <= {maximum}, got {value}")
    return int(value)


def make_env(env_id: str, env_kwargs: dict | None = None, **extra):
    """Build a Gymnasium id or a PettingZoo module path (:func:`polyenvs.rollout.make_env`) with the user's
    ``env_kwargs``; an unknown name or a rejected keyword raises :class:`InputError`.

    ``extra`` holds the caller's own fixed arguments (``render_mode``); an error building the environment with no
    user keywords at all is not the user's doing and propagates unchanged.
    """
    from polyenvs.rollout import UnknownEnvironment
    from polyenvs.rollout import make_env as build

    env_kwargs = dict(env_kwargs or {})
    steps = env_kwargs.get("max_episode_steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, Integral)
                              or not 1 <= steps <= MAX_EPISODE_STEPS):  # fmt: skip
        raise InputError(
            f"bad environment keyword arguments for {env_id}: max_episode_steps must be an integer from 1 to "
            f"{MAX_EPISODE_STEPS}, got {_shown(repr(steps))}"
        )
    try:
        return build(env_id, env_kwargs, **extra)
    except UnknownEnvironment:
        raise InputError(
            f"unknown environment id {env_id.split(':', 1)[-1]!r} (neither a Gymnasium id nor a PettingZoo "
            "module path); run 'polyenvs list' for ours"
        ) from None
    except ModuleNotFoundError as exc:
        from polyenvs.registry import entry

        try:
            extra = entry(env_id).extra
        except KeyError:  # a user's own environment
            extra = None
        hint = f'pip install "polyenvs[{extra}]"' if extra else "see the README's Install section"
        raise InputError(f"{env_id} needs the package {exc.name!r}, which is not installed: {hint}") from exc
    except (TypeError, ValueError, gym.error.Error) as exc:
        if not env_kwargs:
            raise
        raise InputError(f"bad environment keyword arguments for {env_id}: {exc}") from exc


def make_agent(policy: str, env_id: str, env: gym.Env, seed: int | None = None, policy_kwargs: dict | None = None):
    """``baselines.make_policy`` for ``env``; an unknown policy or a rejected parameter raises :class:`InputError`.

    ``policy`` may be a trained model's path (a training directory or a ``.zip``); a missing, corrupt or mismatched
    model raises :class:`InputError` too.
    """
    from baselines import make_policy
    from polyenvs.rollout import agent_spaces

    try:
        return make_policy(policy, env_id, *agent_spaces(env), seed=seed, **dict(policy_kwargs or {}))
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc)) from exc


def evaluate(
    env_id: str,
    policy: str = "paper",
    episodes: int = 10,
    seed: int = 0,
    env_kwargs: dict | None = None,
    policy_kwargs: dict | None = None,
    on_episode: Callable[[dict], None] | None = None,
) -> dict[str, Any]:
    """Run ``policy`` for ``episodes`` episodes seeded ``seed, seed + 1, ...``.

    Returns the document ``{"env_id", "policy", "policy_description", "seeds", "episodes": [{"seed", "return",
    "length", "metrics"}], "summary"}`` where ``summary`` holds the mean of return, length and every metric.
    ``on_episode(result)`` is called after each episode (for progress bars).
    Raises :class:`InputError` (a ``ValueError``) for unknown ids, policies, bad keyword arguments, a negative
    seed or fewer than one episode, all before any episode runs.
    """
    episodes = check_count("episodes", episodes, 1)
    seed = check_count("seed", seed, 0)
    env = make_env(env_id, env_kwargs)
    env_id = env_id.split(":", 1)[-1]
    try:
        agent = make_agent(policy, env_id, env, seed=seed, policy_kwargs=policy_kwargs)
        seeds = [seed + i for i in range(episodes)]
        results = []
        for s in seeds:
            results.append(run_episode(env, agent, s))
            if on_episode is not None:
                on_episode(results[-1])
    finally:
        env.close()
    summary = {
        "return": float(np.mean([r["return"] for r in results])),
        "length": float(np.mean([r["length"] for r in results])),
    }
    for key in results[0]["metrics"]:
        summary[key] = float(np.mean([r["metrics"][key] for r in results]))
    return {
        "env_id": env_id,
        "policy": os.fspath(policy),
        "policy_description": agent.describe(),
        "env_kwargs": env_kwargs or {},
        "seeds": seeds,
        "episodes": results,
        "summary": summary,
    }


def _iqm_of_sorted(sorted_x: np.ndarray) -> np.ndarray:
    """IQM along the last axis of sorted data: the mean of the middle half, ``floor(n/4)`` cut from each end (the
    same as ``scipy.stats.trim_mean(x, 0.25)``, which rliable uses)."""
    n = sorted_x.shape[-1]
    lo, hi = int(np.floor(0.25 * n)), int(np.ceil(0.75 * n))
    return sorted_x[..., lo:hi].mean(axis=-1)


def interquartile_mean(values) -> float:
    """The interquartile mean of ``values`` (the mean of the middle 50%)."""
    x = np.sort(np.asarray(values, dtype=np.float64).ravel())
    if x.size == 0:
        raise ValueError("the IQM of no values is undefined")
    return float(_iqm_of_sorted(x))


def iqm_with_stratified_ci(
    groups, n_boot: int = 2000, seed: int = 0, confidence: float = 0.95
) -> tuple[float, float, float]:
    """IQM of all values pooled over ``groups`` (runs) and its stratified bootstrap interval (percentile method).

    Each bootstrap sample resamples every group's values with replacement within that group (its own count), as
    rliable's ``StratifiedBootstrap`` does with runs x tasks, so every run keeps its weight and the interval
    reflects the spread within runs, not the choice of which runs to keep. With one group this is the plain
    bootstrap of :func:`iqm_with_ci`. Returns ``(iqm, low, high)``.
    """
    runs = [np.sort(np.asarray(g, dtype=np.float64).ravel()) for g in groups]  # sorted: reproduces iqm_with_ci
    if not runs or any(r.size == 0 for r in runs):
        raise ValueError("every group needs at least one value")
    rng = np.random.default_rng(seed)
    boots = np.concatenate([r[rng.integers(0, r.size, size=(n_boot, r.size))] for r in runs], axis=1)
    boots.sort(axis=1)
    dist = _iqm_of_sorted(boots)
    tail = (1.0 - confidence) / 2
    point = interquartile_mean(np.concatenate(runs))
    return point, float(np.quantile(dist, tail)), float(np.quantile(dist, 1.0 - tail))


def iqm_with_ci(values, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """Interquartile mean and its 95% bootstrap confidence interval (one run: no strata)."""
    return iqm_with_stratified_ci([values], n_boot=n_boot, seed=seed)


def temp_path_for(path: str | os.PathLike, keep_suffix: bool = False) -> Path:
    """A fresh temporary name next to ``path``: ``.NAME.<random>.tmp`` (hidden, and matched by ``.gitignore``).

    With ``keep_suffix`` the name ends in ``path``'s suffix too (``.NAME.<random>.tmp.mp4``), for writers that
    choose the format from the file name (ffmpeg).
    """
    path = Path(path)
    return path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp{path.suffix if keep_suffix else ''}"


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, keep_suffix: bool = False) -> Iterator[Path]:
    """Yield a new, empty temporary file next to ``path``; rename it onto ``path`` when the block succeeds.

    The temporary file is created with the usual mode (``0o666 & ~umask``, like ``open(path, "w")``), not
    ``mkstemp``'s 0600. If the block raises (or the process is interrupted), the temporary file is removed and
    ``path`` is left as it was. The parent directory is created if needed. ``keep_suffix``: see
    :func:`temp_path_for`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        tmp = temp_path_for(path, keep_suffix)
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:  # pragma: no cover - 32 random bits collided
            continue
        os.close(fd)
        break
    try:
        yield tmp
        with open(tmp, "rb+") as fh:  # the data must be on disk before the rename makes it visible
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write a file so that a crash never leaves it half-written (temp file in the same directory + rename)."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)


def write_json_atomic(path: str | os.PathLike, document: Any) -> None:
    write_text_atomic(path, json.dumps(document, indent=1) + "\n")
