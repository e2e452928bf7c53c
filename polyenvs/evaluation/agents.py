"""The trained agents on the leaderboard: where the committed ones are, and each as an :class:`Agent`.

A committed agent is a training directory (``model.zip``, optional ``vecnormalize.pkl``, ``run.json``) at
``benchmarks/agents/<env id with / as __>/<algo>/seed<N>/`` (:func:`find_agents`), one per training seed; an agent
named on the command line is any training directory whose ``run.json`` names its environment
(:func:`agent_from_path`). Either is loaded against its environment before any evaluation (:func:`check_agent`),
and its results name its model by SHA-256 (:func:`agent_checksum`). A tuned hand baseline (``polyenvs tune``'s
directory, :mod:`baselines.tuned`) is an agent of algorithm :data:`TUNED` the same way, one per tuning seed at
``<env>/tuned_<baseline>/seed<N>/``: its row sits beside the baseline's, and the verdict compares agents with it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from baselines.tuned import TUNED_FILE, is_tuned_path, read_tuned, tuned_checksum
from polyenvs.errors import InputError
from polyenvs.evaluation.episodes import make_agent, make_env
from polyenvs.evaluation.protocol import old_versions_quietly
from polyenvs.registry import bare_id, slug

__all__ = [
    "DEFAULT_AGENTS_DIR",
    "TUNED",
    "Agent",
    "agent_checksum",
    "agent_from_path",
    "agent_name",
    "agents_line",
    "check_agent",
    "checkout_dirs",
    "default_agents_dirs",
    "find_agents",
    "training_layouts",
    "unfinished",
]

#: The algorithm of a tuned hand baseline's agent (its directory ``tuned_<baseline>``).
TUNED = "tuned"
#: Where committed trained agents live (relative to the repository root, like the reference results).
DEFAULT_AGENTS_DIR = Path("benchmarks/agents")


@dataclass(frozen=True)
class Agent:
    """One trained agent (one training seed) on the leaderboard."""

    env_id: str
    algo: str
    path: str  # the training directory (or .zip), as the results name it
    label: str  # the table row it joins: the algorithm for committed agents, the path for --policy ones
    key: str  # result file name part: agent__<algo>__seed<N>, or agent__<path as a slug>
    seed: int | None = None
    run: dict = field(default_factory=dict, compare=False, hash=False)

    @property
    def name(self) -> str:
        """How progress messages name it: ``ppo seed0``."""
        return agent_name(self.label, self.seed)

    def meta(self) -> dict:
        """What a result document records about the agent (its row, seed and training length)."""
        return {
            "algo": self.algo,
            "label": self.label,
            "training_seed": self.seed,
            "timesteps": self.run.get("timesteps"),
            "requested_timesteps": self.run.get("requested_timesteps"),
            "completed": self.run.get("completed"),
            "training_layouts": training_layouts(self.run),
        }


def unfinished(agent: Agent) -> str:
    """How far an interrupted agent got: its timesteps, or a tuned baseline's trials."""
    run = agent.run
    if agent.algo == TUNED:
        return f"tuned for {run.get('finished_trials')} of {run.get('trials')} trials"
    return f"trained {run.get('timesteps')} of {run.get('requested_timesteps')} requested timesteps"


def training_layouts(run: dict) -> str:
    """The layouts a training run drew its episodes from (its ``env_kwargs``' ``layouts``; "default" where it set
    none, as every run did before ``polyenvs train`` followed the Procgen protocol)."""
    env_kwargs = run.get("env_kwargs")
    layouts = env_kwargs.get("layouts", "default") if isinstance(env_kwargs, dict) else "default"
    return layouts if isinstance(layouts, str) else "default"


def agent_name(label: str, seed: int | None) -> str:
    """How progress and reproduction lines name an agent: ``ppo seed0``, or the label alone without a seed."""
    return f"{label} seed{seed}" if seed is not None else label


def _trained():
    import baselines.trained

    return baselines.trained


def _seed_number(path: Path) -> int:
    match = re.fullmatch(r"seed(\d+)", path.name)
    if match is None:
        raise InputError(f"{path}: agent directories are named seed<N> (the training seed)")
    return int(match.group(1))


#: A directory of agents that start from a hand baseline: ``<algo>_residual_<baseline>`` (a correction of it, where
#: ``polyenvs train --residual`` writes) or ``<algo>_bc_<baseline>`` (cloned from its demonstrations, ``--bc-from``).
_DERIVED_DIR = re.compile(r"(?P<algo>[a-z0-9_]+?)_(?P<how>residual|bc)_(?P<baseline>.+)")


def _algo_dir(path: Path, algos) -> tuple[str, dict[str, str | None]]:
    """``(algorithm, {"residual": baseline or None, "bc": baseline or None})`` an agents directory's name says; for
    a tuned baseline's, ``(TUNED, {"tuned": baseline})``."""
    if path.name in algos:
        return path.name, {"residual": None, "bc": None}
    if path.name.startswith(f"{TUNED}_"):
        return TUNED, {"tuned": path.name.removeprefix(f"{TUNED}_")}
    match = _DERIVED_DIR.fullmatch(path.name)
    if match is None or match["algo"] not in algos:
        raise InputError(
            f"{path}: unknown algorithm directory; known: {', '.join(algos)} (or <algo>_residual_<baseline>, "
            f"<algo>_bc_<baseline>, {TUNED}_<baseline>)"
        )
    return match["algo"], {"residual": None, "bc": None, match["how"]: match["baseline"]}


def _tuned_agent(env_id: str, seed_dir: Path, baseline: str, seed: int) -> Agent:
    """The tuned baseline in ``seed_dir`` (``tuned_<baseline>/seed<N>``), checked against where it sits."""
    try:
        doc = read_tuned(seed_dir)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    for what, found, expected in (
        ("env_id", bare_id(doc["env_id"]), env_id),
        ("policy", doc["policy"], baseline),
        ("seed", doc.get("seed"), seed),
    ):
        if found != expected:
            raise InputError(f"{seed_dir / TUNED_FILE}: {what} is {found!r}, but the directory says {expected!r}")
    label = f"{TUNED}_{baseline}"
    return Agent(env_id, TUNED, str(seed_dir), label, f"agent__{label}__seed{seed}", seed, doc)


def _bases(run: dict) -> dict[str, str | None]:
    """The baseline a run corrects (``residual``) and the one whose demonstrations it cloned (``bc``), or None."""
    residual, bc = run.get("residual"), run.get("bc")
    dataset = bc.get("dataset") if isinstance(bc, dict) else None
    return {
        "residual": residual.get("baseline") if isinstance(residual, dict) else None,
        "bc": dataset.get("policy") if isinstance(dataset, dict) else None,
    }


def find_agents(agents_dir: Path | None, env_id: str) -> list[Agent]:
    """The committed agents of ``env_id``: every ``<agents_dir>/<env>/<algo>/seed<N>/``, by algorithm then seed;
    a residual agent's ``<algo>`` directory is ``<algo>_residual_<baseline>``, one cloned from a baseline's
    demonstrations ``<algo>_bc_<baseline>``, each its own row.

    Each must hold a ``model.zip`` and a ``run.json`` that agrees with where it sits (environment, algorithm,
    seed, the baseline a residual agent corrects, the policy of the demonstrations it cloned); anything else raises :class:`InputError` naming the directory.
    Files (a README) are ignored.
    """
    if agents_dir is None:
        return []
    from baselines.algorithms import ALGOS

    trained = _trained()
    base = Path(agents_dir) / slug(env_id)
    if not base.is_dir():
        return []
    agents = []
    order = {name: i for i, name in enumerate(ALGOS)}  # ppo, dqn, maskable_ppo, sac, td3
    algo_dirs = [p for p in base.iterdir() if p.is_dir() and not p.name.startswith(".")]
    for algo_dir in sorted(algo_dirs, key=lambda p: (order.get(_algo_dir(p, ALGOS)[0], len(order)), p.name)):
        algo, bases = _algo_dir(algo_dir, ALGOS)
        label = algo_dir.name
        seed_dirs = [p for p in algo_dir.iterdir() if p.is_dir() and not p.name.startswith(".")]
        for seed_dir in sorted(seed_dirs, key=lambda p: (_seed_number(p), p.name)):
            seed = _seed_number(seed_dir)
            if algo == TUNED:
                agents.append(_tuned_agent(env_id, seed_dir, str(bases["tuned"]), seed))
                continue
            try:
                _, _, run_file = trained.resolve_model_files(seed_dir)
                if run_file is None:
                    raise trained.TrainedModelError(f"{seed_dir}: no run.json (the leaderboard reads its timesteps)")
                run = trained.read_run_info(run_file)
            except trained.TrainedModelError as exc:
                raise InputError(str(exc)) from None
            for what, found, expected in (
                ("env_id", bare_id(str(run.get("env_id", ""))), env_id),
                ("algo", run.get("algo"), algo),
                ("seed", run.get("seed"), seed),
                ("residual baseline", _bases(run)["residual"], bases["residual"]),
                ("demonstrations' policy", _bases(run)["bc"], bases["bc"]),
            ):
                if found != expected:
                    raise InputError(f"{run_file}: {what} is {found!r}, but the directory says {expected!r}")
            agents.append(Agent(env_id, algo, str(seed_dir), label, f"agent__{label}__seed{seed}", seed, run))
    return agents


def checkout_dirs(relative: Path) -> list[Path]:
    """Where to look for a directory of the repository, in order: ``relative`` to the current directory, then in
    the checkout polyenvs runs from (a clone, or an editable install of one). An installed package does not ship
    the repository's ``benchmarks/`` (16 MB of models): from anywhere else there is only the first."""
    candidates = [Path(relative)]
    root = Path(__file__).resolve().parents[2]
    if (root / "pyproject.toml").is_file() and (root / "polyenvs" / "__init__.py").is_file():
        candidates.append(root / relative)
    return candidates


def default_agents_dirs() -> list[Path]:
    """Where the leaderboard looks for the committed agents: :func:`checkout_dirs` of ``benchmarks/agents``."""
    return checkout_dirs(DEFAULT_AGENTS_DIR)


def agents_line(agents_dir: Path | None, env_ids: list[str], looked: list[Path] | None = None) -> str:
    """One line saying where the trained agents come from and what is there for ``env_ids`` (for the output).

    ``agents_dir`` None: none of ``looked`` exists. Raises :class:`InputError` for a malformed agent directory.
    """
    if agents_dir is None:
        where = " and ".join(str(Path(p).absolute()) for p in dict.fromkeys(looked or [DEFAULT_AGENTS_DIR]))
        return (
            f"trained agents: none found (no {where}; the committed agents are in the polyenvs repository's "
            f"{DEFAULT_AGENTS_DIR}/, which an installed package does not include: run from a checkout or pass "
            "--agents-dir DIR)"
        )
    found = {env_id: find_agents(agents_dir, env_id) for env_id in env_ids}
    agents = [a for group in found.values() for a in group]
    where = Path(agents_dir).absolute()
    if not agents:
        return (
            f"trained agents: none in {where} for the {len(env_ids)} environment{'s' if len(env_ids) != 1 else ''} "
            "run (it has no <env id with / as __>/<algo>/seed<N>/ directory for them)"
        )
    algos = ", ".join(dict.fromkeys(a.algo for a in agents))
    envs = sum(1 for group in found.values() if group)
    return (
        f"trained agents: {len(agents)} ({algos}) for {envs} of {len(env_ids)} environment"
        f"{'s' if len(env_ids) != 1 else ''}, from {where}"
    )


def agent_from_path(path: str) -> Agent:
    """An extra agent named on the command line (``--policy PATH``): its run.json (a tuned baseline's tuned.json)
    must name its environment."""
    slug = re.sub(r"[^A-Za-z0-9._-]+", "_", str(path)).strip("_.") or "model"
    if is_tuned_path(path):
        try:
            doc = read_tuned(path)
        except ValueError as exc:
            raise InputError(str(exc)) from None
        seed = doc.get("seed") if isinstance(doc.get("seed"), int) else None
        return Agent(bare_id(doc["env_id"]), TUNED, str(path), str(path), f"agent__{slug}", seed, doc)
    trained = _trained()
    try:
        model_file, _, run_file = trained.resolve_model_files(path)
        run = trained.read_run_info(run_file)
    except trained.TrainedModelError as exc:
        raise InputError(str(exc)) from None
    env_id = run.get("env_id")
    if not env_id:
        raise InputError(f"{path}: the leaderboard needs the run.json beside the model to know its environment")
    algo = run.get("algo") or "model"
    seed = run.get("seed") if isinstance(run.get("seed"), int) else None
    return Agent(bare_id(str(env_id)), algo, str(path), str(path), f"agent__{slug}", seed, run)


def check_agent(agent: Agent, envs: dict) -> str:
    """Load the agent against its environment (spaces, run.json) before any evaluation; returns its checksum.
    ``envs`` (env id -> environment) keeps the environments built for the caller to reuse and close."""
    if agent.env_id not in envs:
        with old_versions_quietly():
            envs[agent.env_id] = make_env(agent.env_id)
    policy = make_agent(agent.path, agent.env_id, envs[agent.env_id])
    return policy.describe()["sha256"]


def agent_checksum(agent: Agent) -> str:
    """The SHA-256 of ``agent``'s model files (the model and its normalisation statistics), without loading them:
    a result names the model it evaluated by it. A tuned baseline's is of its baseline and parameters."""
    if agent.algo == TUNED:
        return tuned_checksum(agent.run)
    trained = _trained()
    model_file, normalize_file, _ = trained.resolve_model_files(agent.path)
    return trained.model_checksum(model_file, normalize_file)
