"""Helpers shared by the command-line tests."""

from __future__ import annotations

from polyenvs.cli import main

#: A PPO config small enough to train in seconds (WallFollow, 256 timesteps), for the interrupted-run tests.
TINY_PPO_CONFIG = """\
polyenvs/BuckybotWallFollow-v0:
  n_envs: 2
  n_timesteps: 256
  policy: 'MlpPolicy'
  normalize: true
  n_steps: 64
  batch_size: 64
  n_epochs: 1
  policy_kwargs: "dict(net_arch=[16])"
"""


def run_main(args: list[str], capsys) -> tuple[int, str, str]:
    """``main(args)`` in this process: (exit code, stdout, stderr), argparse's exits included."""
    try:
        code = main(args)
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err
