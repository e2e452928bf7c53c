"""``polyenvs train``: every flag checked before any work (one line, exit 2), a short run, Ctrl-C."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.cli_helpers import TINY_PPO_CONFIG

pytest.importorskip("stable_baselines3")
pytest.importorskip("sb3_contrib")

import polyenvs.training.train as train_module  # noqa: E402
import polyenvs.training.vec_adapter as adapter_module  # noqa: E402
from polyenvs.commands.train import add_parser, default_out_dir  # noqa: E402
from polyenvs.errors import InputError  # noqa: E402

WALL = "polyenvs/BuckybotWallFollow-v0"
ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"


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
    assert run["env_kwargs"] == {"max_episode_steps": 30, "layouts": "train"}  # the Procgen protocol by default
    assert main(argv) == 0
    assert "already holds a finished run" in capsys.readouterr().out


def test_train_draws_the_training_layouts_unless_told_otherwise_and_records_them(tmp_path, capsys):
    """Agents learn on layouts="train" (the leaderboard judges them on "test"); --layouts, --env-kwargs' layouts or
    the config's env_kwargs say otherwise; two that disagree are refused before any work."""
    from polyenvs.training.train import training_layouts

    assert training_layouts(None, {}, {}, WALL) == "train"
    assert training_layouts(None, {}, {}, "Pendulum-v1") is None  # not ours: it takes no layouts
    assert training_layouts(None, {}, {"layouts": "default"}, WALL) == "default"
    assert training_layouts(None, {"layouts": "test"}, {"layouts": "default"}, WALL) == "test"
    assert training_layouts("default", {}, {"layouts": "test"}, WALL) == "default"
    base = ["train", WALL, "--algo", "ppo", "--config", str(CONFIGS / "ppo.yml"), "--timesteps", "64", "--n-envs", "1",
            "--env-kwargs", '{"max_episode_steps": 8}', "--no-progress"]  # fmt: skip
    assert main([*base, "--layouts", "default", "--out", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    assert json.loads((tmp_path / "a" / "run.json").read_text())["env_kwargs"]["layouts"] == "default"
    for bad, words in ((["--layouts", "held-out"], "layouts must be one of"),
                       (["--layouts", "test", "--env-kwargs", '{"layouts": "train"}'], "give one")):  # fmt: skip
        assert main([*base, *bad, "--out", str(tmp_path / "b")]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and words in err and not (tmp_path / "b").exists()


def test_ctrl_c_exits_130_and_says_where_the_model_is(tmp_path, capsys, monkeypatch):
    def interrupted(request):
        raise train_module.TrainingInterrupted(request.out_dir, 1234)

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


def test_the_flags_build_the_request_a_python_caller_builds():
    """The command line names each setting once, as the request's field: its defaults are the request's, and each
    flag lands in its own field."""
    from baselines.residual import ResidualSpec
    from polyenvs.commands.train import training_request
    from polyenvs.training.train import TrainRequest

    plain = training_request(_parser().parse_args(["train", WALL, "--algo", "ppo", "--no-progress"]))
    assert plain == TrainRequest(WALL, "ppo", out_dir=default_out_dir(WALL, "ppo", 0))
    flags = ["--config", "c.yml", "--timesteps", "640", "--seed", "7", "--n-envs", "3", "--env-kwargs",
             '{"max_episode_steps": 9}', "--layouts", "default", "--out", "o", "--resume", "--checkpoint-every", "128",
             "--progress"]  # fmt: skip
    given = training_request(_parser().parse_args(["train", WALL, "--algo", "dqn", *flags]))
    assert given == TrainRequest(
        WALL, "dqn", out_dir=Path("o"), config="c.yml", timesteps=640, seed=7, n_envs=3,
        env_kwargs={"max_episode_steps": 9}, layouts="default", resume=True, checkpoint_every=128, progress_bar=True,
    )  # fmt: skip
    residual = ["--residual", "paper", "--residual-scale", "0.25", "--residual-log-std", "-1", "--residual-hold", "2"]
    given = training_request(_parser().parse_args(["train", WALL, "--algo", "ppo", *residual, "--no-progress"]))
    assert given == TrainRequest(
        WALL, "ppo", out_dir=default_out_dir(WALL, "ppo_residual_paper", 0), residual=ResidualSpec("paper", 0.25, hold=2),
        residual_log_std=-1.0,
    )  # fmt: skip


# ------------------------------------------------------------------------------------- interrupted runs


def test_an_interrupted_out_dir_is_one_line_naming_the_flag_to_use(tmp_path, capsys, no_work):
    out = tmp_path / "run"
    out.mkdir()
    run = {"env_id": WALL, "algo": "ppo", "seed": 0, "timesteps": 512, "requested_timesteps": 4096, "completed": False}
    (out / "run.json").write_text(json.dumps(run))
    assert main(["train", WALL, "--algo", "ppo", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("polyenvs train: error: ")
    assert "holds an interrupted run that saved no model yet; --overwrite (or --resume) to train it again" in err
    (out / "model.zip").write_bytes(b"PK")
    assert main(["train", WALL, "--algo", "ppo", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "holds an interrupted run (512 of 4096 timesteps saved); --resume to continue it, or --overwrite" in err
    assert main(["train", WALL, "--algo", "ppo", "--seed", "1", "--resume", "--out", str(out)]) == 2
    assert (
        "holds an unfinished or interrupted run of polyenvs/BuckybotWallFollow-v0 ppo seed 0" in capsys.readouterr().err
    )
    with pytest.raises(SystemExit):
        _parser().parse_args(["train", WALL, "--algo", "ppo", "--resume", "--overwrite"])
    assert sorted(p.name for p in out.iterdir()) == ["model.zip", "run.json"]  # refused: nothing touched


def _wait_for_a_checkpoint(proc: subprocess.Popen, run_file: Path, log: Path) -> dict:
    deadline = time.monotonic() + 300  # a bound on a broken run, not a timing assertion
    while True:
        try:
            run = json.loads(run_file.read_text())
        except (OSError, ValueError):
            run = {}
        if run.get("timesteps", 0) > 0:
            return run
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"training ended (or never checkpointed) before it was killed: {log.read_text()[-2000:]}")
        time.sleep(0.2)


def test_kill_9_then_resume_continues_from_the_last_checkpoint_and_overwrite_starts_again(tmp_path, capsys):
    config, out, log = tmp_path / "tiny.yml", tmp_path / "run", tmp_path / "train.log"
    config.write_text(TINY_PPO_CONFIG)
    argv = ["train", WALL, "--algo", "ppo", "--config", str(config), "--out", str(out), "--no-progress"]
    with open(log, "w") as sink:
        proc = subprocess.Popen(
            [sys.executable, "-m", "polyenvs.cli", *argv, "--timesteps", "1000000", "--checkpoint-every", "128"],
            cwd=ROOT, stdout=sink, stderr=subprocess.STDOUT, start_new_session=True,
        )  # fmt: skip
    try:
        _wait_for_a_checkpoint(proc, out / "run.json", log)
        # While it trains, the directory is its alone.
        assert main([*argv, "--resume"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"is being trained into by pid {proc.pid}; wait for it or stop it" in err
    finally:
        with contextlib.suppress(ProcessLookupError):  # (already gone if it failed to start)
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    run = json.loads((out / "run.json").read_text())
    saved = train_module.saved_timesteps(out)  # run.json may lag the model by the moment between the two
    assert run["completed"] is False and 0 < run["timesteps"] <= saved and saved % 128 == 0

    assert main([*argv, "--timesteps", "512", "--resume"]) == 0
    printed = capsys.readouterr().out
    assert f"interrupted at {saved} of 1000000 timesteps: resuming it from its saved model" in printed
    run = json.loads((out / "run.json").read_text())
    assert run["completed"] is True and run["resumed_at"] == [saved] and run["requested_timesteps"] == 512
    assert run["timesteps"] >= 512 and run["command"].endswith("--timesteps 1000000 --checkpoint-every 128")
    import stable_baselines3 as sb3

    assert sb3.PPO.load(out / "model.zip", device="cpu").num_timesteps == run["timesteps"]
    assert not list(out.glob(".*"))  # no lock or temporary file left in a finished run

    assert main([*argv, "--timesteps", "256", "--overwrite"]) == 0
    run = json.loads((out / "run.json").read_text())
    assert run["completed"] is True and run["timesteps"] == 256 and "resumed_at" not in run


_DIE_BETWEEN_THE_RENAMES = """
import os, sys
from polyenvs.cli import main
rename, renamed = os.replace, []
def replace(source, target):  # the process dies between a checkpoint's two renames, the second time round
    if str(target).endswith("vecnormalize.pkl") and len(renamed) == 1:
        os._exit(9)
    rename(source, target)
    if str(target).endswith("vecnormalize.pkl"):
        renamed.append(target)
os.replace = replace
sys.exit(main(sys.argv[1:]))
"""


def test_a_run_killed_between_a_checkpoints_two_renames_resumes_from_that_checkpoint(tmp_path, capsys):
    """The model of the second checkpoint is in place, its statistics still under their temporary name: resuming
    renames them too and goes on from that checkpoint (it used to refuse: the two were saved apart)."""
    config, out = tmp_path / "tiny.yml", tmp_path / "run"
    config.write_text(TINY_PPO_CONFIG)
    argv = ["train", WALL, "--algo", "ppo", "--config", str(config), "--out", str(out), "--no-progress"]
    died = subprocess.run([sys.executable, "-c", _DIE_BETWEEN_THE_RENAMES, *argv, "--timesteps", "2048",
                           "--checkpoint-every", "128"], cwd=ROOT, capture_output=True, timeout=300)  # fmt: skip
    assert died.returncode == 9, died.stderr.decode()
    saved = train_module.saved_timesteps(out)
    assert saved > json.loads((out / "run.json").read_text())["timesteps"]  # the model got ahead of run.json
    assert main([*argv, "--timesteps", "2048", "--resume"]) == 0, capsys.readouterr().err
    assert json.loads((out / "run.json").read_text())["resumed_at"] == [saved]
