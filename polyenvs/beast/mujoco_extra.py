"""MuJoCo and Gymnasium's ``MujocoEnv``: the ``mujoco`` extra, which every beast module imports from here.

Without the extra, making a beast (``gym.make("polyenvs/BeastRoll-v1")``) raises Gymnasium's
``DependencyNotInstalled`` with the install line, as Gymnasium's own MuJoCo environments do, instead of a bare
``ModuleNotFoundError``; ``polyenvs list`` and the other commands print that line.

:data:`mj_step_at` is MuJoCo's C ``mj_step(const mjModel*, mjData*)`` as compiled code calls it, given the structs'
addresses (``MjModel._address``, ``MjData._address``): the library the ``mujoco`` package loaded is registered with
numba's linker, so a kernel steps the physics without returning to Python and, compiled ``nogil``, without the GIL.
It is the function ``mujoco.mj_step`` calls (``nstep=n`` calls it n times), minus the binding's translation of a
fatal MuJoCo error (``mju_error``: an internal size overflow, which a beast's fixed-size model does not reach) into a
Python exception: such an error would end the process with MuJoCo's message instead.
"""

import glob
import os

from gymnasium.error import DependencyNotInstalled

from polyenvs.core.extras import install_hint

try:
    import mujoco
    from gymnasium.envs.mujoco.mujoco_env import MujocoEnv  # imports imageio and packaging: in the extra too
except ImportError as exc:
    raise DependencyNotInstalled(
        f"the Platonic beasts need {exc.name or 'mujoco'}, which is not installed: {install_hint('mujoco')}"
    ) from exc

import llvmlite.binding
from numba import types

__all__ = ["MujocoEnv", "mj_step_at", "mujoco"]


def _mujoco_library() -> str:
    """The MuJoCo shared library inside the ``mujoco`` package (the one its bindings loaded)."""
    folder = os.path.dirname(mujoco.__file__)
    found = sorted(glob.glob(os.path.join(folder, "libmujoco.so*")) + glob.glob(os.path.join(folder, "*mujoco*.dll")))
    found += sorted(glob.glob(os.path.join(folder, "libmujoco*.dylib")))
    if not found:
        raise DependencyNotInstalled(f"no MuJoCo library in {folder}: {install_hint('mujoco')}")
    return found[0]


# Loading the library the bindings already loaded maps no second copy: the symbols resolve to the same functions.
llvmlite.binding.load_library_permanently(_mujoco_library())
#: ``mj_step(model_address, data_address)``, callable from compiled code only (the addresses as integers).
mj_step_at = types.ExternalFunction("mj_step", types.void(types.intp, types.intp))
