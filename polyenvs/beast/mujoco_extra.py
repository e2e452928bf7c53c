"""MuJoCo and Gymnasium's ``MujocoEnv``: the ``mujoco`` extra, which every beast module imports from here.

Without the extra, making a beast (``gym.make("polyenvs/BeastRoll-v1")``) raises Gymnasium's
``DependencyNotInstalled`` with the install line, as Gymnasium's own MuJoCo environments do, instead of a bare
``ModuleNotFoundError``; ``polyenvs list`` and the other commands print that line.
"""

from gymnasium.error import DependencyNotInstalled

from polyenvs.core.extras import install_hint

try:
    import mujoco
    from gymnasium.envs.mujoco.mujoco_env import MujocoEnv  # imports imageio and packaging: in the extra too
except ImportError as exc:
    raise DependencyNotInstalled(
        f"the Platonic beasts need {exc.name or 'mujoco'}, which is not installed: {install_hint('mujoco')}"
    ) from exc

__all__ = ["MujocoEnv", "mujoco"]
