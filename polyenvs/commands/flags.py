"""What every subcommand shares: its flags' parsers, one-line errors and the progress bar.

A number flag goes through :func:`int_flag` / :func:`float_flag` (``1000``, ``1_000``, ``1e3`` alike), a JSON
object flag through :func:`parse_json_object`; a bad value raises :class:`~polyenvs.errors.InputError` (or
:class:`CliError`), which ``polyenvs.cli`` prints as one line and exit status 2.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from decimal import Decimal, InvalidOperation
from pathlib import Path

from polyenvs.errors import InputError
from polyenvs.errors import shown as _shown
from polyenvs.files import check_writable_directory

__all__ = [
    "CliError",
    "ProgressBar",
    "add_progress_flag",
    "check_output_file",
    "float_flag",
    "int_flag",
    "is_terminal",
    "parse_json_object",
]


class CliError(Exception):
    """An error the user can fix: printed as one line, no traceback."""


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


def is_terminal(stream) -> bool:
    """Whether ``stream`` is an interactive terminal (progress bars are drawn only there)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


#: What a number flag may look like: Python's decimal literals (``1000``, ``1_000``, ``1e3``, ``2.5e3``, ``.5``).
_NUMBER = re.compile(r"[+-]?(?:\d(?:_?\d)*(?:\.(?:\d(?:_?\d)*)?)?|\.\d(?:_?\d)*)(?:[eE][+-]?\d(?:_?\d)*)?", re.ASCII)


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


def add_episode_flags(parser) -> None:
    """The flags of a command that runs a policy's seeded episodes: ``--episodes``, ``--seed``, ``--env-kwargs`` and
    ``--policy-kwargs`` (``evaluate``, ``collect``); :func:`episode_flags` checks them."""
    from polyenvs.limits import MAX_EPISODES, MAX_SEED

    parser.add_argument("--episodes", default="10", help=f"number of episodes, 1 to {MAX_EPISODES} (default 10)")
    parser.add_argument(
        "--seed", default="0", help=f"first seed, 0 to {MAX_SEED}; episodes use seed, seed+1, ... (default 0)"
    )
    parser.add_argument("--env-kwargs", default="{}", help="JSON object of environment keyword arguments")
    parser.add_argument("--policy-kwargs", default="{}", help="JSON object of baseline parameters")


def episode_flags(args: argparse.Namespace) -> tuple[int, int, dict, dict]:
    """``(episodes, seed, env_kwargs, policy_kwargs)`` from the flags :func:`add_episode_flags` added, checked."""
    from polyenvs.limits import MAX_EPISODES, MAX_SEED

    return (
        int_flag("--episodes", args.episodes, 1, MAX_EPISODES),
        int_flag("--seed", args.seed, 0, MAX_SEED),
        parse_json_object(args.env_kwargs, "--env-kwargs"),
        parse_json_object(args.policy_kwargs, "--policy-kwargs"),
    )


def add_progress_flag(parser) -> None:
    """``--progress`` / ``--no-progress`` on an ``argparse`` parser (default ``None``: when stderr is a terminal)."""
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show a progress bar (default: when stderr is a terminal)",
    )


def check_output_file(path: Path, flag: str) -> None:
    """``path`` can be written as a file (it is not a directory, and its folder can be created); else one line."""
    path = Path(path)
    if path.is_dir():
        raise CliError(f"{flag} {path}: is a directory; give a file name")
    check_writable_directory(path.parent, flag, shown=path)


class ProgressBar:
    """A one-line progress bar on stderr, drawn only when stderr is a terminal (so logs and pipes stay clean).

    ``start(total)`` sets the amount of work, ``advance()`` counts one unit, ``message(text)`` prints a line above
    the bar, ``close()`` ends it. Messages are printed whether or not the bar is drawn.
    """

    def __init__(self, unit: str = "episodes", stream=None, enabled: bool | None = None, width: int = 30):
        self.stream = sys.stderr if stream is None else stream
        self.enabled = is_terminal(self.stream) if enabled is None else enabled
        self.unit, self.width = unit, width
        self.total, self.done, self.label = 0, 0, ""
        self._start = time.monotonic()
        self._drawn = False

    def start(self, total: int, label: str = "", draw: bool = True) -> None:
        """Set the amount of work; with ``draw=False`` the bar first appears at the first ``advance()``."""
        self.total, self.done, self.label = int(total), 0, label
        self._start = time.monotonic()
        if draw:
            self._draw()

    def advance(self, n: int = 1) -> None:
        self.done += n
        self._draw()

    def message(self, text: str) -> None:
        if self._drawn:
            self.stream.write("\r\x1b[K")
        print(text, file=self.stream)
        self._draw()

    def close(self) -> None:
        if self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False

    def render(self) -> str:
        frac = min(self.done / self.total, 1.0) if self.total else 1.0
        filled = round(self.width * frac)
        elapsed = time.monotonic() - self._start
        eta = f", ~{elapsed * (self.total - self.done) / self.done:.0f}s left" if 0 < self.done < self.total else ""
        label = f"{self.label} " if self.label else ""
        bar = "#" * filled + "." * (self.width - filled)
        return f"{label}[{bar}] {self.done}/{self.total} {self.unit} ({elapsed:.0f}s{eta})"

    def _draw(self) -> None:
        if not self.enabled or self.total <= 0:
            return
        self.stream.write("\r" + self.render() + "\x1b[K")
        self.stream.flush()
        self._drawn = True
