"""Held-out layouts of the beasts: the floor's friction and the robot's physical parameters, drawn per episode.

A beast's "layout" is the physics it meets: the friction of every contact (the floor: carpet, tile, grass), the
body's mass (a payload), the servos' gain and the joints' damping (motors and worm drives differ from unit to unit,
and wear). ``layouts="train"`` draws each from a sub-interval of its declared range around the default
(:class:`polyenvs.beast.model.BeastModelParams`); ``"test"`` from a disjoint sub-interval, on the side the robot
would meet in the field (a slipperier floor, a heavier body, weaker and stiffer drives), which does not contain the
default. Geometry (link lengths, body size) is not drawn: it changes the model's structure, not only its numbers.

Per-reset cost stays that of a field write: the drawn values are written into the compiled ``MjModel`` in place
(every geom's friction, the torso's mass with its inertia scaled alike, the position servos' gain and bias, the
hinge joints' damping), always from the values the model was built with, then ``mj_setConst`` recomputes what
depends on them; nothing is regenerated or recompiled.
"""

from __future__ import annotations

import numpy as np

from polyenvs.beast.mujoco_extra import mujoco
from polyenvs.core.layouts import LayoutSplit, SplitParameter

__all__ = ["LAYOUT_SPLIT", "ModelFields", "draw_layout"]

#: The split (:mod:`polyenvs.core.layouts`); the names are :class:`BeastModelParams` fields, each interval inside
#: the field's declared range.
LAYOUT_SPLIT = LayoutSplit(
    (
        SplitParameter("friction", "", train=(0.85, 1.15), test=(0.6, 0.8)),
        SplitParameter("body_mass", "kg", train=(2.7, 3.3), test=(3.4, 3.8)),
        SplitParameter("kp", "N m/rad", train=(270.0, 330.0), test=(220.0, 260.0)),
        SplitParameter("damping", "N m s/rad", train=(4.5, 5.5), test=(5.8, 6.6)),
    ),
    varies="the friction of every contact, the body's mass, the servos' gain and the joints' damping",
)
#: The model parameters a layout draws (``physics=`` may not set them beside ``layouts="train"`` or ``"test"``).
LAYOUT_PARAMETERS = tuple(p.name for p in LAYOUT_SPLIT.parameters)


def draw_layout(rng: np.random.Generator, layouts: str) -> dict[str, float]:
    """One value of each split parameter from its ``layouts`` ("train" or "test") interval, in declaration order."""
    return {p.name: float(p.draw(rng, layouts)) for p in LAYOUT_SPLIT.parameters}


class ModelFields:
    """Writes a layout's values into a compiled beast model in place, from the values it was built with."""

    def __init__(self, model: mujoco.MjModel, position_control: bool):
        self.model = model
        self.position_control = position_control
        self.torso = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "torso")
        self.hinges = model.jnt_dofadr[model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE]
        self.built_mass = float(model.body_mass[self.torso])
        self.built_inertia = model.body_inertia[self.torso].copy()

    def apply(self, data: mujoco.MjData, values: dict[str, float]) -> None:
        """Set ``values`` (:func:`draw_layout`'s) on the model and recompute its derived constants."""
        m = self.model
        m.geom_friction[:, 0] = values["friction"]
        m.body_mass[self.torso] = values["body_mass"]
        m.body_inertia[self.torso] = self.built_inertia * (values["body_mass"] / self.built_mass)
        if self.position_control:  # MuJoCo's position servo: force = kp * ctrl - kp * qpos (- kv * qvel)
            m.actuator_gainprm[:, 0] = values["kp"]
            m.actuator_biasprm[:, 1] = -values["kp"]
        m.dof_damping[self.hinges] = values["damping"]
        mujoco.mj_setConst(m, data)
