"""Batched Buckybot simulation core: tipping on the honeycomb lattice, wall contact and range sensing.

State per robot (batch axis first): position of the contact-face centre (cm), resting face, the *motion frame*
(which physical edge of the resting face is the frame's tip direction 0, and that direction's world azimuth),
plus the dead-reckoned position and heading the robot itself computes from its actuator sequence.

The motion frame. Observations and actions live in the resting face's frame, with the three tip directions at
azimuths 0°, 120°, 240° (counter-clockwise from above). Direction 0 is the edge the robot last tipped over, i.e.
tipping 0 goes back where it came from; after a reset it is the edge opposite the face's first-lettered actuator.
Tip ``j`` rotates the frame by ``120° j + 180°`` (plus the heading noise), whatever the faces involved, so a policy
that remembers anything can carry it from one frame to the next. ``info`` publishes the frame's world heading, the
resting face and the actuator each action extends.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot.sensors import measure_ranges
from polyenvs.core.geometry2d import SegmentTable, cast_rays, nearest_wall_points

__all__ = ["TipModel", "BuckybotSimulator", "TIP_ANGLES_RAD"]

#: Frame azimuths of the three tip directions.
TIP_ANGLES_RAD = np.radians([0.0, 120.0, 240.0])
_TWO_PI = 2.0 * np.pi
_COS_ELEVATION = float(np.cos(geo.SENSOR_ELEVATION_RAD))


@dataclass(frozen=True)
class TipModel:
    """Displacement of one tip in the robot frame (+y along the tip direction, +x to its right, z up).

    Defaults are the Buckybot paper's Vicon measurements ("Test Results": 10 repetitions of all 60 tip
    combinations): forward 9.266 ± 0.105 cm, lateral -0.745 ± 0.149 cm, heading +0.31 ± 0.44°, uncorrelated.
    """

    forward_mean_cm: float = 9.266
    forward_sd_cm: float = 0.105
    lateral_mean_cm: float = -0.745
    lateral_sd_cm: float = 0.149
    heading_mean_deg: float = 0.31
    heading_sd_deg: float = 0.44

    def scaled(self, noise_scale: float) -> TipModel:
        """Interpolate between the ideal lattice (0: 9.129 cm straight steps, no spread) and this model (1).

        Both the spread and the systematic offsets scale, so ``noise_scale=0`` is the exact honeycomb.
        """
        s = float(noise_scale)
        ideal = geo.STEP_LENGTH_CM
        return replace(
            self,
            forward_mean_cm=ideal + s * (self.forward_mean_cm - ideal),
            forward_sd_cm=s * self.forward_sd_cm,
            lateral_mean_cm=s * self.lateral_mean_cm,
            lateral_sd_cm=s * self.lateral_sd_cm,
            heading_mean_deg=s * self.heading_mean_deg,
            heading_sd_deg=s * self.heading_sd_deg,
        )

    def mean_offsets(self) -> np.ndarray:
        """(3, 2) mean displacement of each of the three tips in the motion frame."""
        c, s = np.cos(TIP_ANGLES_RAD), np.sin(TIP_ANGLES_RAD)
        # Forward along (c, s); "right" of the tip direction is (s, -c).
        return np.stack(
            [self.forward_mean_cm * c + self.lateral_mean_cm * s, self.forward_mean_cm * s - self.lateral_mean_cm * c],
            axis=-1,
        )


class BuckybotSimulator:
    """A batch of Buckybots on wall plans; every array has the batch on axis 0.

    Args:
        batch_size: number of robots.
        tip_model: the per-tip motion model (already scaled by the environment's ``noise_scale``).
        range_noise_scale: multiplies the range finders' eq. 6 standard deviation.
        body_radius_cm: a tip whose mean landing point is closer than this to a wall is blocked.
    """

    def __init__(self, batch_size: int, tip_model: TipModel, range_noise_scale: float, body_radius_cm: float):
        self.batch_size = int(batch_size)
        self.tip_model = tip_model
        self.range_noise_scale = float(range_noise_scale)
        self.body_radius_cm = float(body_radius_cm)
        self._mean_offsets = tip_model.mean_offsets()  # (3, 2)
        self._frame_turn = TIP_ANGLES_RAD + np.pi + np.radians(tip_model.heading_mean_deg)
        self._heading_sd = np.radians(tip_model.heading_sd_deg)
        beams = np.stack([np.cos(geo.SENSOR_AZIMUTHS_RAD), np.sin(geo.SENSOR_AZIMUTHS_RAD)], axis=-1)
        self._local_vectors = np.concatenate([beams, self._mean_offsets])
        b = self.batch_size
        self.position = np.zeros((b, 2))
        self.heading = np.zeros(b)  # world azimuth of motion-frame direction 0 (rad)
        self.face = np.zeros(b, dtype=np.int64)
        self.edge0 = np.zeros(b, dtype=np.int64)  # physical edge of the resting face at frame direction 0
        self.dr_position = np.zeros((b, 2))
        self.dr_heading = np.zeros(b)
        self.walls: SegmentTable | None = None
        # Refreshed by sense(): what the sensors and the contact geometry say about the current pose.
        self.true_range = np.full((b, 6), np.inf)
        self.wall_distance = np.zeros(b)
        self.wall_foot = np.zeros((b, 2))
        self.wall_segment = np.zeros(b, dtype=np.int64)
        self.tip_allowed = np.ones((b, 3), dtype=bool)

    # --- state ------------------------------------------------------------------------------------------------
    def set_walls(self, walls: SegmentTable) -> None:
        if walls.batch_size not in (1, self.batch_size):
            raise ValueError(f"walls batch {walls.batch_size} does not match the simulator batch {self.batch_size}")
        self.walls = walls

    def place(self, index, position, face, heading) -> None:
        """Put robots ``index`` at a pose (true and dead-reckoned pose agree at the start)."""
        self.position[index] = position
        self.dr_position[index] = position
        self.face[index] = face
        self.edge0[index] = 0
        self.heading[index] = np.mod(heading, _TWO_PI)
        self.dr_heading[index] = self.heading[index]

    def tip_headings(self) -> np.ndarray:
        """(B, 3) world azimuths of the three tip directions."""
        return self.heading[:, None] + TIP_ANGLES_RAD

    def actuators(self) -> np.ndarray:
        """(B, 3) actuator (vertex) index each action would extend."""
        edges = (self.edge0[:, None] + np.arange(3)) % 3
        return geo.FACE_CORNER_ACTUATOR[self.face[:, None], edges]

    # --- dynamics ---------------------------------------------------------------------------------------------
    def tip(self, action: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Tip every robot in direction ``action`` (B,) ints in {0, 1, 2}; ``normals`` (B, 3) standard normals.

        A tip onto a wall (by the mean landing point, i.e. ``tip_allowed``) is blocked: the robot stays put and
        knows it (its accelerometer still reports the same face). Returns the (B,) blocked flags.
        """
        b = np.arange(self.batch_size)
        moved = self.tip_allowed[b, action]
        model = self.tip_model
        angle = self.heading + TIP_ANGLES_RAD[action]
        c, s = np.cos(angle), np.sin(angle)
        forward = model.forward_mean_cm + model.forward_sd_cm * normals[:, 0]
        lateral = model.lateral_mean_cm + model.lateral_sd_cm * normals[:, 1]
        forward *= moved  # a blocked tip moves nothing
        lateral *= moved
        self.position[:, 0] += forward * c + lateral * s
        self.position[:, 1] += forward * s - lateral * c
        turn = self._frame_turn[action] + self._heading_sd * normals[:, 2]
        self.heading = np.mod(self.heading + turn * moved, _TWO_PI)

        # Dead reckoning: the robot replays the mean model for the tips it knows succeeded.
        dc, ds = np.cos(self.dr_heading), np.sin(self.dr_heading)
        off = self._mean_offsets[action] * moved[:, None]
        self.dr_position[:, 0] += dc * off[:, 0] - ds * off[:, 1]
        self.dr_position[:, 1] += ds * off[:, 0] + dc * off[:, 1]
        self.dr_heading = np.mod(self.dr_heading + self._frame_turn[action] * moved, _TWO_PI)

        edge = (self.edge0 + action) % 3
        self.face, self.edge0 = (
            np.where(moved, geo.NEIGHBOR[self.face, edge], self.face),
            np.where(moved, geo.BACK_EDGE[self.face, edge], self.edge0),
        )
        return ~moved

    def sense(self, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Range readings at the current pose (``normals`` (B, 6)); also refreshes contact geometry.

        Returns ``(reading, too_close, no_return)`` as :func:`polyenvs.buckybot.sensors.measure_ranges`.
        """
        # Sensor beams (unit vectors of their horizontal projection) and the candidate landing points, in the world.
        c, s = np.cos(self.heading)[:, None], np.sin(self.heading)[:, None]
        local = self._local_vectors  # (7, 2): six beam directions, then the mean tip offsets
        world = np.empty((self.batch_size, 10, 2))
        world[:, :9, 0] = c * local[:, 0] - s * local[:, 1]
        world[:, :9, 1] = s * local[:, 0] + c * local[:, 1]
        world[:, 9] = 0.0
        beam = world[:, :6]
        horizontal = cast_rays(self.walls, self.position[:, None, :] + geo.SENSOR_HORIZONTAL_OFFSET_CM * beam, beam)
        self.true_range = horizontal / _COS_ELEVATION  # slant range along the tilted beam

        points = self.position[:, None, :] + world[:, 6:]  # (B, 4, 2): the three landing points, then the centre
        distance, foot, segment = nearest_wall_points(self.walls, points)
        self.wall_distance, self.wall_foot, self.wall_segment = distance[:, 3], foot[:, 3], segment[:, 3]
        self.tip_allowed = distance[:, :3] >= self.body_radius_cm
        return measure_ranges(self.true_range, normals, self.range_noise_scale)
