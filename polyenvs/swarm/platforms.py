"""The two robots of the paper as parameter sets: the Maxelbot (University of Wyoming) and Dr Robot's X80Pro.

The paper gives neither body size nor speed; the numbers marked *ours* come from the feasibility study in
``spec/swarm.md`` (Maxelbot radius 0.14 m and wheel base 0.22 m on the MMP-5 base; X80Pro radius 0.19 m and wheel
base 0.26 m). The four virtual sensor angles (S0 right-most ... S3 left-most, x forward, y left) are in the
paper's missing Figure 1; -60°, -15°, +15°, +60° reproduce the three behaviours the text describes
(``geometry-checks.md`` part C).
"""

from __future__ import annotations

from dataclasses import dataclass

from polyenvs.core.validation import check_choice

__all__ = ["IR_SCALES", "PLATFORMS", "Platform", "SENSOR_ANGLES_DEG", "get_platform"]

#: Virtual sensor angles S0..S3 in degrees (x forward, y left; *ours*, the paper's Figure 1 is missing).
SENSOR_ANGLES_DEG = (-60.0, -15.0, 15.0, 60.0)
#: How a platform reports an IR reading: "maxelbot" raw A/D 0..550 (0 = nothing, larger = closer),
#: "x80pro" 0..80 (80 = nothing, 0 = closest).
IR_SCALES = ("maxelbot", "x80pro")


@dataclass(frozen=True)
class Platform:
    """One differential-drive robot.

    Attributes:
        name: "maxelbot" or "x80pro".
        radius_m: body radius (the IR sensors sit on its rim).
        wheel_base_m: distance between the wheels.
        ir_scale: one of :data:`IR_SCALES`.
        controller_sensors: the sensors the paper's AP-lite reads on this robot (all four on the Maxelbot, the
            two outer-most on the X80Pro).
    """

    name: str
    radius_m: float
    wheel_base_m: float
    ir_scale: str
    controller_sensors: tuple[int, ...]


PLATFORMS = {
    "maxelbot": Platform("maxelbot", radius_m=0.14, wheel_base_m=0.22, ir_scale="maxelbot",
                         controller_sensors=(0, 1, 2, 3)),
    "x80pro": Platform("x80pro", radius_m=0.19, wheel_base_m=0.26, ir_scale="x80pro", controller_sensors=(0, 3)),
}  # fmt: skip


def get_platform(name) -> Platform:
    """The platform called ``name`` (``ValueError`` naming ``platform`` otherwise)."""
    return PLATFORMS[check_choice("platform", name, PLATFORMS)]
