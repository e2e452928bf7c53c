"""The Stable-Baselines3 / sb3-contrib algorithms polyenvs knows: one table for training and for loading models.

``polyenvs train`` builds a row's class; :mod:`baselines.trained` loads a saved model with it (the names are those
of run.json and ``benchmarks/agents/<env>/<algo>/``). The classes are imported on use (they import torch).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from gymnasium import spaces

from polyenvs.core.extras import install_hint
from polyenvs.errors import InputError

__all__ = ["ALGOS", "AlgoInfo", "algo_class", "check_action_space", "get_algo"]


@dataclass(frozen=True)
class AlgoInfo:
    name: str
    module: str
    class_name: str
    #: Action space types the algorithm accepts.
    action_spaces: tuple[type[spaces.Space], ...]
    #: How the accepted spaces are described in errors.
    kind: str


#: algorithm name -> its row, in the order tables and searches list them (ppo, dqn, maskable_ppo, sac, td3).
ALGOS: dict[str, AlgoInfo] = {
    a.name: a
    for a in (
        AlgoInfo("ppo", "stable_baselines3", "PPO",
                 (spaces.Discrete, spaces.Box, spaces.MultiDiscrete, spaces.MultiBinary), "any action space"),
        AlgoInfo("dqn", "stable_baselines3", "DQN", (spaces.Discrete,), "discrete actions (Discrete)"),
        AlgoInfo("maskable_ppo", "sb3_contrib", "MaskablePPO",
                 (spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary), "discrete actions"),
        AlgoInfo("sac", "stable_baselines3", "SAC", (spaces.Box,), "continuous actions (Box)"),
        AlgoInfo("td3", "stable_baselines3", "TD3", (spaces.Box,), "continuous actions (Box)"),
    )
}  # fmt: skip


def get_algo(name: str) -> AlgoInfo:
    """The table row of ``name``; an unknown name raises :class:`~polyenvs.errors.InputError`."""
    if not isinstance(name, str) or name not in ALGOS:
        raise InputError(f"unknown algorithm {name!r}; expected one of {', '.join(ALGOS)}")
    return ALGOS[name]


def algo_class(name: str) -> type:
    """The Stable-Baselines3 / sb3-contrib class (imports torch)."""
    info = get_algo(name)
    try:
        module = importlib.import_module(info.module)
    except ImportError as exc:
        raise InputError(f"{name} needs {info.module.replace('_', '-')}: {install_hint('train')}") from exc
    return getattr(module, info.class_name)


def check_action_space(name: str, env_id: str, action_space: spaces.Space) -> None:
    """Raise :class:`~polyenvs.errors.InputError` where ``name`` cannot act in ``action_space``."""
    info = get_algo(name)
    if not isinstance(action_space, info.action_spaces):
        fits = [a for a, i in ALGOS.items() if isinstance(action_space, i.action_spaces)]
        raise InputError(
            f"{name} needs {info.kind}, but {env_id} has {action_space}; algorithms that fit: {', '.join(fits)}"
        )
