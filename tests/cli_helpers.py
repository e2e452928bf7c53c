"""Helpers shared by the command-line tests."""

from __future__ import annotations

from polyenvs.cli import main


def run_main(args: list[str], capsys) -> tuple[int, str, str]:
    """``main(args)`` in this process: (exit code, stdout, stderr), argparse's exits included."""
    try:
        code = main(args)
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err
