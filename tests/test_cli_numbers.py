"""Every number flag of every subcommand: one parser (the same formats everywhere) and an upper limit for each,
checked before any work (one line, exit 2)."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

import polyenvs.evaluation.episodes
import polyenvs.evaluation.localization
import polyenvs.evaluation.rollout
import polyenvs.training.sweep
import polyenvs.training.tune
from baselines.residual import MAX_HOLD
from polyenvs.cli import build_parser
from polyenvs.commands.flags import int_flag
from polyenvs.errors import InputError
from polyenvs.limits import (
    MAX_BC_EPOCHS,
    MAX_BUMPS,
    MAX_EPISODES,
    MAX_JOBS,
    MAX_N_ENVS,
    MAX_PARTICLES,
    MAX_RUNS,
    MAX_SEED,
    MAX_STEPS,
    MAX_TIMESTEPS,
    MAX_TRIALS,
)
from tests.cli_helpers import run_main

ROOT = Path(__file__).resolve().parent.parent
GOAL, WALL = "polyenvs/BuckybotGoal-v0", "polyenvs/BuckybotWallFollow-v0"

#: Every integer flag of the command line: (subcommand argv before the flag, flag, minimum, maximum).
INT_FLAGS = [
    (["evaluate", GOAL], "--episodes", 1, MAX_EPISODES),
    (["evaluate", GOAL], "--seed", 0, MAX_SEED),
    (["leaderboard"], "--episodes", 1, MAX_EPISODES),
    (["leaderboard"], "--jobs", 1, MAX_JOBS),
    (["record", GOAL], "--seed", 0, MAX_SEED),
    (["record", GOAL], "--max-steps", 1, MAX_STEPS),
    (["record", GOAL], "--every", 1, MAX_STEPS),
    (["train", GOAL, "--algo", "ppo"], "--timesteps", 1, MAX_TIMESTEPS),
    (["train", GOAL, "--algo", "ppo"], "--seed", 0, MAX_SEED),
    (["train", GOAL, "--algo", "ppo"], "--n-envs", 1, MAX_N_ENVS),
    (["train", GOAL, "--algo", "ppo"], "--checkpoint-every", 0, MAX_TIMESTEPS),
    (["sweep", "--envs", GOAL, "--algos", "ppo"], "--seeds", 0, MAX_SEED),
    (["sweep", "--envs", GOAL, "--algos", "ppo", "--seeds", "0"], "--timesteps", 1, MAX_TIMESTEPS),
    (["sweep", "--envs", GOAL, "--algos", "ppo", "--seeds", "0"], "--episodes", 1, MAX_EPISODES),
    (["sweep", "--envs", GOAL, "--algos", "ppo", "--seeds", "0"], "--jobs", 1, MAX_JOBS),
    (["sweep", "--envs", GOAL, "--algos", "ppo", "--seeds", "0"], "--checkpoint-every", 0, MAX_TIMESTEPS),
    (["localize"], "--particles", 10, MAX_PARTICLES),
    (["localize"], "--runs", 1, MAX_RUNS),
    (["localize"], "--bumps", 1, MAX_BUMPS),
    (["localize"], "--seed", 0, MAX_SEED),
    (["collect", GOAL, "--out", "dataset"], "--episodes", 1, MAX_EPISODES),
    (["collect", GOAL, "--out", "dataset"], "--seed", 0, MAX_SEED),
    (["train", GOAL, "--algo", "ppo"], "--bc-epochs", 1, MAX_BC_EPOCHS),
    (["train", GOAL, "--algo", "ppo"], "--residual-hold", 1, MAX_HOLD),
    (["tune", GOAL, "--out", "tuned"], "--trials", 1, MAX_TRIALS),
    (["tune", GOAL, "--out", "tuned", "--trials", "1"], "--seed", 0, MAX_SEED),
    (["tune", GOAL, "--out", "tuned", "--trials", "1"], "--episodes", 1, MAX_EPISODES),
]
#: Flags that take something else than an integer (text, paths, JSON, names, switches; --fps is a number).
OTHER_FLAGS = {
    "help", "json", "policy", "env_kwargs", "policy_kwargs", "quick", "only", "results_dir", "output", "redo",
    "agents_dir", "update_reference", "reproduce", "fps", "algo", "config", "out", "progress", "resume", "overwrite", "envs",
    "algos", "config_dir", "backend", "address", "estimator", "map", "env", "estimator_kwargs", "bc_from",
    "bc_log_std", "residual", "residual_scale", "residual_log_std", "layouts", "sampler", "storage", "max_mean",
    "policies",
}  # fmt: skip


@pytest.fixture
def no_work(monkeypatch):
    """Any episode, recording, rollout, training or sweep job fails the test: the flags must stop it first."""

    def refuse(*args, **kwargs):
        raise AssertionError("work started before the flags were checked")

    monkeypatch.setattr(polyenvs.evaluation.episodes, "run_episode", refuse)
    monkeypatch.setattr(polyenvs.evaluation.rollout, "episode_frames", refuse)
    monkeypatch.setattr(polyenvs.evaluation.localization, "rollout_logs", refuse)
    monkeypatch.setattr(polyenvs.training.sweep, "run_sweep", refuse)
    monkeypatch.setattr(polyenvs.training.tune, "tune", refuse)
    try:
        from polyenvs.training import vec_adapter
    except ImportError:  # pragma: no cover - no train extra
        return
    monkeypatch.setattr(vec_adapter, "make_training_vec_env", refuse)


def _one_line(code: int, err: str, fragment: str) -> None:
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and fragment in lines[0] and "Traceback" not in err, err


def test_the_table_names_every_integer_flag_of_every_subcommand():
    """A new integer flag must join INT_FLAGS (and so be tested for its limit and formats)."""
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    found = set()
    for command, subparser in sub.choices.items():
        for action in subparser._actions:
            if action.option_strings and action.dest not in OTHER_FLAGS:
                found.add((command, max(action.option_strings, key=len)))
    assert found == {(argv[0], flag) for argv, flag, _, _ in INT_FLAGS}


@pytest.mark.parametrize(("argv", "flag", "minimum", "maximum"), INT_FLAGS, ids=lambda v: str(v))
def test_every_integer_flag_has_an_upper_limit_checked_before_any_work(
    argv, flag, minimum, maximum, capsys, tmp_path, monkeypatch, no_work
):
    monkeypatch.chdir(tmp_path)  # nothing may be written: a command that went ahead would write here
    for value in (str(maximum + 1), "99999999999999999999999", "1e400"):
        code, _, err = run_main([*argv, flag, value], capsys)
        _one_line(code, err, f"{flag} must be <= {maximum}, got {value}")
    code, _, err = run_main([*argv, flag, str(minimum - 1)], capsys)
    _one_line(code, err, f"{flag} must be >= {minimum}, got {minimum - 1}")
    for value in ("abc", "1.5e0", "0x10", "nan"):
        code, _, err = run_main([*argv, flag, value], capsys)
        _one_line(code, err, f"{flag} must be ")
    assert list(tmp_path.iterdir()) == []


def test_one_parser_reads_every_format_exactly():
    for text, value in [("1000", 1000), ("1_000", 1000), ("1e3", 1000), ("1000.0", 1000), ("2.5e3", 2500),
                        (" 7 ", 7), ("9007199254740993", 9007199254740993)]:  # fmt: skip
        assert int_flag("--n", text, 0, 10**16) == value
    for text in ("1__0", "_1", "1e", "e3", "1.5", "1e-3", "", "١٢"):
        with pytest.raises(InputError, match="--n must be an integer"):
            int_flag("--n", text, 0, 10**16)
    with pytest.raises(InputError, match=r"--n must be <= 5, got 999999999999\.\.\.999999999999 \(5000 characters\)"):
        int_flag("--n", "9" * 5000, 0, 5)


def test_evaluate_and_record_read_1e3_like_train_and_localize(capsys, tmp_path):
    """``--episodes 1e3`` was refused by evaluate while train and localize took ``--timesteps 1e6``."""
    code, out, err = run_main(["evaluate", GOAL, "--episodes", "2e0", "--seed", "1_0", "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["seeds"] == [10, 11]
    pytest.importorskip("imageio.v3")
    gif = tmp_path / "e.gif"
    code, _, err = run_main(["record", GOAL, "--max-steps", "1e1", "--every", "5.0", "--output", str(gif)], capsys)
    assert code == 0 and gif.stat().st_size > 0, err


BIG = "9" * 5000  # past Python's 4300-digit limit for reading an integer


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["evaluate", GOAL, "--env-kwargs", '{"max_episode_steps": 99999999999999999999}'],
         "max_episode_steps must be an integer from 1 to 1000000, got 99999999999999999999"),
        (["evaluate", GOAL, "--env-kwargs", '{"max_episode_steps": true}'], "max_episode_steps must be an integer"),
        (["evaluate", GOAL, "--env-kwargs", '{"max_episode_steps": -1}'], "max_episode_steps must be an integer"),
        (["record", GOAL, "--env-kwargs", '{"max_episode_steps": 1e400}'], "max_episode_steps must be an integer"),
        (["evaluate", GOAL, "--env-kwargs", f'{{"max_episode_steps": {BIG}}}'],
         "--env-kwargs: Exceeds the limit (4300 digits) for integer string conversion"),
        (["evaluate", GOAL, "--policy-kwargs", f'{{"clearance_cm": {BIG}}}'], "--policy-kwargs: Exceeds the limit"),
    ],
)  # fmt: skip
def test_json_keyword_arguments_are_checked_against_what_they_feed(args, fragment, capsys, tmp_path, monkeypatch,
                                                                   no_work):  # fmt: skip
    """An episode limit in --env-kwargs is a count like the flags' (gym.make took 1e20, -1 and true)."""
    monkeypatch.chdir(tmp_path)
    code, _, err = run_main(args, capsys)
    _one_line(code, err, fragment)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["record", GOAL, "--fps", "0.001"], "--fps must be between 0.01 and 1000, got 0.001"),  # GIF: 16-bit delay
        (["record", GOAL, "--fps", "1e9"], "--fps must be between 0.01 and 1000, got 1e9"),
        (["record", GOAL, "--fps", "inf"], "--fps must be a finite number"),
        (
            ["record", "polyenvs/BeastRoll-v0", "--max-steps", "8000"],
            "--max-steps 8000 with --every 1 keeps up to 8002 frames in memory, more than 3000: raise --every to 3",
        ),
    ],
)
def test_flags_checked_against_what_they_feed(args, fragment, capsys, tmp_path, monkeypatch, no_work):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_main(args, capsys)
    _one_line(code, err, fragment)
    assert list(tmp_path.iterdir()) == []


def test_train_n_envs_beyond_the_limit_is_one_line_in_a_subprocess(tmp_path):
    """The issue's command: it printed ``ValueError: num_envs must be in [1, 1000000]`` with a traceback."""
    pytest.importorskip("stable_baselines3")
    result = subprocess.run(
        [sys.executable, "-m", "polyenvs.cli", "train", GOAL, "--algo", "ppo", "--n-envs", "10000000",
         "--out", str(tmp_path / "run")],
        capture_output=True, text=True, timeout=300, cwd=ROOT,
    )  # fmt: skip
    _one_line(result.returncode, result.stderr, f"--n-envs must be <= {MAX_N_ENVS}, got 10000000")
    assert not (tmp_path / "run").exists()


def test_a_config_cannot_ask_for_more_than_the_flags_allow(tmp_path, capsys, no_work):
    pytest.importorskip("stable_baselines3")
    config = tmp_path / "c.yml"
    config.write_text(f"{GOAL}:\n  n_timesteps: 1000\n  n_envs: 10000000\n")
    code, _, err = run_main(["train", GOAL, "--algo", "ppo", "--config", str(config), "--out", str(tmp_path / "r")],
                            capsys)  # fmt: skip
    _one_line(code, err, f"n_envs: expected an integer <= {MAX_N_ENVS}, got 10000000")
    config.write_text(f"{GOAL}:\n  n_timesteps: !!float 1e11\n")
    code, _, err = run_main(["train", GOAL, "--algo", "ppo", "--config", str(config), "--out", str(tmp_path / "r")],
                            capsys)  # fmt: skip
    _one_line(code, err, f"n_timesteps: expected an integer <= {MAX_TIMESTEPS}, got 100000000000")
