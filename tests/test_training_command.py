"""``polyenvs train``: every flag checked before any work (one line, exit 2), a short run, Ctrl-C."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("sb3_contrib")

import polyenvs.training.train as train_module  # noqa: E402
import polyenvs.training.vec_adapter as adapter_module  # noqa: E402
from polyenvs.evaluation import InputError  # noqa: E402
from polyenvs.training.command import add_parser, default_out_dir  # noqa: E402

WALL = "polyenvs/BuckybotWallFollow-v0"
CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="polyenvs")
    add_parser(parser.add_subparsers(dest="command", required=True))
    return parser


def main(argv: list[str]) -> int:
    """What ``polyenvs.cli.main`` does with the subcommand: InputError -> one line on stderr, exit 2."""
    args = _parser().parse_args(argv)
    try:
        return args.func(args)
    except InputError as exc:
        print(f"polyenvs {args.command}: error: {exc}", file=sys.stderr)
        return 2


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if training environments are ever built."""

    def refuse(*args, **kwargs):
        raise AssertionError("work started before the flags were checked")

    monkeypatch.setattr(adapter_module, "make_training_vec_env", refuse)


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--algo", "a2c"], "unknown algorithm 'a2c'; expected one of ppo, dqn, maskable_ppo, sac, td3"),
        (["--algo", "ppo", "--timesteps", "many"], "--timesteps must be an integer, got 'many'"),
        (["--algo", "ppo", "--timesteps", "0"], "--timesteps must be >= 1, got 0"),
        (["--algo", "ppo", "--timesteps", "1.5"], "--timesteps must be an integer, got '1.5'"),
        (["--algo", "ppo", "--seed", "-1"], "--seed must be >= 0, got -1"),
        (["--algo", "ppo", "--n-envs", "0"], "--n-envs must be >= 1, got 0"),
        (["--algo", "ppo", "--env-kwargs", "{bad"], "--env-kwargs is not valid JSON"),
        (["--algo", "ppo", "--env-kwargs", "[1]"], "--env-kwargs must be a JSON object, got '[1]'"),
        (["--algo", "ppo", "--env-kwargs", '{"floor_plan": "nowhere"}'], "bad environment keyword arguments"),
        (["--algo", "ppo", "--config", "missing.yml"], "config file missing.yml does not exist"),
        (["--algo", "sac"], "sac needs continuous actions (Box), but polyenvs/BuckybotWallFollow-v0 has Discrete(3)"),
    ],
)
def test_flag_errors_are_one_line_before_any_work(tmp_path, capsys, no_work, flags, message):
    out = tmp_path / "out"
    assert main(["train", WALL, *flags, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("polyenvs train: error: ") and message in err, err
    assert err.count("\n") == 1
    assert not out.exists()


def test_unknown_id_bad_config_and_unusable_out(tmp_path, capsys, no_work):
    assert main(["train", "polyenvs/Nope-v0", "--algo", "ppo", "--out", str(tmp_path / "a")]) == 2
    assert "unknown environment id 'polyenvs/Nope-v0'" in capsys.readouterr().err
    config = tmp_path / "c.yml"
    config.write_text(f"{WALL}:\n  n_timesteps: 10\n  n_step: 5\n")
    assert main(["train", WALL, "--algo", "ppo", "--config", str(config), "--out", str(tmp_path / "b")]) == 2
    assert f"{config}: {WALL}: n_step: unknown key for ppo (PPO) (did you mean 'n_steps'?)" in capsys.readouterr().err
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "x").write_text("")
    assert main(["train", WALL, "--algo", "ppo", "--out", str(busy)]) == 2
    assert "holds files and no run.json" in capsys.readouterr().err
    blocker = tmp_path / "blocker"
    blocker.write_text("")
    assert main(["train", WALL, "--algo", "ppo", "--out", str(blocker / "run")]) == 2
    assert "is not a directory" in capsys.readouterr().err


def test_train_command_runs_and_skips_when_finished(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["train", WALL, "--algo", "maskable_ppo", "--config", str(CONFIGS / "maskable_ppo.yml"), "--timesteps", "128",
            "--n-envs", "1", "--seed", "2", "--env-kwargs", '{"max_episode_steps": 30}', "--out", str(out),
            "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "trained maskable_ppo on polyenvs/BuckybotWallFollow-v0: 256 timesteps" in printed
    assert f"wrote {out}" in printed
    run = json.loads((out / "run.json").read_text())
    assert run["seed"] == 2 and run["n_envs"] == 1 and run["completed"] is True
    assert run["env_kwargs"] == {"max_episode_steps": 30}
    assert main(argv) == 0
    assert "already holds a finished run" in capsys.readouterr().out


def test_ctrl_c_exits_130_and_says_where_the_model_is(tmp_path, capsys, monkeypatch):
    def interrupted(*args, out_dir, **kwargs):
        raise train_module.TrainingInterrupted(Path(out_dir), 1234)

    monkeypatch.setattr(train_module, "train", interrupted)
    assert main(["train", WALL, "--algo", "ppo", "--out", str(tmp_path / "run")]) == 130
    err = capsys.readouterr().err
    assert "interrupted after 1234 timesteps; saved the partial model in" in err and "completed false" in err


def test_defaults():
    args = _parser().parse_args(["train", WALL, "--algo", "ppo"])
    assert args.config is None and args.timesteps is None and args.n_envs is None and args.progress is None
    assert args.seed == "0" and args.env_kwargs == "{}" and args.out is None
    assert default_out_dir(WALL, "ppo", 3) == Path("runs/train/BuckybotWallFollow-v0/ppo/seed3")
    assert _parser().parse_args(["train", WALL, "--algo", "ppo", "--progress"]).progress is True
    assert _parser().parse_args(["train", WALL, "--algo", "ppo", "--no-progress"]).progress is False
    with pytest.raises(SystemExit):
        _parser().parse_args(["train", WALL])  # --algo is required
