"""``polyenvs sweep``: flags checked before any job (one line each), a local 2-job sweep, its re-run, Ray."""

from __future__ import annotations

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

from polyenvs.cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
WALL = "polyenvs/BuckybotWallFollow-v0"
SLUG = "polyenvs__BuckybotWallFollow-v0"


@pytest.fixture
def config_dir(tmp_path) -> Path:
    directory = tmp_path / "configs"
    directory.mkdir()
    (directory / "ppo.yml").write_text(TINY_PPO_CONFIG)
    return directory


def _argv(config_dir: Path, out: Path, *extra: str) -> list[str]:
    return [
        "sweep", "--envs", WALL, "--algos", "ppo", "--seeds", "0", "1", "--timesteps", "256",
        "--config-dir", str(config_dir), "--out", str(out), "--episodes", "1", "--jobs", "2", *extra,
    ]  # fmt: skip


def _check_outputs(out: Path) -> dict[int, float]:
    mtimes = {}
    for seed in (0, 1):
        agent = out / "agents" / SLUG / "ppo" / f"seed{seed}"
        run = json.loads((agent / "run.json").read_text())
        assert run["completed"] is True and run["seed"] == seed and run["timesteps"] >= 256
        assert run["command"].startswith(f"polyenvs train {WALL} --algo ppo --config ")
        assert not (agent / "tb").exists()
        result = json.loads((out / "results" / f"{SLUG}__agent__ppo__seed{seed}.json").read_text())
        assert result["n_episodes"] == 1 and result["seeds"] == [1000] and result["agent"]["training_seed"] == seed
        mtimes[seed] = (agent / "model.zip").stat().st_mtime_ns
    return mtimes


def test_local_sweep_runs_two_jobs_then_skips_them(tmp_path, config_dir, capsys):
    out = tmp_path / "out"
    assert main(_argv(config_dir, out)) == 0
    printed = capsys.readouterr().out
    assert printed.count("trained in") == 2 and "IQM return" in printed and "2 of 2 jobs finished" in printed
    mtimes = _check_outputs(out)
    results = {p: p.stat().st_mtime_ns for p in (out / "results").iterdir()}

    assert main(_argv(config_dir, out)) == 0
    printed = capsys.readouterr().out
    assert printed.count("trained before; evaluated before") == 2 and "done before" in printed
    assert _check_outputs(out) == mtimes  # no retraining
    assert {p: p.stat().st_mtime_ns for p in (out / "results").iterdir()} == results


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"--envs": ["polyenvs/Nope-v0"]}, "--envs: unknown environment id 'polyenvs/Nope-v0'"),
        ({"--envs": ["polyenvs/BuckybotWalFollow-v0"]}, "Did you mean: `BuckybotWallFollow`?"),
        ({"--algos": ["a2c"]}, "--algos: unknown algorithm 'a2c'"),
        ({"--seeds": ["0", "-1"]}, "--seeds must be >= 0, got -1"),
        ({"--seeds": ["x"]}, "--seeds must be an integer, got 'x'"),
        ({"--jobs": ["0"]}, "--jobs must be >= 1, got 0"),
        ({"--timesteps": ["0"]}, "--timesteps must be >= 1, got 0"),
        ({"--episodes": ["0"]}, "--episodes must be >= 1, got 0"),
        ({"--backend": ["slurm"]}, "--backend must be one of local, ray, got 'slurm'"),
        ({"--address": ["auto"]}, "--address joins a Ray cluster: it needs --backend ray"),
        ({"--algos": ["dqn"]}, "dqn.yml does not exist"),
        ({"--envs": ["polyenvs/BuckybotGoal-v0"]}, "has no entry for polyenvs/BuckybotGoal-v0"),
        ({"--config-dir": ["/nonexistent/configs"]}, "--config-dir /nonexistent/configs: no such directory"),
        ({"--out": ["/proc/polyenvs-sweep"]}, "--out /proc/polyenvs-sweep: cannot write in /proc"),
    ],
)
def test_bad_flags_are_one_line_before_any_job(tmp_path, config_dir, capsys, monkeypatch, change, message):
    import polyenvs.training.sweep as sweep

    monkeypatch.setattr(sweep, "run_sweep", lambda *a, **k: pytest.fail("a job started before the flags were checked"))
    argv = _argv(config_dir, tmp_path / "out")
    for flag, values in change.items():
        if flag in argv:
            i = argv.index(flag)
            end = i + 1
            while end < len(argv) and not argv[end].startswith("--"):
                end += 1
            argv[i + 1 : end] = values
        else:
            argv += [flag, *values]
    assert main(argv) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("polyenvs sweep: error: ") and message in err, err
    assert not (tmp_path / "out").exists()


def test_an_interrupted_job_that_saved_no_model_is_trained_again(tmp_path, config_dir, capsys):
    """What a kill -9 before the first checkpoint leaves: the run.json written before training, without
    ``completed`` true (and maybe a temporary file cut short). Every re-run used to stop at it with exit 2."""
    out = tmp_path / "out"
    busy = out / "agents" / SLUG / "ppo" / "seed1"
    busy.mkdir(parents=True)
    (busy / "run.json").write_text(json.dumps({"env_id": WALL, "algo": "ppo", "seed": 1, "timesteps": 0,
                                               "requested_timesteps": 256, "completed": False}))  # fmt: skip
    (busy / ".model.zip.0123abcd.tmp.zip").write_bytes(b"PK")  # the write the kill cut short
    assert main(_argv(config_dir, out)) == 0
    printed = capsys.readouterr().out
    assert f"{WALL} ppo seed1: interrupted before it saved a model: training it again from the start" in printed
    assert "2 of 2 jobs finished" in printed
    _check_outputs(out)
    assert "resumed_at" not in json.loads((busy / "run.json").read_text())
    assert sorted(p.name for p in busy.iterdir()) == ["curve.json", "model.zip", "run.json", "vecnormalize.pkl"]


def _wait_for_checkpoints(proc: subprocess.Popen, run_files: list[Path], log: Path) -> None:
    """Until every run.json records a checkpoint (timesteps > 0); fails if the process ends first."""
    deadline = time.monotonic() + 300  # a bound on a broken run, not a timing assertion
    while True:
        runs = []
        for path in run_files:
            try:
                runs.append(json.loads(path.read_text()))
            except (OSError, ValueError):
                runs.append({})
        if all(r.get("timesteps", 0) > 0 for r in runs):
            return
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"the sweep ended (or never checkpointed) before it was killed: {log.read_text()[-2000:]}")
        time.sleep(0.2)


def _wait_until_unlocked(lock: Path) -> None:
    import fcntl

    deadline = time.monotonic() + 60  # a bound, not a timing assertion
    while lock.exists():
        with open(lock) as fh:
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return
            except OSError:
                if time.monotonic() > deadline:
                    pytest.fail(f"{lock} is still held after the kill")
        time.sleep(0.1)


def test_a_sweep_killed_mid_training_resumes_every_job(tmp_path, config_dir, capsys):
    """kill -9 of the whole sweep (driver and workers: the machine lost, the OOM killer) mid-training, then the
    same sweep again: every job resumes from its last checkpoint and finishes."""
    out = tmp_path / "out"
    argv = _argv(config_dir, out, "--checkpoint-every", "128")
    argv[argv.index("--timesteps") + 1] = "1000000"  # would train for an hour: only the kill ends it
    log = tmp_path / "sweep.log"
    with open(log, "w") as sink:
        proc = subprocess.Popen([sys.executable, "-m", "polyenvs.cli", *argv], cwd=ROOT, stdout=sink,
                                stderr=subprocess.STDOUT, start_new_session=True)  # fmt: skip
    runs = [out / "agents" / SLUG / "ppo" / f"seed{seed}" / "run.json" for seed in (0, 1)]
    try:
        _wait_for_checkpoints(proc, runs, log)
    finally:
        with contextlib.suppress(ProcessLookupError):  # (already gone if it failed to start)
            os.killpg(proc.pid, signal.SIGKILL)  # the driver and its workers, as a lost machine stops them
        proc.wait()
    for path in runs:  # the workers are gone once the kernel has released their locks (a moment after the driver)
        _wait_until_unlocked(path.parent / ".training.lock.tmp")
    from polyenvs.training.train import saved_timesteps

    saved = {}
    for seed, path in enumerate(runs):
        run = json.loads(path.read_text())
        saved[seed] = saved_timesteps(path.parent)  # run.json may lag the model by the moment between the two
        assert run["completed"] is False and 0 < run["timesteps"] <= saved[seed]

    argv[argv.index("--timesteps") + 1] = "512"
    assert main(argv) == 0
    printed = capsys.readouterr().out
    for seed in (0, 1):
        assert (
            f"ppo seed{seed}: interrupted at {saved[seed]} of 1000000 timesteps: resuming it from its saved model"
            in printed
        )
        assert f"ppo seed{seed}: resumed at {saved[seed]} timesteps, trained in" in printed
    assert "2 of 2 jobs finished" in printed
    _check_outputs(out)
    for seed, path in enumerate(runs):
        run = json.loads(path.read_text())
        assert run["resumed_at"] == [saved[seed]] and run["timesteps"] >= 512 and run["requested_timesteps"] == 512


def _live_processes(session: int) -> set[int]:
    """The processes of ``session`` that have not exited (zombies waiting to be reaped are not counted)."""
    live = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            state, _, _, sid = stat.read_text().rsplit(")", 1)[1].split()[:4]
        except (OSError, ValueError):  # gone meanwhile
            continue
        if int(sid) == session and state != "Z":
            live.add(int(stat.parent.name))
    return live


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process table in /proc")
def test_a_pool_worker_exits_when_its_parent_is_killed_outright(tmp_path):
    """kill -9 of the sweep's main process alone (not its group) left its pool worker alive for ever (458 MB, idle
    once its job ended): a worker must exit with its parent, here one busy with a 10-minute job."""
    started = tmp_path / "started"
    jobs = [f"open({str(started)!r}, 'w').close()", "import time; time.sleep(600)"]
    script = f"from polyenvs.pool import run_local; run_local(exec, {jobs!r}, 1, print, print)"
    log = tmp_path / "pool.log"
    with open(log, "w") as sink:
        proc = subprocess.Popen([sys.executable, "-c", script], cwd=ROOT, stdout=sink, stderr=subprocess.STDOUT,
                                start_new_session=True)  # fmt: skip
    try:
        deadline = time.monotonic() + 120  # bounds on a broken run, not timing assertions
        while not started.exists():
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"the pool's first job never ran: {log.read_text()[-2000:]}")
            time.sleep(0.1)
        assert len(_live_processes(proc.pid)) >= 2  # the parent and its worker (and multiprocessing's tracker)
        os.kill(proc.pid, signal.SIGKILL)  # the parent alone
        proc.wait()
        deadline = time.monotonic() + 60
        while _live_processes(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not _live_processes(proc.pid), f"still alive 60 s after their parent died: {_live_processes(proc.pid)}"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def test_a_failing_job_is_reported_and_the_others_finish(tmp_path, config_dir, capsys):
    out = tmp_path / "out"
    blocked = out / "results" / f"{SLUG}__agent__ppo__seed1.json"
    blocked.mkdir(parents=True)  # a directory where the result file goes: its evaluation cannot be written
    assert main(_argv(config_dir, out)) == 1
    captured = capsys.readouterr()
    assert "1 of 2 jobs finished" in captured.out
    failures = [line for line in captured.err.splitlines() if "FAILED" in line]
    assert len(failures) == 1 and f"{WALL} ppo seed1: FAILED: " in failures[0]
    assert (out / "results" / f"{SLUG}__agent__ppo__seed0.json").is_file()


def test_missing_ray_gives_the_install_hint(tmp_path, config_dir, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    assert main(_argv(config_dir, tmp_path / "out", "--backend", "ray")) == 2
    err = capsys.readouterr().err.strip()
    assert err == 'polyenvs sweep: error: the ray backend needs Ray: pip install ".[distributed]" in a polyenvs clone'


def test_ray_backend_on_a_local_instance_runs_two_jobs(tmp_path, config_dir, capsys):
    pytest.importorskip("ray")
    out = tmp_path / "out"
    assert main(_argv(config_dir, out, "--backend", "ray")) == 0
    printed = capsys.readouterr().out
    assert "on Ray (a local instance, 2 CPUs)" in printed and printed.count("trained in") == 2
    _check_outputs(out)
