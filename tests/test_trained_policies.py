"""Trained Stable-Baselines3 models as policies: evaluate, record and the leaderboard take a model's path.

The models are trained here, for a few hundred steps, into training directories written by hand after the contract
of ``polyenvs train`` (``model.zip``, ``vecnormalize.pkl``, ``run.json``), so these tests depend on nothing but
Stable-Baselines3. Also: the stratified bootstrap interval of the leaderboard on synthetic data.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import polyenvs
import polyenvs.evaluation.episodes
import polyenvs.evaluation.page
import polyenvs.evaluation.results
import polyenvs.evaluation.run
import polyenvs.evaluation.table
from polyenvs.cli import main
from polyenvs.evaluation.episodes import evaluate
from polyenvs.evaluation.rollout import policy_action
from polyenvs.evaluation.statistics import interquartile_mean, iqm_with_ci, iqm_with_stratified_ci
from tests.cli_helpers import run_main

sb3 = pytest.importorskip("stable_baselines3")
sb3_contrib = pytest.importorskip("sb3_contrib")

from baselines import make_policy  # noqa: E402
from baselines.trained import TrainedModelError, TrainedPolicy  # noqa: E402

WALL, GOAL = "polyenvs/BuckybotWallFollow-v0", "polyenvs/BuckybotGoal-v0"
WALL_SLUG = "polyenvs__BuckybotWallFollow-v0"
STEPS = 256


def write_run_json(directory: Path, algo: str, seed: int = 0, env_id: str = WALL, **changes) -> None:
    run = {
        "env_id": env_id,
        "algo": algo,
        "seed": seed,
        "timesteps": STEPS,
        "requested_timesteps": STEPS,
        "n_envs": 1,
        "env_kwargs": {},
        "hyperparams": {  # normalize as polyenvs train records it: VecNormalize's arguments, or false
            "normalize": {"norm_obs": True, "norm_reward": True, "gamma": 0.99} if algo == "ppo" else False,
            "policy": "MlpPolicy",
        },
        "command": f"polyenvs train {env_id} --algo {algo} --timesteps {STEPS} --seed {seed}",
        "versions": {"stable_baselines3": sb3.__version__},
        "git_commit": None,
        "wall_clock_s": 1.0,
        "completed": True,
        **changes,
    }
    (directory / "run.json").write_text(json.dumps(run, indent=1))


@pytest.fixture(scope="module")
def ppo_run(tmp_path_factory) -> Path:
    """PPO trained for 256 steps on WallFollow with VecNormalize: model.zip, vecnormalize.pkl, run.json."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    directory = tmp_path_factory.mktemp("ppo_wall") / "seed0"
    directory.mkdir()
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(WALL)]), norm_obs=True, norm_reward=True)
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=128,
        batch_size=64,
        n_epochs=1,
        seed=0,
        policy_kwargs={"net_arch": [16]},
        device="cpu",
    )
    model.learn(STEPS)
    model.save(directory / "model.zip")
    venv.save(directory / "vecnormalize.pkl")
    venv.close()
    write_run_json(directory, "ppo")
    return directory


@pytest.fixture(scope="module")
def maskable_run(tmp_path_factory) -> Path:
    """An untrained MaskablePPO on WallFollow (no normalisation): enough to see that it gets the action masks."""
    from sb3_contrib import MaskablePPO

    directory = tmp_path_factory.mktemp("maskable_wall") / "seed3"
    directory.mkdir()
    env = gym.make(WALL)
    MaskablePPO("MlpPolicy", env, n_steps=64, batch_size=64, seed=3, policy_kwargs={"net_arch": [16]}).save(
        directory / "model.zip"
    )
    env.close()
    write_run_json(directory, "maskable_ppo", seed=3)
    return directory


def assert_one_line_error(code: int, err: str, fragment: str) -> None:
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and fragment in lines[0], err
    assert "Traceback" not in err


def copy_run(source: Path, target: Path, **run_changes) -> Path:
    shutil.copytree(source, target)
    if run_changes:
        run = json.loads((target / "run.json").read_text())
        run.update(run_changes)
        (target / "run.json").write_text(json.dumps(run))
    return target


# ------------------------------------------------------------------------------------------- the policy itself


def test_describe_names_algorithm_seed_timesteps_and_path(ppo_run):
    env = gym.make(WALL)
    policy = make_policy(str(ppo_run), WALL, env.observation_space, env.action_space)
    env.close()
    assert isinstance(policy, TrainedPolicy)
    description = policy.describe()
    assert description["algo"] == "ppo" and description["name"] == "ppo"
    assert description["training_seed"] == 0 and description["timesteps"] == STEPS
    assert description["path"] == str(ppo_run) and description["normalize"] is True
    assert len(description["sha256"]) == 64


def test_predict_normalises_observations_without_updating_the_statistics(ppo_run):
    import pickle

    env = gym.make(WALL)
    policy = make_policy(str(ppo_run), WALL, env.observation_space, env.action_space)
    with open(ppo_run / "vecnormalize.pkl", "rb") as fh:
        stats = pickle.load(fh)
    count = float(policy.normalization.obs_rms.count)
    obs, _ = env.reset(seed=5)
    for _ in range(20):
        action, _ = policy.predict(obs, deterministic=True)
        expected, _ = policy.model.predict(stats.normalize_obs(obs), deterministic=True)
        assert int(action) == int(expected)
        obs, *_ = env.step(action)
    batch = np.stack([obs, obs])  # a batch, as SB3 takes it
    actions, _ = policy.predict(batch)
    assert actions.shape == (2,)
    assert float(policy.normalization.obs_rms.count) == count and policy.normalization.training is False
    env.close()


def test_a_trained_policy_acts_with_one_torch_thread_whatever_the_machine(ppo_run):
    """More torch threads sum a batched forward pass in another order: the committed formation agents' returns
    changed in the 7th digit between 1 and 2 threads and then diverged. Loading a model pins torch to one thread."""
    import torch

    torch.set_num_threads(2)
    env = gym.make(WALL)
    make_policy(str(ppo_run), WALL, env.observation_space, env.action_space)
    env.close()
    assert torch.get_num_threads() == 1


def test_trained_policy_works_with_sb3_evaluate_policy(ppo_run):
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.monitor import Monitor

    env = Monitor(gym.make(WALL))
    policy = make_policy(str(ppo_run), WALL, env.observation_space, env.action_space)
    mean, _ = evaluate_policy(policy, env, n_eval_episodes=1)
    assert math.isfinite(mean)
    env.close()


# --------------------------------------------------------------------------------------------------- evaluate


def test_evaluate_a_training_directory(ppo_run, capsys):
    assert main(["evaluate", WALL, "--policy", str(ppo_run), "--episodes", "2", "--seed", "7", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["policy"] == str(ppo_run) and doc["seeds"] == [7, 8]
    for key in ("wall_distance_error_cm", "perimeter_fraction", "laps", "blocked_tips"):
        assert key in doc["episodes"][0]["metrics"] and key in doc["summary"]
    assert doc["policy_description"]["algo"] == "ppo" and doc["policy_description"]["timesteps"] == STEPS
    # Deterministic actions: the same document again.
    assert main(["evaluate", WALL, "--policy", str(ppo_run), "--episodes", "2", "--seed", "7", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["episodes"] == doc["episodes"]


def test_evaluate_table_names_the_model(ppo_run, capsys):
    assert main(["evaluate", WALL, "--policy", str(ppo_run), "--episodes", "1"]) == 0
    out = capsys.readouterr().out
    assert f"policy: ppo model {ppo_run} (training_seed=0, timesteps={STEPS}, normalize=true)" in out


def test_a_bare_zip_uses_the_run_json_and_statistics_beside_it(ppo_run, capsys):
    assert main(["evaluate", WALL, "--policy", str(ppo_run / "model.zip"), "--episodes", "1", "--json"]) == 0
    by_zip = json.loads(capsys.readouterr().out)
    assert main(["evaluate", WALL, "--policy", str(ppo_run), "--episodes", "1", "--json"]) == 0
    by_dir = json.loads(capsys.readouterr().out)
    assert by_zip["episodes"] == by_dir["episodes"]
    assert by_zip["policy_description"]["training_seed"] == 0 and by_zip["policy_description"]["normalize"]


@pytest.mark.parametrize("fixture, algo", [("ppo_run", "ppo"), ("maskable_run", "maskable_ppo")])
def test_a_bare_zip_without_run_json_detects_its_algorithm(fixture, algo, request, tmp_path, capsys):
    source = request.getfixturevalue(fixture)
    shutil.copy(source / "model.zip", tmp_path / "agent.zip")
    assert main(["evaluate", WALL, "--policy", str(tmp_path / "agent.zip"), "--episodes", "1", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["policy_description"]["algo"] == algo and doc["policy_description"]["normalize"] is False


def test_rl_zoo_layout_finds_its_statistics(ppo_run, tmp_path):
    """RL Zoo saves ``<env>.zip`` and ``<env>/vecnormalize.pkl``."""
    shutil.copy(ppo_run / "model.zip", tmp_path / "BuckybotWallFollow-v0.zip")
    (tmp_path / "BuckybotWallFollow-v0").mkdir()
    shutil.copy(ppo_run / "vecnormalize.pkl", tmp_path / "BuckybotWallFollow-v0" / "vecnormalize.pkl")
    env = gym.make(WALL)
    policy = make_policy(str(tmp_path / "BuckybotWallFollow-v0.zip"), WALL, env.observation_space, env.action_space)
    assert policy.describe()["normalize"] is True
    env.close()


# ------------------------------------------------------------------------------------------------------ masks


def test_maskable_ppo_gets_the_action_masks(maskable_run, monkeypatch):
    from baselines.trained import LeanActor  # MaskablePPO's deterministic predict (tests/test_lean_actor.py)

    seen = []
    real_call = LeanActor.__call__

    def spy(self, observation, action_masks=None):
        action = real_call(self, observation, action_masks)
        seen.append((action_masks, int(action)))
        return action

    monkeypatch.setattr(LeanActor, "__call__", spy)
    doc = evaluate(WALL, str(maskable_run), episodes=2, seed=11)
    assert doc["policy_description"]["action_masks"] is True
    assert len(seen) == sum(e["length"] for e in doc["episodes"])
    for mask, action in seen:
        assert mask is not None and mask.dtype == bool and mask.shape == (3,)
        assert mask[action], (mask, action)  # never a tip into a wall
    assert any(not mask.all() for mask, _ in seen)  # the masks did restrict something


def test_masks_reach_only_policies_that_take_them(ppo_run):
    class Baseline:  # the hand baselines' signature: no action_masks
        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            return 1, state

    class Masked:
        def predict(self, observation, state=None, episode_start=None, deterministic=True, action_masks=None):
            self.masks = action_masks
            return 2, state

    info = {"action_mask": np.array([1, 0, 1], dtype=np.int8)}
    assert policy_action(Baseline(), np.zeros(19), None, True, info)[0] == 1
    masked = Masked()
    assert policy_action(masked, np.zeros(19), None, True, info)[0] == 2
    assert masked.masks.tolist() == [True, False, True]
    assert policy_action(masked, np.zeros(19), None, True, {})[0] == 2 and masked.masks is None


# ------------------------------------------------------------------------------------------------------- record


def test_record_a_trained_model(ppo_run, tmp_path):
    imageio = pytest.importorskip("imageio.v3")
    out = tmp_path / "ppo.gif"
    assert main(["record", WALL, "--policy", str(ppo_run), "--max-steps", "6", "--output", str(out)]) == 0
    frames = imageio.imread(out, index=None)
    assert len(frames) == 7 and frames[0].shape[-1] in (3, 4)
    assert [p.name for p in tmp_path.iterdir()] == ["ppo.gif"]


# ---------------------------------------------------------------------------------------------- bad models


def _bad_model(kind: str, ppo_run: Path, tmp_path: Path) -> tuple[str, str, str]:
    """(env id, --policy value, fragment of the one-line error) for each way a model can be unusable."""
    if kind in ("missing", "missing zip"):
        name = "nowhere.zip" if kind == "missing zip" else "nowhere"
        return WALL, str(tmp_path / name), "no such training directory or model file"
    run = copy_run(ppo_run, tmp_path / "run")
    return _break_model_file(kind, run) or _break_run_files(kind, run, tmp_path)


def _break_model_file(kind: str, run: Path) -> tuple[str, str, str] | None:
    """:func:`_bad_model` for the kinds that spoil ``run``'s model.zip (None for the others)."""
    if kind == "no model in directory":
        (run / "model.zip").unlink()
        return WALL, str(run), "must hold model.zip"
    if kind == "not a zip":
        (run / "model.zip").write_bytes(b"this is not a model")
        return WALL, str(run), "not a Stable-Baselines3 model"
    if kind == "truncated zip":
        data = (run / "model.zip").read_bytes()
        (run / "model.zip").write_bytes(data[: len(data) // 2])
        return WALL, str(run), "not a Stable-Baselines3 model"
    if kind == "zip of something else":
        import zipfile

        with zipfile.ZipFile(run / "model.zip", "w") as archive:
            archive.writestr("hello.txt", "hi")
        return WALL, str(run), "no data or policy.pth"
    return None


def _break_run_files(kind: str, run: Path, tmp_path: Path) -> tuple[str, str, str]:
    """:func:`_bad_model` for the kinds that spoil what lies beside the model (or ask for another environment)."""
    if kind == "another environment":
        return GOAL, str(run), f"trained on {WALL}"
    if kind == "spaces differ":
        (run / "run.json").unlink()
        return GOAL, str(run), "observations are Box(19,), but polyenvs/BuckybotGoal-v0 has Box(22,)"
    if kind == "run.json not JSON":
        (run / "run.json").write_text("{broken")
        return WALL, str(run), "not valid JSON"
    if kind == "unknown algo":
        copy_run(run, tmp_path / "other", algo="rainbow")
        return WALL, str(tmp_path / "other"), "unknown algo 'rainbow'"
    if kind == "wrong algo":
        copy_run(run, tmp_path / "other", algo="dqn")
        return WALL, str(tmp_path / "other"), "cannot load it as dqn"
    if kind == "normalize missing":
        (run / "vecnormalize.pkl").unlink()
        return WALL, str(run), "there is no vecnormalize.pkl"
    if kind == "statistics corrupt":
        (run / "vecnormalize.pkl").write_bytes(b"garbage")
        return WALL, str(run), "vecnormalize.pkl: cannot load it"
    raise AssertionError(kind)


@pytest.mark.parametrize(
    "normalize, requested",
    [
        (True, True),
        (False, False),
        ({}, True),
        ({"norm_obs": True, "gamma": 0.99}, True),
        ({"norm_obs": False, "norm_reward": True}, False),
        ("dict(gamma=0.99)", True),
        ("dict(norm_obs=False, norm_reward=True)", False),
        (None, False),
    ],
)
def test_normalize_forms_in_run_json(normalize, requested, ppo_run, tmp_path):
    """Without vecnormalize.pkl, a run.json that says observations were normalised is refused."""
    run = copy_run(ppo_run, tmp_path / "run", hyperparams={"normalize": normalize})
    (run / "vecnormalize.pkl").unlink()
    env = gym.make(WALL)
    if requested:
        with pytest.raises(TrainedModelError, match="no vecnormalize.pkl"):
            make_policy(str(run), WALL, env.observation_space, env.action_space)
    else:
        assert make_policy(str(run), WALL, env.observation_space, env.action_space).describe()["normalize"] is False
    env.close()


BAD_MODELS = [
    "missing",
    "missing zip",
    "no model in directory",
    "not a zip",
    "truncated zip",
    "zip of something else",
    "another environment",
    "spaces differ",
    "run.json not JSON",
    "unknown algo",
    "wrong algo",
    "normalize missing",
    "statistics corrupt",
]


@pytest.fixture
def no_episodes(monkeypatch):
    def run_episode(*args, **kwargs):
        raise AssertionError("an episode ran before the model was checked")

    monkeypatch.setattr(polyenvs.evaluation.episodes, "run_episode", run_episode)


@pytest.mark.parametrize("kind", BAD_MODELS)
def test_a_bad_model_is_one_line_before_any_episode(kind, ppo_run, tmp_path, capsys, no_episodes):
    env_id, policy, fragment = _bad_model(kind, ppo_run, tmp_path)
    code, out, err = run_main(["evaluate", env_id, "--policy", policy, "--episodes", "1"], capsys)
    assert_one_line_error(code, err, fragment)
    assert out == ""


@pytest.mark.parametrize("kind", ["missing", "not a zip", "spaces differ"])
def test_record_of_a_bad_model_is_one_line_and_writes_nothing(kind, ppo_run, tmp_path, capsys):
    pytest.importorskip("imageio.v3")
    env_id, policy, fragment = _bad_model(kind, ppo_run, tmp_path / "models")
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = run_main(["record", env_id, "--policy", policy, "--output", str(out / "x.gif")], capsys)
    assert_one_line_error(code, err, fragment)
    assert list(out.iterdir()) == []


def test_a_trained_model_takes_no_policy_kwargs(ppo_run, capsys):
    code, _, err = run_main(["evaluate", WALL, "--policy", str(ppo_run), "--policy-kwargs", '{"x": 1}'], capsys)
    assert_one_line_error(code, err, "takes no parameters")


def test_an_action_space_mismatch_is_named(ppo_run):
    env = gym.make(WALL)
    with pytest.raises(TrainedModelError, match=r"actions are Discrete\(3\), but .* has Discrete\(4\)"):
        make_policy(str(ppo_run), WALL, env.observation_space, gym.spaces.Discrete(4))
    env.close()


# -------------------------------------------------------------------------------------------- the leaderboard


@pytest.fixture
def agents_dir(ppo_run, tmp_path) -> Path:
    """Two PPO training seeds committed the way benchmarks/agents/ holds them."""
    root = tmp_path / "agents"
    base = root / WALL_SLUG / "ppo"
    base.mkdir(parents=True)
    copy_run(ppo_run, base / "seed0")
    copy_run(ppo_run, base / "seed1", seed=1, timesteps=2 * STEPS)
    (root / "README.md").write_text("agents")
    return root


def leaderboard_args(tmp_path: Path, agents: Path, *extra: str) -> list[str]:
    return [
        "leaderboard",
        "--only",
        "WallFollow",
        "--agents-dir",
        str(agents),
        "--results-dir",
        str(tmp_path / "results"),
        "--output",
        str(tmp_path / "LEADERBOARD.md"),
        "--jobs",
        "1",
        *extra,
    ]


def test_leaderboard_evaluates_and_aggregates_trained_agents(agents_dir, tmp_path, capsys):
    code, out, err = run_main(leaderboard_args(tmp_path, agents_dir, "--episodes", "2"), capsys)
    assert code == 0, err
    results = tmp_path / "results"
    files = sorted(p.name for p in results.iterdir())
    assert f"{WALL_SLUG}__agent__ppo__seed0.json" in files and f"{WALL_SLUG}__agent__ppo__seed1.json" in files
    assert f"{WALL_SLUG}__wall_follower.json" in files and f"{WALL_SLUG}__random.json" in files
    doc = json.loads((results / f"{WALL_SLUG}__agent__ppo__seed1.json").read_text())
    assert doc["seeds"] == [1000, 1001] and doc["n_episodes"] == 2 and doc["date"]
    assert doc["agent"]["algo"] == "ppo" and doc["agent"]["training_seed"] == 1
    assert doc["policy_description"]["timesteps"] == 2 * STEPS and doc["policy"] == str(
        agents_dir / WALL_SLUG / "ppo" / "seed1"
    )

    text = (tmp_path / "LEADERBOARD.md").read_text()
    assert out == text + "\n"
    header = next(line for line in text.splitlines() if line.startswith("| algo |"))
    columns = [c.strip() for c in header.strip("|").split("|")]
    assert columns[:8] == [
        "algo",
        "env_id",
        "mean_reward",
        "std_reward",
        "n_timesteps",
        "eval_episodes",
        "seeds",
        "IQM [95% CI]",
    ]
    details = text[text.index("| algo |") :]  # RL Zoo's columns, below the headline table
    rows = {r[0]: r for r in ([c.strip() for c in line.strip("|").split("|")] for line in details.splitlines()) if r}
    ppo = dict(zip(columns, rows["ppo"], strict=True))
    assert ppo["n_timesteps"] == "384" and ppo["seeds"] == "2" and ppo["eval_episodes"] == "4"  # mean of 256, 512
    assert re.fullmatch(r"-?\d+\.\d\d \[-?\d+\.\d\d, -?\d+\.\d\d\]", ppo["IQM [95% CI]"])
    assert dict(zip(columns, rows["wall_follower"], strict=True))["seeds"] == "-"
    assert "perimeter_fraction" in columns
    headline = text[text.index("| policy |") : text.index("| algo |")]
    assert "| ppo |" in headline and "| wall_follower |" in headline  # one row per algorithm, beside the baselines

    png = tmp_path / f"LEADERBOARD_{WALL_SLUG}.png"
    assert f"](LEADERBOARD_{WALL_SLUG}.png)" in text and png.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert not [p for p in tmp_path.rglob("*") if ".tmp" in p.name]

    # A re-run reuses every result; a changed model is evaluated again, saying why.
    mtimes = {p.name: p.stat().st_mtime_ns for p in results.iterdir()}
    code, _, err = run_main(leaderboard_args(tmp_path, agents_dir, "--episodes", "2"), capsys)
    assert code == 0 and "ppo seed0: done before" in err
    assert {p.name: p.stat().st_mtime_ns for p in results.iterdir()} == mtimes
    stats = agents_dir / WALL_SLUG / "ppo" / "seed0" / "vecnormalize.pkl"
    with open(stats, "ab") as fh:
        fh.write(b"\x00")  # pickle ignores trailing bytes: a loadable but different file
    code, _, err = run_main(leaderboard_args(tmp_path, agents_dir, "--episodes", "2"), capsys)
    assert code == 0, err
    assert "ppo seed0: redoing" in err and "SHA-256 differs" in err and "ppo seed1: done before" in err

    # Evaluating another environment keeps the agents' rows of this one in the table (stored results).
    code, _, err = run_main(leaderboard_args(tmp_path, agents_dir, "--episodes", "1", "--only", "Goal"), capsys)
    assert code == 0, err
    text = (tmp_path / "LEADERBOARD.md").read_text()
    assert f"| ppo | {WALL} |" in text and f"| goal_seeker | {GOAL} |" in text
    assert (tmp_path / "LEADERBOARD_polyenvs__BuckybotGoal-v0.png").is_file()


def test_agents_found_by_another_path_reuse_their_results(agents_dir, tmp_path, capsys, monkeypatch):
    """The reference names its agents from the checkout (benchmarks/agents/...); the main job run from another
    directory finds the same agents by an absolute path, and must still take their results as theirs."""
    code, _, err = run_main(leaderboard_args(tmp_path, agents_dir, "--episodes", "2"), capsys)
    assert code == 0, err
    monkeypatch.chdir(agents_dir.parent)
    code, _, err = run_main(leaderboard_args(tmp_path, Path(agents_dir.name), "--episodes", "2"), capsys)
    assert code == 0 and "ppo seed0: done before" in err and "ppo seed1: done before" in err, err
    result = tmp_path / "results" / f"{WALL_SLUG}__agent__ppo__seed0.json"
    sha = json.loads(result.read_text())["policy_description"]["sha256"]
    load = polyenvs.evaluation.results.load_result
    assert load(result, WALL, f"/elsewhere/agents/{WALL_SLUG}/ppo/seed0", sha256=sha)[0] is not None
    others = ("polyenvs__BuckybotGoal-v0/ppo/seed0", f"{WALL_SLUG}/maskable_ppo/seed0", f"{WALL_SLUG}/ppo/seed1")
    for other in (f"/elsewhere/agents/{part}" for part in others):
        doc, why = load(result, WALL, other, sha256=sha)  # another directory, row or seed is another agent
        assert doc is None and f"not {WALL} {other}" in why


def test_leaderboard_policy_flag_adds_a_model_by_path(ppo_run, tmp_path, capsys):
    empty = tmp_path / "no_agents"
    empty.mkdir()
    code, out, err = run_main(leaderboard_args(tmp_path, empty, "--episodes", "1", "--policy", str(ppo_run)), capsys)
    assert code == 0, err
    assert f"| {ppo_run} | {WALL} |" in out
    assert any(p.name.startswith(f"{WALL_SLUG}__agent__") for p in (tmp_path / "results").iterdir())

    # A model for an environment that --only leaves out is one line, before any evaluation.
    args = leaderboard_args(tmp_path, empty, "--episodes", "1", "--policy", str(ppo_run))
    args[args.index("WallFollow")] = "Goal"
    code, _, err = run_main(args, capsys)
    assert_one_line_error(code, err, "not among the environments")


@pytest.mark.parametrize(
    "breakage, fragment",
    [
        ("env", "env_id is"),
        ("seed", "seed is"),
        ("algo dir", "unknown algorithm directory"),
        ("seed dir name", "seed<N>"),
        ("no run.json", "no run.json"),
        ("corrupt", "not a Stable-Baselines3 model"),
    ],
)
def test_a_broken_agent_directory_stops_the_leaderboard_before_any_evaluation(
    breakage, fragment, agents_dir, tmp_path, capsys, monkeypatch
):
    def no_evaluation(*args, **kwargs):
        raise AssertionError("an evaluation ran before the agents were checked")

    monkeypatch.setattr(polyenvs.evaluation.run, "evaluate", no_evaluation)
    seed0 = agents_dir / WALL_SLUG / "ppo" / "seed0"
    run = json.loads((seed0 / "run.json").read_text())
    if breakage == "env":
        run["env_id"] = GOAL
        (seed0 / "run.json").write_text(json.dumps(run))
    elif breakage == "seed":
        run["seed"] = 5
        (seed0 / "run.json").write_text(json.dumps(run))
    elif breakage == "algo dir":
        (agents_dir / WALL_SLUG / "ppo").rename(agents_dir / WALL_SLUG / "rainbow")
    elif breakage == "seed dir name":
        seed0.rename(seed0.parent / "best")
    elif breakage == "no run.json":
        (seed0 / "run.json").unlink()
    elif breakage == "corrupt":
        (seed0 / "model.zip").write_bytes(b"not a zip")
    code, _, err = run_main(leaderboard_args(tmp_path, agents_dir, "--episodes", "1"), capsys)
    assert_one_line_error(code, err, fragment)
    assert not (tmp_path / "results").exists() or list((tmp_path / "results").iterdir()) == []


def test_leaderboard_agents_dir_must_exist(tmp_path, capsys):
    code, _, err = run_main(leaderboard_args(tmp_path, tmp_path / "nope", "--episodes", "1"), capsys)
    assert_one_line_error(code, err, "--agents-dir")


# ------------------------------------------------------------------------------------------------- statistics


def test_interquartile_mean_on_known_inputs():
    assert interquartile_mean(range(8)) == pytest.approx(3.5)  # the middle four of 0..7
    assert interquartile_mean([5.0]) == 5.0
    assert interquartile_mean([1, 2, 3, 4, 100]) == pytest.approx(3.0)  # floor(5/4) = 1 cut from each end
    x = np.random.default_rng(0).normal(size=101)
    s = np.sort(x)
    assert interquartile_mean(x) == pytest.approx(s[25:76].mean())  # scipy.stats.trim_mean(x, 0.25)


def test_one_stratum_is_the_plain_bootstrap():
    x = np.random.default_rng(1).exponential(size=40)
    assert iqm_with_stratified_ci([x]) == pytest.approx(iqm_with_ci(x))


def test_stratified_bootstrap_resamples_within_each_run():
    # Each run has one value: resampling within runs keeps one 0 and one 10 in every sample, so the pooled IQM
    # never moves; resampling the pooled episodes would draw (0, 0) and (10, 10) as well.
    iqm, low, high = iqm_with_stratified_ci([np.zeros(10), np.full(10, 10.0)])
    assert iqm == low == high == pytest.approx(5.0)
    pooled = iqm_with_ci(np.r_[np.zeros(10), np.full(10, 10.0)])
    assert pooled[2] - pooled[1] > 1.0


def _true_exponential_iqm() -> float:
    a, b = -math.log(0.75), math.log(4.0)  # quartiles of Exp(1)
    return 2 * ((a + 1) * math.exp(-a) - (b + 1) * math.exp(-b))  # E[X | a < X < b]


def test_stratified_interval_covers_the_true_iqm_in_most_draws():
    true = _true_exponential_iqm()
    rng = np.random.default_rng(2024)
    covered = 0
    for draw in range(200):
        runs = [rng.exponential(size=30) for _ in range(3)]
        _, low, high = iqm_with_stratified_ci(runs, n_boot=500, seed=draw)
        covered += low <= true <= high
    assert covered >= 170, covered  # nominal 95%; the percentile bootstrap of 90 values is a little short


def test_stratified_interval_narrows_with_more_episodes():
    rng = np.random.default_rng(7)

    def mean_width(episodes: int) -> float:
        widths = []
        for _ in range(20):
            _, low, high = iqm_with_stratified_ci([rng.exponential(size=episodes) for _ in range(3)], n_boot=500)
            widths.append(high - low)
        return float(np.mean(widths))

    few, many = mean_width(10), mean_width(160)
    assert many < few / 2.5, (few, many)  # about 1/sqrt(16) = 1/4 in theory


def test_normalised_score_and_rows_for_synthetic_agents():
    def doc(policy, returns, perimeter, agent=None):
        d = {
            "env_id": WALL,
            "policy": policy,
            "episodes": [
                {"seed": 1000 + i, "return": r, "length": 1, "metrics": {"perimeter_fraction": perimeter}}
                for i, r in enumerate(returns)
            ],
            "summary": {},
            "n_episodes": len(returns),
        }
        if agent is not None:
            d["agent"] = agent
        return d

    documents = [
        doc("random", [0.0] * 4, 0.0),
        doc("wall_follower", [10.0] * 4, 0.4),
        doc("a/seed0", [20.0] * 4, 0.6, {"algo": "ppo", "label": "ppo", "training_seed": 0, "timesteps": 1e6}),
        doc("a/seed1", [30.0] * 4, 1.0, {"algo": "ppo", "label": "ppo", "training_seed": 1, "timesteps": 2e6}),
    ]
    rows = polyenvs.evaluation.table.leaderboard_rows(documents)[WALL]
    assert [r["label"] for r in rows] == ["ppo", "wall_follower", "random"]  # ranked by the task score
    ppo = rows[0]
    assert ppo["iqm"] == pytest.approx(25.0)  # the return's IQM, shown beside the score
    assert ppo["score"]["value"] == pytest.approx(0.8) and ppo["normalised"] == pytest.approx(2.0)
    assert ppo["n_timesteps"] == 1.5e6 and ppo["seeds"] == [0, 1] and ppo["episodes"] == 8
    text = polyenvs.evaluation.page.leaderboard_markdown(documents)
    # The run is the unit: its seeds score 0.6 and 1 (each seed's own listed), so the interval spans them.
    assert "| ppo | 0.8 [0.6, 1] | 2.00 | 25.00 [25.00, 25.00] | - | - | 0.6, 1 |" in text
    assert f"| ppo | {WALL} | 25.00 | 5.00 | 1.5M | 8 | 2 | 25.00 [25.00, 25.00] | 0.8 |" in text


def test_committed_agents_directory_layout_is_documented():
    readme = Path(polyenvs.__file__).resolve().parent.parent / "benchmarks" / "agents" / "README.md"
    if not readme.exists():
        pytest.skip("source checkout only")
    assert "seed<N>" in readme.read_text() and "run.json" in readme.read_text()
