"""The ``polyenvs`` command line: list environments, evaluate policies, build the leaderboard, record episodes.

Every ``--policy`` takes a baseline name or a trained model's path alike (a training directory or a ``.zip``).
Expected failures (a bad flag value, an unknown id or policy, bad JSON or keyword arguments, a missing, corrupt or
mismatched model, an output path that cannot be written) print one line on stderr and exit 2, before any
evaluation runs. Anything else is a bug and shows its traceback.

Each subcommand is a module of :mod:`polyenvs.commands` (``add_parser``, ``run``); this module only assembles them
and maps their errors to one line and an exit status.
"""

from __future__ import annotations

import argparse
import sys

from polyenvs import __version__
from polyenvs.commands import collect, evaluate, leaderboard, localize, record, sweep, train
from polyenvs.commands import list as list_command
from polyenvs.commands.flags import CliError
from polyenvs.errors import InputError

__all__ = ["build_parser", "main"]

#: The subcommands, in the order ``polyenvs --help`` lists them (each imports nothing heavy until it runs).
COMMANDS = (train, sweep, localize, list_command, evaluate, leaderboard, record, collect)


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
        return args.func(args)
    except (CliError, InputError) as exc:
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


if __name__ == "__main__":
    raise SystemExit(main())
