"""The ``polyenvs`` command line: list environments, evaluate policies, build the leaderboard, record episodes.

Every ``--policy`` takes a baseline name or a trained model's path alike (a training directory or a ``.zip``).
Expected failures (a bad flag value, an unknown id or policy, bad JSON or keyword arguments, a missing, corrupt or
mismatched model, an output path that cannot be written, a missing optional extra) print one line on stderr and
exit 2, before any evaluation runs. Anything else is a bug and shows its traceback.

A superseded id (a -v0 beside its -v1, kept registered for the results made with it) is named as such in one line
of our own on stderr once a command that ran on it is done (``polyenvs list`` marks it); Gymnasium's two-line "out of
date" warning is silenced while a command runs, since ``list``, ``leaderboard`` and ``localize``'s default build
such ids without the user asking.

Each subcommand is a module of :mod:`polyenvs.commands` (``add_parser``, ``run``); this module only assembles them
and maps their errors to one line and an exit status.
"""

from __future__ import annotations

import argparse
import sys

from gymnasium.error import DependencyNotInstalled

from polyenvs import __version__
from polyenvs.commands import collect, evaluate, leaderboard, localize, record, sweep, train, tune
from polyenvs.commands import list as list_command
from polyenvs.commands.flags import CliError
from polyenvs.errors import InputError
from polyenvs.evaluation.protocol import old_versions_quietly
from polyenvs.registry import bare_id, entry

__all__ = ["ID_ARGUMENTS", "build_parser", "main", "superseded_notes"]

#: The subcommands, in the order ``polyenvs --help`` lists them (each imports nothing heavy until it runs).
COMMANDS = (train, tune, sweep, localize, list_command, evaluate, leaderboard, record, collect)
#: The arguments by which the commands name environments: an id (evaluate, record, collect, train), localize's
#: ``--env`` and sweep's ``--envs``.
ID_ARGUMENTS = ("env_id", "env", "envs")


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage block), like every other error of this command line."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="polyenvs", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"polyenvs {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        with old_versions_quietly():
            code = args.func(args)
    except (CliError, InputError, DependencyNotInstalled) as exc:
        message = exc.args[0] if exc.args else str(exc)
        print(f"polyenvs {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("polyenvs: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader went away (polyenvs list | head): stop quietly, as other tools do
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error when Python flushes
        return 141
    for note in superseded_notes(args):
        print(f"polyenvs {args.command}: note: {note}", file=sys.stderr)
    return code


def superseded_notes(args: argparse.Namespace) -> list[str]:
    """One line for each superseded id among those the command ran on (:data:`ID_ARGUMENTS`)."""
    named: list[str] = []
    for name in ID_ARGUMENTS:
        value = getattr(args, name, None)
        named += value if isinstance(value, list) else [value] if value is not None else []
    notes = []
    for env_id in dict.fromkeys(bare_id(v) for v in named):
        try:
            newer = entry(env_id).superseded_by
        except KeyError:  # not one of ours (a user's Gymnasium id or module)
            continue
        if newer is not None:
            notes.append(
                f"{env_id} is superseded by {newer} (kept registered, unchanged, for the results made with it)"
            )
    return notes


if __name__ == "__main__":
    raise SystemExit(main())
