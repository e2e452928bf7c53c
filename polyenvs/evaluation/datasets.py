"""Demonstration datasets in Minari's format: a policy's seeded episodes, written and read back (``polyenvs collect``).

:func:`collect` runs the policy a :class:`CollectRequest` names (any name ``polyenvs evaluate`` takes:
``"random"``, a hand baseline, ``"paper"``, a trained model's path) on seeds ``seed, seed + 1, ...`` and writes one
`Minari <https://minari.farama.org>`_ dataset (needs ``polyenvs[collect]``) into a directory of its own, laid out as
a Minari datasets root: ``DIR/polyenvs/<env>/<policy>-v0/data/``. Load it with ``MINARI_DATASETS_PATH=DIR`` and
``minari.load_dataset("polyenvs/<env>/<policy>-v0")``, or with :func:`load_dataset` (which takes DIR itself).
Nothing is written into Minari's default root (``~/.minari``).

A dataset holds the environment's spec (``recover_environment()`` rebuilds it, with the same keywords), each
episode's seed, Minari's metadata (``algorithm_name``: the policy's name; ``code_permalink``: polyenvs' version and
git commit; ``ref_min_score`` / ``ref_max_score``: the mean return of random and of the paper's algorithm) and
polyenvs' own under the ``polyenvs`` key (the id, keywords, policy and its description, seeds, where the reference
scores come from).

Reference scores are read from the committed reference results (``benchmarks/results/``, 50 episodes from seed
1000: :func:`polyenvs.evaluation.results.load_result`) when they exist for the id with the default keywords; otherwise
they are evaluated here, :data:`REFERENCE_EPISODES` episodes from :data:`polyenvs.evaluation.protocol.EVAL_SEED`.

Minari stores Gymnasium environments only; a PettingZoo swarm becomes a per-robot dataset: every robot's
trajectory of a swarm episode is an episode of its own (its seed, and ``options={"robot": name}``), and the
environment spec is :class:`RobotView`, the swarm as one robot sees it, its teammates driven by the dataset's
policy. ``recover_environment().reset(seed=s, options={"robot": r})`` then replays robot ``r``'s episode bit for bit
with a deterministic hand baseline; a trained model's action for one robot alone can differ from its action in the
swarm's batch in the last bits (torch's kernels depend on the batch size: 2e-7 measured, on the committed corridor
agent), so its replay follows the recorded episode to float32 rounding and may drift from there; random teammates
draw their actions in another order than the whole swarm did.
"""

from __future__ import annotations

import contextlib
import glob
import os
import re
import shutil
import warnings
from collections.abc import Callable, Iterator
from dataclasses import KW_ONLY, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from polyenvs.core.extras import install_hint
from polyenvs.errors import InputError, check_count
from polyenvs.evaluation.episodes import make_agent, make_env
from polyenvs.evaluation.rollout import SharedPolicy, agent_spaces, is_parallel, policy_action
from polyenvs.files import temp_path_for
from polyenvs.limits import MAX_EPISODES, MAX_SEED
from polyenvs.registry import bare_id

__all__ = [
    "DATASET_FORMAT",
    "REFERENCE_EPISODES",
    "CollectRequest",
    "Demonstrations",
    "RobotView",
    "check_out_dir",
    "collect",
    "dataset_id",
    "find_dataset",
    "load_dataset",
    "load_demonstrations",
]

#: Minari's storage format for the datasets written here (HDF5, Minari's default; h5py comes with the extra).
DATASET_FORMAT = "hdf5"
#: Episodes of random and of the paper's algorithm evaluated for the reference scores when no committed result
#: fits (another keyword set, or an installed copy without benchmarks/).
REFERENCE_EPISODES = 10
#: How the datasets name their author (Minari asks for one).
AUTHOR = "The polyenvs authors"


def _minari():
    try:
        import minari
    except ImportError:
        raise InputError(f"datasets need minari and h5py: {install_hint('collect')}") from None
    return minari


def _env_name(env_id: str) -> str:
    """``APLiteCorridor-v0`` for ``polyenvs/APLiteCorridor-v0``, ``corridor_v0`` for ``polyenvs.swarm.corridor_v0``."""
    return bare_id(env_id).split("/")[-1].split(".")[-1]


def dataset_id(env_id: str, policy_name: str) -> str:
    """Minari's id of a dataset: ``polyenvs/<env>/<policy>-v0`` (dots and other characters as ``_``)."""
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in policy_name)
    return f"polyenvs/{_env_name(env_id)}/{safe}-v0"


def _policy_name(env_id: str, policy: str, description: dict) -> str:
    """The collecting policy's name: the baseline's (``paper`` resolved), or ``trained_<algo>`` for a model."""
    from baselines import paper_policy

    if "algo" in description and "path" in description:
        return f"trained_{description['algo']}"
    return paper_policy(env_id) or policy if policy == "paper" else policy


# ------------------------------------------------------------------------------------------------ the swarm's view


class RobotView(gym.Env):
    """One robot of a PettingZoo swarm as a Gymnasium environment: the environment of a per-robot dataset.

    The agent acts for one robot; its teammates are driven by ``teammates`` (a policy name, as ``polyenvs
    evaluate`` takes it), one shared policy as in :func:`polyenvs.evaluation.rollout.run_episode`. The episode ends
    for the agent when its robot leaves the swarm (``terminated`` or ``truncated`` as the swarm says), or truncated
    when the swarm's episode ends without it.

    Args:
        module: the swarm's module path (``"polyenvs.swarm.corridor_v0"``).
        teammates: the policy of the other robots (default ``"paper"``).
        robot: the robot the agent drives unless ``reset(options={"robot": name})`` names another (default: the
            first).
        env_kwargs: the swarm's keyword arguments.
        policy_kwargs: the teammates' policy parameters.
    """

    metadata = {"render_modes": []}

    def __init__(self, module: str, teammates: str = "paper", robot: str | None = None, env_kwargs=None,
                 policy_kwargs=None):  # fmt: skip
        self.swarm = make_env(module, env_kwargs)
        if not is_parallel(self.swarm):
            raise ValueError(f"module must name a PettingZoo swarm, got {module!r}")
        self.robot = self._check_robot(robot if robot is not None else self.swarm.possible_agents[0])
        self.observation_space, self.action_space = agent_spaces(self.swarm)
        self.teammates = make_agent(teammates, module, self.swarm, policy_kwargs=policy_kwargs)
        self._module, self._teammates_name, self._shared = module, teammates, None
        self._observations: dict = {}
        self._infos: dict = {}

    def _check_robot(self, robot) -> str:
        if robot not in self.swarm.possible_agents:
            raise ValueError(f"robot must be one of {self.swarm.possible_agents}, got {robot!r}")
        return robot

    def reset(self, *, seed=None, options=None):
        robot = self._check_robot((options or {}).get("robot", self.robot))  # checked before anything changes
        super().reset(seed=seed)
        self.robot = robot
        self._observations, self._infos = self.swarm.reset(seed=seed)
        self._shared = SharedPolicy(self.swarm, self.teammates)
        return self._observations[robot], self._infos.get(robot, {})

    def step(self, action):
        """Step the swarm with ``action`` for this robot and the shared policy's actions for its teammates; return
        this robot's observation, reward, terminated, truncated and info (Gymnasium's step)."""
        if self.robot not in self.swarm.agents:
            raise RuntimeError("the robot's episode has ended: call reset()")
        # the shared policy acts for every live robot, as in the whole swarm's rollout (a trained model's batch of
        # the same rows gives the same bits), and the agent's action replaces its robot's
        live = {a: self._observations[a] for a in self.swarm.agents}
        actions = {**self._shared.act(live, self._infos), self.robot: action}
        self._observations, rewards, terminations, truncations, self._infos = self.swarm.step(actions)
        terminated = bool(terminations.get(self.robot, False))
        truncated = bool(truncations.get(self.robot, False)) or (not terminated and not self.swarm.agents)
        return (self._observations[self.robot], float(rewards.get(self.robot, 0.0)), terminated, truncated,
                self._infos.get(self.robot, {}))  # fmt: skip

    def close(self):
        self.swarm.close()


def _robot_view_spec(module: str, policy: str, env_kwargs: dict, policy_kwargs: dict) -> gym.envs.registration.EnvSpec:
    """An (unregistered) spec of :class:`RobotView` that ``gym.make`` builds and Minari stores as JSON."""
    kwargs = {"module": module, "teammates": policy, "env_kwargs": env_kwargs,
              "policy_kwargs": policy_kwargs}  # fmt: skip
    return gym.envs.registration.EnvSpec(
        id=f"polyenvs/{_env_name(module)}-robot", entry_point="polyenvs.evaluation.datasets:RobotView", kwargs=kwargs,
        disable_env_checker=True,
    )  # fmt: skip


# ---------------------------------------------------------------------------------------------------- rollouts


@dataclass
class _Trajectory:
    """One episode of one actor: observations (one more than actions), actions, rewards, how it ended."""

    seed: int
    observations: list
    actions: list
    rewards: list
    terminated: bool = False
    options: dict | None = None

    def buffer(self, index: int):
        from minari.data_collector.episode_buffer import EpisodeBuffer

        steps = len(self.actions)
        terminations = [False] * steps
        truncations = [False] * steps
        (terminations if self.terminated else truncations)[-1] = True
        return EpisodeBuffer(
            id=index, seed=self.seed, options=self.options, observations=np.stack(self.observations),
            actions=np.stack(self.actions), rewards=np.asarray(self.rewards, dtype=np.float64),
            terminations=terminations, truncations=truncations,
        )  # fmt: skip


def _single_episode(env, agent, seed: int) -> list[_Trajectory]:
    """A Gymnasium episode, step by step as :func:`polyenvs.evaluation.rollout.run_episode` runs it."""
    obs, info = env.reset(seed=seed)
    trajectory = _Trajectory(seed, [obs], [], [])
    state, start = None, True
    while True:
        action, state = policy_action(agent, obs, state, start, info)
        obs, reward, terminated, truncated, info = env.step(action)
        trajectory.observations.append(obs)
        trajectory.actions.append(np.asarray(action))
        trajectory.rewards.append(float(reward))
        start = False
        if terminated or truncated:
            trajectory.terminated = bool(terminated)
            return [trajectory]


def _swarm_episode(env, agent, seed: int) -> list[_Trajectory]:
    """A swarm episode (:func:`polyenvs.evaluation.rollout.run_episode`'s), cut into one trajectory per robot."""
    observations, infos = env.reset(seed=seed)
    shared = SharedPolicy(env, agent)
    robots = {a: _Trajectory(seed, [observations[a]], [], [], options={"robot": a}) for a in env.agents}
    while env.agents:
        actions = shared.act({a: observations[a] for a in env.agents}, infos)
        observations, rewards, terminations, truncations, infos = env.step(actions)
        for name, action in actions.items():
            robot = robots[name]
            robot.observations.append(observations[name])
            robot.actions.append(np.asarray(action))
            robot.rewards.append(float(rewards.get(name, 0.0)))
            robot.terminated = bool(terminations.get(name, False))
    return [robots[a] for a in env.possible_agents if a in robots and robots[a].actions]


def _rollouts(env, agent, seeds: list[int], on_episode: Callable[[], None] | None) -> list[_Trajectory]:
    run = _swarm_episode if is_parallel(env) else _single_episode
    trajectories = []
    for seed in seeds:
        trajectories += run(env, agent, seed)
        if on_episode is not None:
            on_episode()
    return trajectories


# ------------------------------------------------------------------------------------------- reference scores


def _reference_return(env_id: str, policy: str, env_kwargs: dict, results_dir: Path | None) -> tuple[float, str]:
    """The mean return of ``policy`` (``"random"`` or the paper's baseline) and where it comes from."""
    from polyenvs.evaluation.protocol import EVAL_SEED
    from polyenvs.evaluation.results import load_result, result_path

    if results_dir is not None and not env_kwargs:
        path = result_path(results_dir, env_id, policy)
        doc, _ = load_result(path, env_id, policy)
        if doc is not None:
            return float(doc["summary"]["return"]), f"{path} ({doc['n_episodes']} episodes)"
    from polyenvs.evaluation.episodes import evaluate

    doc = evaluate(env_id, policy, episodes=REFERENCE_EPISODES, seed=EVAL_SEED, env_kwargs=env_kwargs)
    return float(doc["summary"]["return"]), f"evaluated: {REFERENCE_EPISODES} episodes from seed {EVAL_SEED}"


def _reference_scores(env_id: str, env_kwargs: dict, results_dir: Path | None) -> dict[str, Any]:
    from baselines import paper_policy

    paper = paper_policy(env_id)
    if paper is None:
        return {}
    low, low_source = _reference_return(env_id, "random", env_kwargs, results_dir)
    high, high_source = _reference_return(env_id, paper, env_kwargs, results_dir)
    return {"ref_min_score": low, "ref_max_score": high,
            "sources": {"ref_min_score": f"random: {low_source}", "ref_max_score": f"{paper}: {high_source}"}}  # fmt: skip


# ---------------------------------------------------------------------------------------------------- writing


def check_out_dir(out_dir: str | os.PathLike, overwrite: bool, flag: str = "out_dir") -> None:
    """``out_dir`` can be written (absent, empty, or ``overwrite``; its folder writable); else an InputError."""
    from polyenvs.files import check_writable_directory

    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{flag} {out_dir}: is a file")
    if out_dir.is_dir() and any(out_dir.iterdir()) and not overwrite:
        again = "--overwrite" if flag.startswith("--") else "overwrite=True"
        raise InputError(f"{flag} {out_dir}: exists and is not empty; choose another directory or {again}")
    check_writable_directory(out_dir.parent, flag, shown=out_dir)


@contextlib.contextmanager
def _minari_root(root: Path) -> Iterator[None]:
    """Minari writes under ``$MINARI_DATASETS_PATH``: point it at ``root`` for the block, then restore it."""
    saved = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(Path(root).absolute())  # a relative one ends up joined twice
    try:
        yield
    finally:
        if saved is None:
            del os.environ["MINARI_DATASETS_PATH"]
        else:
            os.environ["MINARI_DATASETS_PATH"] = saved


#: The lock file of a run's work directory: held while the run lives (the kernel drops it when the run dies).
_WORK_LOCK = ".collect.lock"


def _hold_lock(lock_file: Path) -> int | None:
    """A descriptor holding ``lock_file``'s exclusive lock (the file created if need be), or ``None`` if another
    process holds it, its directory is gone, or the system has no such locks (Windows)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: no locks, so no telling a live run's directory from a dead one
        return None
    try:
        fd = os.open(lock_file, os.O_RDWR | os.O_CREAT, 0o666)
    except FileNotFoundError:  # removed meanwhile
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def _remove_abandoned(out_dir: Path) -> None:
    """Remove the work directories beside ``out_dir`` that runs killed outright (kill -9) left behind: those whose
    lock no process holds. Runs before the lock existed left none in theirs, which counts as abandoned too."""
    name = re.compile(rf"\.{re.escape(out_dir.name)}\.[0-9a-f]{{8}}\.tmp")  # files.temp_path_for's names
    for path in out_dir.parent.glob(f".{glob.escape(out_dir.name)}.*.tmp"):
        if not name.fullmatch(path.name) or path.is_symlink() or not path.is_dir():
            continue
        fd = _hold_lock(path / _WORK_LOCK)
        if fd is not None:
            shutil.rmtree(path, ignore_errors=True)
            os.close(fd)


@contextlib.contextmanager
def _work_dir(out_dir: Path) -> Iterator[Path]:
    """A new hidden directory beside ``out_dir`` (``.NAME.<random>.tmp``) for this run's files, locked while the
    block runs and removed after it, even when it raises; the directories of killed runs are removed first."""
    out_dir.parent.mkdir(parents=True, exist_ok=True)  # check_out_dir accepts a folder it can create
    _remove_abandoned(out_dir)
    work = temp_path_for(out_dir)
    work.mkdir()
    fd = _hold_lock(work / _WORK_LOCK)
    try:
        yield work
    finally:
        shutil.rmtree(work)
        if fd is not None:
            os.close(fd)


def _replace_dir(new: Path, out_dir: Path, work: Path) -> None:
    """Move the finished ``new`` onto ``out_dir``; an old ``out_dir`` goes into ``work``, removed with it."""
    if out_dir.exists():
        os.replace(out_dir, work / "replaced")
    os.replace(new, out_dir)


@dataclass(frozen=True)
class CollectRequest:
    """One dataset for :func:`collect`, each setting named once: its field, default and meaning below.

    ``CollectRequest("polyenvs/APLiteCorridor-v0", "paper", episodes=200, out_dir="runs/demos")``; ``polyenvs
    collect`` builds one from its flags. The counts are checked when the request is made (InputError naming the
    field); the environment, the policy and ``out_dir`` by :func:`collect`, before any episode runs.
    """

    #: A Gymnasium id or a PettingZoo module path (a per-robot dataset).
    env_id: str
    #: Any name :func:`polyenvs.evaluation.episodes.make_agent` takes (a trained model's path too).
    policy: str = "paper"
    _: KW_ONLY  # the rest by name only: two settings of one type cannot swap places unseen
    #: Episodes, seeded ``seed, seed + 1, ...`` (swarm episodes for a swarm, one dataset episode per robot of each).
    episodes: int = 10
    #: The first episode's seed.
    seed: int = 0
    #: The directory to write (a Minari datasets root holding this one dataset); it must not exist or be empty,
    #: unless ``overwrite``.
    out_dir: Path = Path("dataset")
    #: The environment's keyword arguments (stored in the spec).
    env_kwargs: dict[str, Any] | None = None
    #: The policy's parameters.
    policy_kwargs: dict[str, Any] | None = None
    #: Replace ``out_dir``.
    overwrite: bool = False
    #: The committed reference results (see the module docstring), or ``None`` to evaluate them here.
    results_dir: Path | None = None
    #: Called after each episode (progress bars).
    on_episode: Callable[[], None] | None = None

    def __post_init__(self):
        episodes = check_count("episodes", self.episodes, 1, MAX_EPISODES)
        seed = check_count("seed", self.seed, 0, MAX_SEED)
        if seed + episodes - 1 > MAX_SEED:
            raise InputError(f"seed + episodes - 1 must be <= {MAX_SEED}, got {seed + episodes - 1}")
        checked = {
            "episodes": episodes,
            "seed": seed,
            "out_dir": Path(self.out_dir),
            "env_kwargs": dict(self.env_kwargs or {}),  # the request's own copies: the caller's are not kept
            "policy_kwargs": dict(self.policy_kwargs or {}),
            "results_dir": Path(self.results_dir) if self.results_dir is not None else None,
        }
        for name, value in checked.items():  # stored once all passed: a request that raises was never made
            object.__setattr__(self, name, value)


def collect(request: CollectRequest) -> str:
    """Run ``request.policy`` for ``request.episodes`` seeded episodes and write them as a Minari dataset into
    ``request.out_dir``; return the dataset's Minari id.

    Raises:
        InputError: before any episode runs, for anything the caller got wrong.
    """
    check_out_dir(request.out_dir, request.overwrite)
    _minari()  # its install hint before any episode runs
    dataset = _gather(request)
    _write(dataset, request.out_dir)
    return dataset.identifier


@dataclass
class _Dataset:
    """What :func:`collect` gathered, ready to write: the episodes, the spec and spaces, the metadata."""

    identifier: str
    trajectories: list[_Trajectory]
    spec: gym.envs.registration.EnvSpec
    observation_space: gym.Space
    action_space: gym.Space
    #: polyenvs' own metadata (stored under the ``polyenvs`` key).
    metadata: dict[str, Any]
    #: Minari's ``ref_min_score`` and ``ref_max_score``, if the id has a paper's baseline.
    references: dict[str, float]


def _gather(request: CollectRequest) -> _Dataset:
    """Run the request's episodes and describe them (the reference scores read or evaluated)."""
    env_kwargs, policy_kwargs, policy = request.env_kwargs or {}, request.policy_kwargs or {}, request.policy
    env = make_env(request.env_id, env_kwargs)
    env_id = bare_id(request.env_id)
    try:
        agent = make_agent(policy, env_id, env, seed=request.seed, policy_kwargs=policy_kwargs)
        description = agent.describe()
        name = _policy_name(env_id, os.fspath(policy), description)
        identifier = dataset_id(env_id, name)
        seeds = list(range(request.seed, request.seed + request.episodes))
        trajectories = _rollouts(env, agent, seeds, request.on_episode)
        parallel = is_parallel(env)
        # a trained model's path made absolute, so that the recovered swarm finds its teammates from anywhere
        teammates = str(Path(policy).absolute()) if "path" in description else os.fspath(policy)
        spec = _robot_view_spec(env_id, teammates, env_kwargs, policy_kwargs) if parallel else env.spec
        observation_space, action_space = agent_spaces(env)
    finally:
        env.close()
    references = _reference_scores(env_id, env_kwargs, request.results_dir)
    metadata = {
        "env_id": env_id, "env_kwargs": env_kwargs, "kind": "per-robot" if parallel else "gymnasium",
        "policy": os.fspath(policy), "policy_name": name, "policy_kwargs": policy_kwargs,
        "policy_description": description, "seeds": seeds, "reference_scores": references.pop("sources", {}),
    }  # fmt: skip
    return _Dataset(
        identifier=identifier, trajectories=trajectories, spec=spec, observation_space=observation_space,
        action_space=action_space, metadata=metadata, references=references,
    )  # fmt: skip


def _write(dataset: _Dataset, out_dir: Path) -> None:
    """Create ``dataset`` in a hidden work directory beside ``out_dir`` (:func:`_work_dir`), then rename it into
    place."""
    from polyenvs.evaluation.results import provenance

    minari = _minari()
    facts = provenance()
    commit = facts["git_commit"]
    version = facts["versions"]["polyenvs"]
    metadata = dataset.metadata
    with _work_dir(out_dir) as work:
        root = work / "dataset"
        with _minari_root(root), warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # Minari's notes on fields we leave out (author_email)
            written = minari.create_dataset_from_buffers(
                dataset_id=dataset.identifier,
                buffer=[t.buffer(i) for i, t in enumerate(dataset.trajectories)],
                env=dataset.spec,
                algorithm_name=metadata["policy_name"],
                author=AUTHOR,
                code_permalink=f"polyenvs {version}" + (f", git commit {commit}" if commit else ""),
                observation_space=dataset.observation_space,
                action_space=dataset.action_space,
                description=f"{metadata['policy_name']} on {metadata['env_id']}: {len(metadata['seeds'])} seeded "
                f"episodes ({metadata['kind']}), written by polyenvs collect",
                data_format=DATASET_FORMAT,
                requirements=[f"polyenvs=={version}"],
                **dataset.references,
            )
            written.storage.update_metadata({"polyenvs": {**metadata, "versions": facts["versions"]}})
        _replace_dir(root, out_dir, work)


# ---------------------------------------------------------------------------------------------------- reading


def find_dataset(path: str | os.PathLike) -> tuple[Path, str]:
    """``(root, dataset id)`` of the one dataset under ``path``: a directory :func:`collect` wrote (a datasets
    root), a dataset's own directory, or its ``data`` directory; else an :class:`InputError`."""
    path = Path(path)
    if not path.is_dir():
        raise InputError(f"{path}: no such dataset directory")
    found = sorted({p.parent.parent for p in path.glob("**/data/metadata.json")})
    if (path / "metadata.json").is_file():
        found = [path.parent]
    if len(found) != 1:
        what = "no Minari dataset" if not found else f"{len(found)} Minari datasets"
        raise InputError(f"{path}: holds {what}; give the directory polyenvs collect wrote")
    dataset_dir = found[0]
    metadata = _read_metadata(dataset_dir / "data")
    identifier = metadata.get("dataset_id")
    if not isinstance(identifier, str):
        raise InputError(f"{dataset_dir}: its metadata.json has no dataset_id")
    root = dataset_dir
    for _ in identifier.split("/"):
        root = root.parent
    return root, identifier


def _read_metadata(data_dir: Path) -> dict:
    import json

    try:
        metadata = json.loads((data_dir / "metadata.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"{data_dir}: cannot read its metadata.json ({exc})") from None
    if not isinstance(metadata, dict):
        raise InputError(f"{data_dir}: its metadata.json is not an object")
    return metadata


def load_dataset(path: str | os.PathLike):
    """The Minari dataset under ``path`` (see :func:`find_dataset`), loaded with ``minari.load_dataset``."""
    minari = _minari()
    root, identifier = find_dataset(path)
    with _minari_root(root):
        try:
            return minari.load_dataset(identifier)
        except (OSError, ValueError, KeyError) as exc:
            raise InputError(f"{path}: cannot load the dataset {identifier} ({exc})") from None


@dataclass(frozen=True)
class Demonstrations:
    """A dataset's episodes as arrays, for behaviour cloning.

    ``episodes`` holds ``(observations, actions, rewards)`` per episode (one more observation than actions);
    ``info`` is the dataset's ``polyenvs`` metadata plus its ``path``, ``dataset_id`` and episode count.
    """

    episodes: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
    observation_space: gym.Space
    action_space: gym.Space
    info: dict

    @property
    def steps(self) -> int:
        return sum(len(actions) for _, actions, _ in self.episodes)


def load_demonstrations(path: str | os.PathLike) -> Demonstrations:
    """The episodes of the dataset under ``path``; an :class:`InputError` if it is not a polyenvs dataset."""
    dataset = load_dataset(path)
    facts = dataset.storage.metadata.get("polyenvs")
    if not isinstance(facts, dict) or "env_id" not in facts:
        raise InputError(f"{path}: not a dataset polyenvs collect wrote (no polyenvs metadata)")
    episodes = [
        (np.asarray(e.observations), np.asarray(e.actions), np.asarray(e.rewards, dtype=np.float64))
        for e in dataset.iterate_episodes()
    ]
    if not episodes:
        raise InputError(f"{path}: the dataset has no episodes")
    info = {**facts, "path": str(path), "dataset_id": dataset.spec.dataset_id, "episodes": len(episodes)}
    return Demonstrations(episodes, dataset.observation_space, dataset.action_space, info)
