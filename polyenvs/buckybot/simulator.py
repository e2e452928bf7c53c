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

import math
from dataclasses import dataclass, replace

import numpy as np

from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot.sensors import measure_into
from polyenvs.core.geometry2d import SegmentTable, nearest_point, ray_distance
from polyenvs.core.jit import njit

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
        # What the sensors reported at the last sense(): reading (cm, nan if invalid), the two invalid cases, and
        # the observation's normalised range.
        self.reading = np.full((b, 6), np.nan)
        self.too_close = np.zeros((b, 6), dtype=bool)
        self.no_return = np.zeros((b, 6), dtype=bool)
        self.normalised = np.zeros((b, 6), dtype=np.float32)
        self._all_rows = np.arange(b, dtype=np.int64)

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

    # --- dynamics ---------------------------------------------------------------------------------------------
    def tip(self, action: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Tip every robot in direction ``action`` (B,) ints in {0, 1, 2}; ``normals`` (B, 3) standard normals.

        A tip onto a wall (by the mean landing point, i.e. ``tip_allowed``) is blocked: the robot stays put and
        knows it (its accelerometer still reports the same face). An action of -1 leaves that robot alone (a
        vector env resetting it). Returns the (B,) blocked flags.
        """
        blocked = np.empty(self.batch_size, dtype=np.bool_)
        _tip(np.asarray(action, dtype=np.int64), np.ascontiguousarray(normals), *self._tip_args(), blocked)
        return blocked

    def sense(self, normals: np.ndarray, rows: np.ndarray | None = None):
        """Range readings at the current pose; also refreshes the contact geometry.

        Args:
            normals: ``(len(rows), 6)`` standard normals.
            rows: the robots to sense (default: all).

        Returns the simulator's ``(reading, too_close, no_return, normalised)`` buffers (B, 6), as
        :func:`polyenvs.buckybot.sensors.measure_ranges_normalised` would compute them.
        """
        rows = self._all_rows if rows is None else np.asarray(rows, dtype=np.int64)
        _sense(np.ascontiguousarray(normals), rows, *self._sense_args())
        return self.reading, self.too_close, self.no_return, self.normalised

    def step(self, action: np.ndarray, normals: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``tip`` then ``sense`` in one compiled call; ``normals`` (B, 9): three for the tip, six for the sensors.

        ``rows`` limits the sensing (robots with action -1 that were just reset keep their first readings).
        Returns the (B,) blocked flags; the readings are in the simulator's buffers.
        """
        blocked = np.empty(self.batch_size, dtype=np.bool_)
        rows = self._all_rows if rows is None else rows
        _step(action, normals, blocked, rows, self._tip_args(), self._sense_args())
        return blocked

    def _tip_args(self) -> tuple:
        m = self.tip_model
        return (
            self.tip_allowed, self.position, self.heading, self.face, self.edge0, self.dr_position,
            self.dr_heading, self._mean_offsets, self._frame_turn, m.forward_mean_cm, m.forward_sd_cm,
            m.lateral_mean_cm, m.lateral_sd_cm, self._heading_sd, geo.NEIGHBOR, geo.BACK_EDGE,
        )  # fmt: skip

    def _sense_args(self) -> tuple:
        w = self.walls
        return (
            self.position, self.heading, w.start, w.vector, w.inv_length_sq, w.is_real, self._local_vectors,
            geo.SENSOR_HORIZONTAL_OFFSET_CM, _COS_ELEVATION, self.body_radius_cm, self.range_noise_scale,
            self.true_range, self.wall_distance, self.wall_foot, self.wall_segment, self.tip_allowed,
            self.reading, self.too_close, self.no_return, self.normalised,
        )  # fmt: skip


@njit(cache=True)
def _step(action, normals, blocked, rows, tip_args, sense_args):
    _tip(action, normals[:, :3], *tip_args, blocked)
    _sense(normals[rows, 3:], rows, *sense_args)


@njit(cache=True)
def _tip(
    action, normals, tip_allowed, position, heading, face, edge0, dr_position, dr_heading, mean_offsets, frame_turn,
    forward_mean, forward_sd, lateral_mean, lateral_sd, heading_sd, neighbor, back_edge, blocked,
):  # fmt: skip
    for b in range(action.shape[0]):
        a = action[b]
        if a < 0:
            blocked[b] = False
            continue
        blocked[b] = not tip_allowed[b, a]
        if blocked[b]:
            continue
        angle = heading[b] + TIP_ANGLES_RAD[a]
        c, s = math.cos(angle), math.sin(angle)
        forward = forward_mean + forward_sd * normals[b, 0]
        lateral = lateral_mean + lateral_sd * normals[b, 1]  # +lateral is to the right of the tip direction
        position[b, 0] += forward * c + lateral * s
        position[b, 1] += forward * s - lateral * c
        heading[b] = (heading[b] + frame_turn[a] + heading_sd * normals[b, 2]) % _TWO_PI
        # Dead reckoning: the robot replays the mean model for the tips it knows succeeded.
        dc, ds = math.cos(dr_heading[b]), math.sin(dr_heading[b])
        dr_position[b, 0] += dc * mean_offsets[a, 0] - ds * mean_offsets[a, 1]
        dr_position[b, 1] += ds * mean_offsets[a, 0] + dc * mean_offsets[a, 1]
        dr_heading[b] = (dr_heading[b] + frame_turn[a]) % _TWO_PI
        edge = (edge0[b] + a) % 3
        old = face[b]
        face[b] = neighbor[old, edge]
        edge0[b] = back_edge[old, edge]


@njit(cache=True)
def _sense(
    normals, rows, position, heading, start, vector, inv_length_sq, is_real, local, sensor_offset, cos_elevation,
    body_radius, range_noise_scale, true_range, wall_distance, wall_foot, wall_segment, tip_allowed, reading,
    too_close, no_return, normalised,
):  # fmt: skip
    shared = start.shape[0] == 1
    for n in range(rows.shape[0]):
        b = rows[n]
        w = 0 if shared else b
        px, py = position[b, 0], position[b, 1]
        c, s = math.cos(heading[b]), math.sin(heading[b])
        for i in range(6):  # beams: slant range along the tilted beam = horizontal distance / cos(19.47°)
            dx, dy = c * local[i, 0] - s * local[i, 1], s * local[i, 0] + c * local[i, 1]
            h = ray_distance(px + sensor_offset * dx, py + sensor_offset * dy, dx, dy, start[w], vector[w], is_real[w])
            true_range[b, i] = h / cos_elevation
        measure_into(
            true_range[b], normals[n], range_noise_scale, reading[b], too_close[b], no_return[b], normalised[b]
        )
        for j in range(3):  # a tip is allowed when its mean landing point keeps the body off the walls
            lx = px + c * local[6 + j, 0] - s * local[6 + j, 1]
            ly = py + s * local[6 + j, 0] + c * local[6 + j, 1]
            d = nearest_point(lx, ly, start[w], vector[w], inv_length_sq[w], is_real[w])[0]
            tip_allowed[b, j] = d >= body_radius
        d, fx, fy, k = nearest_point(px, py, start[w], vector[w], inv_length_sq[w], is_real[w])
        wall_distance[b], wall_foot[b, 0], wall_foot[b, 1], wall_segment[b] = d, fx, fy, k
