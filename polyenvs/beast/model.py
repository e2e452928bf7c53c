"""The beasts' MuJoCo model, generated as MJCF from physical parameters (nothing shipped that cannot be regenerated).

Names the environments, the gait and the tests rely on: body ``torso`` (free joint ``root``), hinge joints
``limb{i}_joint{k}`` (i = 1..n_limbs, k = 1..3) whose angle is exactly the DH theta_k of
:mod:`polyenvs.beast.kinematics`, actuators with the same names, foot spheres ``limb{i}_foot`` centred on the DH
foot point, link geoms ``limb{i}_link{k}``, the body geom ``torso``, the ground plane ``floor`` and the camera
``track`` that follows the torso.

Default values are the feasibility study's (``../shared/spec/beast.md``), which held the nominal stance with no drift
and made the working tumble roll: 2 ms ``implicitfast`` steps, a 3.0 kg convex octahedral body of side 170 mm (the
6-beast's body is a cube with the same inradius, so every limb's shoulder sits the same 42.6 mm above its face),
links of 0.15 / 0.15 / 0.12 kg, a 0.03 kg foot sphere of radius 18 mm (4.8 kg in all for the 4-beast, under the
paper's 5 kg), position servos of kp 300 N m/rad limited to +-6 N m (worm-geared DC motors that lift the robot from
limbs straight out and horizontal, paper section 2), joint damping 5 N m s/rad, armature 0.02 kg m^2 (the worm
drive's reflected inertia), friction 1.0 and collisions between links, feet and body on. The paper gives no joint
limits; ours are the ranges the gaits need.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from polyenvs.beast import kinematics as K
from polyenvs.core.parameters import check_parameters, documented, parameter, parameter_ranges
from polyenvs.core.validation import check_choice, check_int, show

__all__ = [
    "CONTROL_DT",
    "PARAMETER_RANGES",
    "START_STANCE",
    "BeastModelParams",
    "beast_xml",
    "build_model",
    "check_limbs",
    "stance_orientation",
    "stance_qpos",
]

CONTROLS = ("position", "torque")
#: Control tick (s): one action every 10 ms, i.e. frame_skip 5 at the default 2 ms physics step (``timestep``). The
#: environments step at it and the gaits' controllers count time by it.
CONTROL_DT = 0.01

#: Capsule radii of the links (m): the shoulder stub and the thigh / shank tubes of the link modules (*ours*).
_LINK1_RADIUS = 0.02
_LINK_RADIUS = 0.012


_FEASIBILITY = "feasibility study"
_GAITS = "ours: the range the gaits need"
_WRAP = "ours: a cable wrap lets joint 1 wind past a half-turn (the 4-beast's sharp turn needs about +-250)"
_LINK = "the bent joints stop at their links"


@documented
@dataclasses.dataclass(frozen=True)
class BeastModelParams:
    """Physical parameters of a beast (SI units; joint limits in degrees); every number is checked against its
    plausible range on construction (``ValueError`` naming it outside).

    {parameters}

    and the choices

    | parameter | default | meaning |
    | --- | --- | --- |
    | polyhedron | "tetrahedron" | 4-beast; "octahedron" = 6-beast, "cube" = 8-beast |
    | control | "position" | "torque" makes the actuators plain motors limited to +-torque_limit |
    | locked_limbs | () | 1-based limbs whose joints are locked (a failed worm drive does not backdrive) |
    """

    polyhedron: str = "tetrahedron"
    # d1 runs from beyond the face (the largest body's inradius is under 90 mm) up to twice Table 1's.
    d1: float = parameter(K.PROTOTYPE_LINKS.d1, 0.10, 0.20, "m", "Table 1")
    a2: float = parameter(K.PROTOTYPE_LINKS.a2, 0.05, 0.25, "m", "Table 1")
    a3: float = parameter(K.PROTOTYPE_LINKS.a3, 0.05, 0.30, "m", "Table 1 (it depends on the foot module)")
    body_side: float = parameter(K.BODY_SIDE, 0.12, 0.22, "m", "paper section 2")
    body_mass: float = parameter(3.0, 0.5, 10.0, "kg", f"{_FEASIBILITY} (4.8 kg in all; paper: under 5 kg)")
    link1_mass: float = parameter(0.15, 0.01, 1.0, "kg", _FEASIBILITY)
    link2_mass: float = parameter(0.15, 0.01, 1.0, "kg", _FEASIBILITY)
    link3_mass: float = parameter(0.12, 0.01, 1.0, "kg", _FEASIBILITY)
    foot_mass: float = parameter(0.03, 0.005, 0.5, "kg", _FEASIBILITY)
    foot_radius: float = parameter(0.018, 0.005, 0.04, "m", _FEASIBILITY)
    kp: float = parameter(300.0, 10.0, 2000.0, "N m/rad", f"position servo gain, {_FEASIBILITY}")
    torque_limit: float = parameter(6.0, 0.5, 50.0, "N m", f"{_FEASIBILITY}: lifts from limbs straight out")
    damping: float = parameter(5.0, 0.0, 50.0, "N m s/rad", f"worm drive, {_FEASIBILITY}")
    armature: float = parameter(0.02, 0.0, 1.0, "kg m^2", f"worm drive's reflected inertia, {_FEASIBILITY}")
    friction: float = parameter(1.0, 0.1, 2.0, "", f"sliding friction of every contact, {_FEASIBILITY}")
    timestep: float = parameter(0.002, 0.0005, 0.005, "s", f"implicitfast integrator, {_FEASIBILITY}")
    joint1_low_deg: float = parameter(-180.0, -270.0, 0.0, "deg", _WRAP)
    joint1_high_deg: float = parameter(180.0, 0.0, 270.0, "deg", _WRAP)
    joint2_low_deg: float = parameter(-120.0, -180.0, 0.0, "deg", f"{_GAITS}; {_LINK}")
    joint2_high_deg: float = parameter(160.0, 0.0, 180.0, "deg", f"{_GAITS}; {_LINK}")
    joint3_low_deg: float = parameter(-150.0, -180.0, 0.0, "deg", f"{_GAITS}; {_LINK}")
    joint3_high_deg: float = parameter(150.0, 0.0, 180.0, "deg", f"{_GAITS}; {_LINK}")
    control: str = "position"
    locked_limbs: tuple = ()

    def __post_init__(self):
        check_choice("polyhedron", self.polyhedron, K.POLYHEDRA)
        check_choice("control", self.control, CONTROLS)
        object.__setattr__(self, "locked_limbs", check_limbs("locked_limbs", self.locked_limbs, self.n_limbs))
        check_parameters(self)
        if self.foot_radius >= self.a3 / 2:
            raise ValueError(f"foot_radius must be under a3 / 2 = {self.a3 / 2:g} m, got {self.foot_radius!r}")
        for k in (1, 2, 3):
            if getattr(self, f"joint{k}_low_deg") >= getattr(self, f"joint{k}_high_deg"):
                raise ValueError(f"joint{k}_low_deg must be below joint{k}_high_deg")

    @property
    def links(self) -> K.Links:
        return K.Links(self.d1, self.a2, self.a3)

    @property
    def n_limbs(self) -> int:
        return K.N_LIMBS[self.polyhedron]

    @property
    def inradius(self) -> float:
        """The body's inradius (m): each limb's face lies this far from the centre, where link 1 starts (the 6-beast's
        cube body has the octahedron's inradius, so its shoulders sit at the same depth)."""
        return self.body_side / math.sqrt(6)

    @property
    def joint_ranges(self) -> np.ndarray:
        """(3, 2) joint limits in radians, rows joint 1, 2, 3."""
        deg = [[getattr(self, f"joint{k}_{side}_deg") for side in ("low", "high")] for k in (1, 2, 3)]
        return np.radians(np.array(deg))

    @property
    def total_mass(self) -> float:
        per_limb = self.link1_mass + self.link2_mass + self.link3_mass + self.foot_mass
        return self.body_mass + self.n_limbs * per_limb


#: Plausible range of every physical parameter (from the declarations above). Outside it: ValueError.
PARAMETER_RANGES = parameter_ranges(BeastModelParams)


def check_limbs(name: str, value, n_limbs: int) -> tuple[int, ...]:
    """A tuple of distinct 1-based limb numbers, sorted."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise ValueError(f"{name} must be a tuple of limb numbers 1..{n_limbs}, got {show(value)}")
    limbs = [check_int(name, v, 1, n_limbs) for v in value]
    if len(set(limbs)) != len(limbs):
        raise ValueError(f"{name} must not repeat a limb, got {show(value)}")
    return tuple(sorted(limbs))


def _body_vertices(params: BeastModelParams) -> np.ndarray:
    if params.polyhedron == "octahedron":
        # A cube with the octahedron's inradius: the 6-beast's limbs sit on its faces at the same depth.
        half = params.inradius
        return half * np.array(list(np.ndindex(2, 2, 2)), dtype=float) * 2 - half
    # The octahedron of Table 2's body frame: z is a 2-fold axis through two vertices, the others at 45 degrees.
    r = params.body_side / math.sqrt(2)
    s = r / math.sqrt(2)
    return np.array([[0, 0, r], [0, 0, -r], [s, s, 0], [s, -s, 0], [-s, s, 0], [-s, -s, 0]])


def _f(values) -> str:
    return " ".join(f"{float(v):.9g}" for v in np.ravel(values))


def _limb_xml(p: BeastModelParams, i: int, frame: np.ndarray) -> str:
    """The MJCF bodies of limb ``i`` (1-based) on its face, with base frame ``frame`` (4, 4)."""
    rad = p.joint_ranges
    return f"""
      <body name="limb{i}_link1" quat="{_f(K.rotation_quat(frame[:3, :3]))}">
        <joint name="limb{i}_joint1" range="{_f(rad[0])}"/>
        <geom name="limb{i}_link1" type="capsule" size="{_LINK1_RADIUS}"
              fromto="0 0 {p.inradius:.9g} 0 0 {p.d1:.9g}" mass="{p.link1_mass:.9g}"/>
        <body name="limb{i}_link2" pos="0 0 {p.d1:.9g}" quat="{_f(K.rotation_quat(K.rot_x(math.pi / 2)))}">
          <joint name="limb{i}_joint2" range="{_f(rad[1])}"/>
          <geom name="limb{i}_link2" type="capsule" size="{_LINK_RADIUS}" fromto="0 0 0 {p.a2:.9g} 0 0"
                mass="{p.link2_mass:.9g}"/>
          <body name="limb{i}_link3" pos="{p.a2:.9g} 0 0">
            <joint name="limb{i}_joint3" range="{_f(rad[2])}"/>
            <geom name="limb{i}_link3" type="capsule" size="{_LINK_RADIUS}"
                  fromto="0 0 0 {p.a3 - p.foot_radius:.9g} 0 0" mass="{p.link3_mass:.9g}"/>
            <geom name="limb{i}_foot" type="sphere" size="{p.foot_radius:.9g}" pos="{p.a3:.9g} 0 0"
                  mass="{p.foot_mass:.9g}" material="foot"/>
          </body>
        </body>
      </body>"""


def _actuator_xml(p: BeastModelParams, i: int) -> list[str]:
    """The three actuators of limb ``i`` (1-based): position servos, or plain motors for ``control="torque"``."""
    rad = p.joint_ranges
    if p.control == "position":
        actuator = "position"
        gains = f'kp="{p.kp:.9g}" forcerange="{-p.torque_limit:.9g} {p.torque_limit:.9g}"'
    else:
        actuator = "motor"
        gains = f'ctrlrange="{-p.torque_limit:.9g} {p.torque_limit:.9g}"'
    lines = []
    for k in (1, 2, 3):
        ctrl = f'ctrlrange="{_f(rad[k - 1])}" ' if p.control == "position" else ""
        lines.append(f'    <{actuator} name="limb{i}_joint{k}" joint="limb{i}_joint{k}" {ctrl}{gains}/>')
    return lines


def beast_xml(params: BeastModelParams) -> str:
    """The MJCF of a beast with these parameters, standing at the origin (the tasks place it)."""
    p = params
    limbs, actuators = [], []
    for i, frame in enumerate(K.limb_base_frames(p.polyhedron), start=1):
        limbs.append(_limb_xml(p, i, frame))
        actuators.extend(_actuator_xml(p, i))
    standing = p.d1 + p.a2 + p.a3
    # Evaluated inside mj_step (so the raw step cost includes them): contacts of each foot with the floor, all
    # contacts of the robot with the floor, and the world's up direction in the body frame (for the tilt switches).
    sensors = [
        f'    <contact name="limb{i}_foot_floor" geom1="limb{i}_foot" geom2="floor" data="found"/>'
        for i in range(1, p.n_limbs + 1)
    ]
    sensors.append('    <contact name="robot_floor" subtree1="torso" geom2="floor" data="found"/>')
    sensors.append('    <framezaxis name="up" objtype="body" objname="world" reftype="body" refname="torso"/>')
    # Locked joints hold the angle the environment writes into eq_data at reset.
    locks = [f'    <joint name="lock{i}_{k}" joint1="limb{i}_joint{k}"/>' for i in p.locked_limbs for k in (1, 2, 3)]
    equality = f"\n  <equality>\n{chr(10).join(locks)}\n  </equality>" if locks else ""
    return f"""<mujoco model="beast_{p.polyhedron}">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{p.timestep:.9g}" integrator="implicitfast"/>
  <visual>
    <global offwidth="640" offheight="480"/>
  </visual>
  <default>
    <joint type="hinge" axis="0 0 1" damping="{p.damping:.9g}" armature="{p.armature:.9g}"/>
    <geom friction="{p.friction:.9g} 0.005 0.0001" material="link"/>
  </default>
  <asset>
    <mesh name="body" vertex="{_f(_body_vertices(p))}"/>
    <texture name="grid" type="2d" builtin="checker" rgb1="0.85 0.85 0.82" rgb2="0.65 0.68 0.72" width="256"
             height="256"/>
    <material name="grid" texture="grid" texrepeat="8 8" texuniform="true"/>
    <material name="body" rgba="0.85 0.45 0.15 1"/>
    <material name="link" rgba="0.3 0.35 0.45 1"/>
    <material name="foot" rgba="0.1 0.1 0.1 1"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 0.05" material="grid"/>
    <body name="torso" pos="0 0 {standing:.9g}">
      <freejoint name="root"/>
      <light name="sun" mode="track" pos="0 0 3" dir="0 0 -1" directional="true"/>
      <camera name="track" mode="track" pos="0.75 -0.75 0.55" xyaxes="0.7071 0.7071 0 -0.35 0.35 0.87"/>
      <geom name="torso" type="mesh" mesh="body" mass="{p.body_mass:.9g}" material="body"/>{"".join(limbs)}
    </body>
  </worldbody>
  <actuator>
{chr(10).join(actuators)}
  </actuator>
  <sensor>
{chr(10).join(sensors)}
  </sensor>{equality}
</mujoco>
"""


def build_model(params: BeastModelParams):
    """A compiled ``mujoco.MjModel`` for these parameters (imports MuJoCo, the optional ``mujoco`` extra)."""
    from polyenvs.beast.mujoco_extra import mujoco

    return mujoco.MjModel.from_xml_string(beast_xml(params))


#: The start stance of each polyhedron: (feet radius about the body's vertical axis, body centre height) in metres.
#: The 4-beast's is the working tumble's K0 (feet on an equilateral pattern of side 300 mm, body centre 168 mm up),
#: from which the canonical tumble is plannable; the nominal B3 stance (side 353 mm) admits no tumble.
START_STANCE = {"tetrahedron": (0.300 / math.sqrt(3), 0.168), "octahedron": (0.20, 0.17), "cube": (0.20, 0.17)}
#: Body-frame direction that points up in the start stance: limb 4 for the 4-beast, a cube corner (3-fold axis,
#: three limbs down) for the 6-beast, the body's z axis (a vertex, four limbs down) for the 8-beast.
_UP = {
    "tetrahedron": -np.array([0.0, math.sqrt(2 / 3), 1 / math.sqrt(3)]),
    "octahedron": np.ones(3) / math.sqrt(3),
    "cube": np.array([0.0, 0.0, 1.0]),
}


def stance_orientation(polyhedron: str) -> tuple[np.ndarray, np.ndarray]:
    """(world-from-body rotation, stance limb indices) of the start stance, heading along world +x.

    The stance limbs are those pointing below the horizontal. The heading (world +x) is away from the last stance
    limb, so that for the 4-beast the canonical tumble (1234) tips over edge p1-p2 along +x.
    """
    directions = K.limb_directions(polyhedron)
    up = _UP[polyhedron]
    stance = np.flatnonzero(directions @ up < -0.2)
    back = directions[stance[-1]]
    forward = -(back - (back @ up) * up)
    forward /= np.linalg.norm(forward)
    return np.stack([forward, np.cross(up, forward), up]), stance


def stance_qpos(params: BeastModelParams, feet_radius: float, height: float, yaw: float = 0.0) -> np.ndarray:
    """qpos of a stance: stance feet on a circle of ``feet_radius`` about the body's vertical axis at the azimuths of
    their limb axes, sphere centres one foot radius above the floor, body centre ``height`` up, each limb on the
    inverse-kinematics solution with the highest knee; other limbs straight out (0, 90, 0). The whole robot is
    turned by ``yaw`` about the vertical. For the 4-beast with ``START_STANCE`` this is the working tumble's K0."""
    rot, stance = stance_orientation(params.polyhedron)
    rot = K.rot_z(yaw) @ rot
    world_dirs = K.limb_directions(params.polyhedron) @ rot.T
    azimuth = np.arctan2(world_dirs[stance, 1], world_dirs[stance, 0])
    feet = np.stack(
        [
            feet_radius * np.cos(azimuth),
            feet_radius * np.sin(azimuth),
            np.full(len(stance), params.foot_radius - height),
        ],
        axis=1,
    )
    theta = np.tile(K.STRAIGHT_OUT, (params.n_limbs, 1))
    base = K.limb_base_frames(params.polyhedron)[stance, :3, :3]
    solutions = K.ik_solutions(np.einsum("lji,lj->li", base, feet @ rot), params.links)  # (stance, 4, 3)
    # Of the four solutions, the one with the knee highest above the floor: clear of the ground and the body
    # (for the 4-beast this is K0's). (theta1 + pi, pi - theta2, -theta3) puts knee and foot at the same places; the
    # micrometre bonus breaks that tie for the theta3 > 0 knee branch the tumbles need.
    knees = np.einsum("ij,ljk,lsk->lsi", rot, base, K.dh_frames(solutions, params.links)[..., 1, :3, 3])
    best = np.argmax(knees[..., 2] + 1e-6 * (solutions[..., 2] > 0), axis=1)
    theta[stance] = solutions[np.arange(len(stance)), best]
    quat = K.rotation_quat(rot)
    return np.concatenate([[0.0, 0.0, height], quat / np.linalg.norm(quat), theta.ravel()])
