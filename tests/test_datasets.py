"""``polyenvs collect``: Minari datasets of seeded episodes, one id of every family, loaded back with Minari itself."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from tests.cli_helpers import run_main

minari = pytest.importorskip("minari")

from polyenvs import __version__  # noqa: E402
from polyenvs.evaluation.datasets import CollectRequest, collect  # noqa: E402
from polyenvs.evaluation.episodes import make_agent  # noqa: E402
from polyenvs.evaluation.rollout import policy_action  # noqa: E402

#: One id of every family, its episodes cut short so that the whole file runs in seconds.
FAMILIES = [
    ("polyenvs/BuckybotGoal-v0", {"max_episode_steps": 40}),
    ("polyenvs/BeastTumble-v1", {"max_episode_steps": 30}),
    ("polyenvs/BumperCartExplore-v1", {"max_episode_steps": 8}),
    ("polyenvs/APLiteCorridor-v0", {"max_episode_steps": 40}),
    ("polyenvs.swarm.corridor_v0", {"max_cycles": 25}),
]
SEED = 7
ROOT = Path(__file__).resolve().parent.parent
#: ``polyenvs collect`` stalled while Minari writes its HDF5 (a partial file already there), until it is killed.
STALLED_COLLECT = """
import os, sys, time
import minari
from polyenvs.cli import main

def stalled(*args, **kwargs):
    root = os.environ["MINARI_DATASETS_PATH"]
    os.makedirs(root)
    with open(os.path.join(root, "partial.hdf5"), "wb") as fh:
        fh.write(bytes(100_000))
    time.sleep(600)

minari.create_dataset_from_buffers = stalled
sys.exit(main(sys.argv[1:]))
"""


def _load(root, identifier, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    return minari.load_dataset(identifier)


def _replay(env, agent, seed, options):
    """A fresh rollout of ``agent`` in the recovered environment: (observations, actions)."""
    obs, info = env.reset(seed=seed, options=options)
    observations, actions, state, start = [obs], [], None, True
    while True:
        action, state = policy_action(agent, obs, state, start, info)
        obs, _, terminated, truncated, info = env.step(action)
        observations.append(obs)
        actions.append(action)
        start = False
        if terminated or truncated:
            return np.stack(observations), np.stack(actions)


@pytest.mark.parametrize("env_id, env_kwargs", FAMILIES, ids=[f[0] for f in FAMILIES])
def test_a_dataset_round_trips_through_minari(env_id, env_kwargs, tmp_path, monkeypatch):
    out = tmp_path / "demos"
    identifier = collect(CollectRequest(env_id, "paper", episodes=2, seed=SEED, out_dir=out, env_kwargs=env_kwargs))
    dataset = _load(out, identifier, monkeypatch)
    metadata = dataset.storage.metadata
    facts = metadata["polyenvs"]
    assert facts["env_id"] == env_id and facts["seeds"] == [SEED, SEED + 1]
    assert metadata["algorithm_name"] == facts["policy_name"] != "paper"
    assert f"polyenvs {__version__}" in metadata["code_permalink"]
    # the references: random's and the paper's mean return, evaluated here (the keywords differ from the committed)
    assert metadata["ref_min_score"] < metadata["ref_max_score"] or env_id.startswith("polyenvs/BumperCart")
    assert "evaluated" in facts["reference_scores"]["ref_max_score"]

    episodes = list(dataset.iterate_episodes())
    per_episode = list(dataset.storage.get_episode_metadata(range(dataset.total_episodes)))
    swarm = env_id.startswith("polyenvs.swarm")
    robots = 3 if swarm else 1
    assert len(episodes) == 2 * robots
    if swarm:  # one episode per robot of each swarm episode, named by its options
        assert [m["options"]["robot"] for m in per_episode] == [f"robot_{i}" for i in range(3)] * 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = dataset.recover_environment()
    try:
        # the collecting policy, seeded as collect seeds it: a stochastic one (the cart's) replays its draws too
        agent = make_agent("paper", env_id, env, seed=SEED)
        for episode, meta in zip(episodes, per_episode, strict=True):
            observations, actions = _replay(env, agent, int(meta["seed"]), meta.get("options"))
            assert np.array_equal(observations, episode.observations)
            assert np.array_equal(actions, episode.actions)
            assert len(episode.rewards) == len(actions) > 0
    finally:
        env.close()


def test_reference_scores_come_from_the_committed_results(tmp_path, monkeypatch):
    """With the default keywords, random's and the paper's mean returns are read from benchmarks/results."""
    from polyenvs.evaluation.results import load_result, result_path

    results = "benchmarks/results"
    out = tmp_path / "demos"
    identifier = collect(
        CollectRequest("polyenvs/APLiteCorridor-v0", "random", episodes=1, out_dir=out, results_dir=results)
    )
    metadata = _load(out, identifier, monkeypatch).storage.metadata
    paper, _ = load_result(result_path(results, "polyenvs/APLiteCorridor-v0", "aplite"), "polyenvs/APLiteCorridor-v0",
                           "aplite")  # fmt: skip
    assert metadata["ref_max_score"] == paper["summary"]["return"]
    assert metadata["algorithm_name"] == "random"
    assert "benchmarks/results" in metadata["polyenvs"]["reference_scores"]["ref_min_score"]


def test_the_command_writes_once_and_refuses_an_existing_directory(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no committed results here: the references are evaluated
    args = ["collect", "polyenvs/APLiteCorridor-v0", "--episodes", "1", "--out", "demos", "--env-kwargs",
            '{"max_episode_steps": 20}']  # fmt: skip
    code, out, err = run_main(args, capsys)
    assert code == 0, err
    assert f"MINARI_DATASETS_PATH={tmp_path / 'demos'} " in out
    written = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*") if p.is_file())
    assert written == [
        "demos/polyenvs/APLiteCorridor-v0/aplite-v0/data/main_data.hdf5",
        "demos/polyenvs/APLiteCorridor-v0/aplite-v0/data/metadata.json",
        "demos/polyenvs/APLiteCorridor-v0/namespace_metadata.json",
        "demos/polyenvs/namespace_metadata.json",
    ]
    code, _, err = run_main(args, capsys)
    assert code == 2 and "--overwrite" in err and len(err.strip().splitlines()) == 1
    code, _, err = run_main([*args, "--overwrite", "--seed", "3"], capsys)
    assert code == 0, err
    metadata = json.loads((tmp_path / written[1]).read_text())
    assert metadata["polyenvs"]["seeds"] == [3]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demos"]  # no temporary folder left behind


def test_the_command_creates_the_folders_above_its_directory(tmp_path, capsys):
    out_dir = tmp_path / "not" / "yet" / "demos"
    args = ["collect", "polyenvs/APLiteCorridor-v0", "--episodes", "1", "--out", str(out_dir), "--env-kwargs",
            '{"max_episode_steps": 20}']  # fmt: skip
    code, _, err = run_main(args, capsys)
    assert code == 0, err
    assert (out_dir / "polyenvs/APLiteCorridor-v0/aplite-v0/data/main_data.hdf5").is_file()


def test_an_interrupted_collection_leaves_the_directory_as_it_was(tmp_path, monkeypatch):
    """Written under a temporary name: a failure before the rename keeps the old dataset and leaves no trace."""
    import polyenvs.evaluation.datasets as datasets

    out = tmp_path / "demos"
    kwargs = {"out_dir": out, "env_kwargs": {"max_episode_steps": 5}}
    collect(CollectRequest("polyenvs/APLiteCorridor-v0", "paper", episodes=1, seed=1, **kwargs))
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}

    def broken(*args, **kwargs):
        raise RuntimeError("the machine went away")

    monkeypatch.setattr(datasets, "_replace_dir", broken)
    with pytest.raises(RuntimeError):
        collect(CollectRequest("polyenvs/APLiteCorridor-v0", "paper", episodes=1, seed=2, overwrite=True, **kwargs))
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["demos"]


def _stalled_collect(args: list[str], out, log) -> tuple[subprocess.Popen, Path]:
    """A ``polyenvs collect`` process stalled in its write, and the work directory it writes in."""
    before = set(out.parent.glob(f".{out.name}.*.tmp"))
    proc = subprocess.Popen([sys.executable, "-c", STALLED_COLLECT, *args], cwd=ROOT, stdout=log,
                            stderr=subprocess.STDOUT)  # fmt: skip
    deadline = time.monotonic() + 120  # a bound on a broken run, not a timing assertion
    while True:
        started = [p.parent.parent for p in out.parent.glob(f".{out.name}.*.tmp/*/partial.hdf5")]
        new = [p for p in started if p not in before]
        if new:
            return proc, new[0]
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"the collection never started writing: {Path(log.name).read_text()[-2000:]}")
        time.sleep(0.1)


@pytest.mark.skipif(sys.platform == "win32", reason="no kill -9 (nor the locks that tell a live run)")
def test_a_collection_killed_outright_leaves_nothing_behind_the_next_run(tmp_path, capsys):
    """kill -9 while Minari wrote left the hidden work directory (up to 3 MB of partial HDF5) beside the output for
    ever: the next run removes it, and keeps the one a live collection is writing in."""
    out = tmp_path / "demos"
    args = ["collect", "polyenvs/APLiteCorridor-v0", "--episodes", "1", "--out", str(out), "--env-kwargs",
            '{"max_episode_steps": 5}']  # fmt: skip
    with open(tmp_path / "killed.log", "w") as killed_log, open(tmp_path / "live.log", "w") as live_log:
        killed, abandoned = _stalled_collect(args, out, killed_log)
        os.kill(killed.pid, signal.SIGKILL)
        killed.wait()
        assert (abandoned / "dataset" / "partial.hdf5").stat().st_size == 100_000  # what the kill leaves
        live, working = _stalled_collect(args, out, live_log)  # the next run: it starts by removing it
        try:
            assert {p.name for p in tmp_path.glob(".demos.*")} == {working.name}
            code, _, err = run_main(args, capsys)
            assert code == 0, err
            assert {p.name for p in tmp_path.glob(".demos.*")} == {working.name}
            assert live.poll() is None  # still writing, undisturbed
        finally:
            live.kill()
            live.wait()
    assert (out / "polyenvs" / "APLiteCorridor-v0" / "aplite-v0" / "data" / "main_data.hdf5").is_file()


@pytest.mark.parametrize(
    "extra, fragment",
    [
        (["--episodes", "0"], "--episodes"),
        (["--episodes", "1.5"], "--episodes"),
        (["--seed", "-1"], "--seed"),
        (["--env-kwargs", "[1]"], "--env-kwargs"),
        (["--env-kwargs", '{"nonsense": 1}'], "nonsense"),
        (["--policy", "nobody"], "unknown policy"),
        (["--policy", "runs/none/model.zip"], "runs/none/model.zip"),
        (["--policy-kwargs", '{"clearance_cm": -1}'], "clearance_cm"),
        (["--out", "file.txt"], "is a file"),
        (["--out", "full"], "--overwrite"),
    ],
)
def test_bad_flags_are_one_line_before_any_work(extra, fragment, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "file.txt").write_text("")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep").write_text("")
    args = ["collect", "polyenvs/APLiteCorridor-v0", "--out", "demos", *extra]
    code, _, err = run_main(args, capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and fragment in lines[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt", "full"]
    assert [p.name for p in (tmp_path / "full").iterdir()] == ["keep"]


def test_unknown_environment_is_one_line(tmp_path, capsys):
    code, _, err = run_main(["collect", "polyenvs/Nope-v0", "--out", str(tmp_path / "d")], capsys)
    assert code == 2 and "unknown environment id" in err and len(err.strip().splitlines()) == 1


def test_the_robot_view_acts_for_its_robot_alone(tmp_path, monkeypatch):
    """The recovered swarm is driven by the agent for the named robot: other actions change that robot's episode,
    and its teammates keep their own policy's."""
    request = CollectRequest("polyenvs.swarm.corridor_v0", "paper", episodes=1, out_dir=tmp_path / "d",
                             env_kwargs={"max_cycles": 15})  # fmt: skip
    identifier = collect(request)
    dataset = _load(tmp_path / "d", identifier, monkeypatch)
    env = dataset.recover_environment()
    try:
        obs, _ = env.reset(seed=0, options={"robot": "robot_1"})
        observations = [obs]
        for _ in range(14):
            obs, _, terminated, truncated, _ = env.step(np.ones(2, dtype=np.float32))  # straight ahead, full power
            observations.append(obs)
        robots = [m["options"]["robot"] for m in dataset.storage.get_episode_metadata(range(dataset.total_episodes))]
        recorded = list(dataset.iterate_episodes())[robots.index("robot_1")]
        assert np.array_equal(observations[0], recorded.observations[0])
        assert not np.array_equal(np.stack(observations), recorded.observations[: len(observations)])
        with pytest.raises(ValueError, match="robot"):
            env.reset(seed=0, options={"robot": "robot_9"})
    finally:
        env.close()
