"""Hand baselines for the Buckybot environments: the paper's wall follower, an explorer and a goal seeker.

They read only the observation (the six range finders and the tip-failed flag, plus the dead-reckoned goal for
BuckybotGoal) and act in the resting face's frame, where direction j is the tip at azimuth 120° j and
direction 0 goes back over the last edge tipped (:mod:`polyenvs.buckybot.simulator`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baselines.base import Policy
from polyenvs.buckybot.env import SENSOR_OBSERVATION_STRUCTURE
from polyenvs.buckybot.geometry import BODY_RADIUS_CM, STEP_LENGTH_CM
from polyenvs.buckybot.sensors import RANGE_MAX_CM, RANGE_MIN_CM, horizontal_range, walls_from_readings
from polyenvs.buckybot.simulator import TIP_ANGLES_RAD
from polyenvs.core import libm
from polyenvs.core.parameters import parameter
from polyenvs.core.validation import check_bool, check_in_range

__all__ = ["GoalSeeker", "WallFollower", "WallFollowExplorer", "decode_readings"]

_TIP_VECTORS = STEP_LENGTH_CM * np.stack([libm.cos(TIP_ANGLES_RAD), libm.sin(TIP_ANGLES_RAD)], axis=-1)
#: The two sensors flanking each tip direction (±22.24° about it).
_FLANKING_SENSORS = np.array([[5, 0], [1, 2], [3, 4]])
#: The frame turns by 120° j + 180° when tip j succeeds.
_FRAME_TURN = TIP_ANGLES_RAD + np.pi


def decode_readings(observation: np.ndarray, too_close_cm: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """Slant readings in cm from an observation (too-close readings replaced by ``too_close_cm``, no return = nan)."""
    lo, hi = SENSOR_OBSERVATION_STRUCTURE["range"]
    reading = observation[lo:hi].astype(np.float64) * RANGE_MAX_CM
    too_close = observation[slice(*SENSOR_OBSERVATION_STRUCTURE["too_close"])] > 0.5
    no_return = observation[slice(*SENSOR_OBSERVATION_STRUCTURE["no_return"])] > 0.5
    reading = np.where(too_close, too_close_cm, np.where(no_return, np.nan, reading))
    tip_failed = bool(observation[SENSOR_OBSERVATION_STRUCTURE["tip_failed"][0]] > 0.5)
    return reading, too_close, tip_failed


@dataclass(frozen=True)
class WallFollowerTunables:
    """What ``polyenvs tune`` searches for the wall follower: the spec names d* and x_s as its parameters and
    gives no values; the defaults are ours. The search stays within a few tips of the wall (a tip is about 23 cm)."""

    d_star_cm: float = parameter(50.0, 20.0, 120.0, "cm", "ours (the paper names d*, gives no value)")
    x_s_cm: float = parameter(20.0, 0.0, 80.0, "cm", "ours (the paper names x_s, gives no value)")
    too_close_cm: float = parameter(20.0, 5.0, RANGE_MIN_CM, "cm", "ours: below the sonar's minimum range")


@dataclass(frozen=True)
class WallFollowExplorerTunables(WallFollowerTunables):
    """The explorer's: farther from the wall, so the beams sweep the rooms."""

    d_star_cm: float = parameter(70.0, 20.0, 150.0, "cm", "ours")
    x_s_cm: float = parameter(30.0, 0.0, 80.0, "cm", "ours")


@dataclass(frozen=True)
class GoalSeekerTunables:
    """What ``polyenvs tune`` searches for the goal seeker."""

    clearance_cm: float = parameter(40.0, 10.0, 120.0, "cm", "ours")


class WallFollower(Policy):
    """The Buckybot paper's wall follower ("Wall Following"), with its proposed fixes as options.

    Before each tip: identify walls from pairs of adjacent sensors (law of cosines, Heron's formula, corrected
    inclination), take the closest, put a target d* from it along the perpendicular through the centre, add x_s
    along the wall in the counter-clockwise direction (+z cross centre-to-wall), and tip in the direction whose
    landing point is closest to the target. With no wall in sight, it heads for open space.

    Known failures (paper, "Anticipated Implementation Issues"): at 90° corners and in narrow hallways the closest
    wall flips between two, and the robot alternates between two faces. The paper's fixes are options:

    Args:
        d_star_cm: wall distance to keep, from the robot's centre: in [13, 182.88] cm (the body radius
            ``BODY_RADIUS_CM`` to the sonar's maximum range ``RANGE_MAX_CM``).
        x_s_cm: the look-ahead along the wall; larger values navigate corners better. In [0, 182.88] cm.
        no_backtrack: never undo the previous tip (unless both other tips face a too-close reading).
        clockwise_exception: when the closest wall switches to one on the opposite side (normals more than 120°
            apart), flip the sense of travel, so the robot keeps going the way it went (paper: "if a wall is sensed
            on the opposite side of the robot, the robot will begin following in a clockwise direction").
        too_close_cm: the range assumed for a sensor that did not settle (it is near an obstacle): in
            (0, 30.48] cm, i.e. at most the sonar's minimum range ``RANGE_MIN_CM``.
        avoid_failed_tip: not in the paper: after a blocked tip (the accelerometer reports the same face), do not
            repeat any tip that failed since the last one that succeeded; try the next-best direction instead of
            pushing against the wall again, and tip back (even with ``no_backtrack``) once both forward tips
            failed, as at a door jamb.

    Numbers must be finite real numbers in their range and switches ``True``/``False``; anything else raises
    ``ValueError`` naming the parameter.
    """

    # sense (+1 counter-clockwise), last wall normal azimuth (frame), has a last wall, last action, has acted,
    # has moved (a tip succeeded, so direction 0 now means "back"), tips failed since the last success (bits)
    memory_size = 7
    tunables = WallFollowerTunables

    def __init__(
        self,
        observation_space,
        action_space,
        *,
        d_star_cm: float = WallFollowerTunables.d_star_cm,
        x_s_cm: float = WallFollowerTunables.x_s_cm,
        no_backtrack: bool = False,
        clockwise_exception: bool = False,
        too_close_cm: float = WallFollowerTunables.too_close_cm,
        avoid_failed_tip: bool = False,
    ):
        # Validate everything before keeping anything.
        d_star_cm = check_in_range("d_star_cm", d_star_cm, BODY_RADIUS_CM, RANGE_MAX_CM)
        x_s_cm = check_in_range("x_s_cm", x_s_cm, 0.0, RANGE_MAX_CM)
        too_close_cm = check_in_range("too_close_cm", too_close_cm, 0.0, RANGE_MIN_CM, low_open=True)
        no_backtrack = check_bool("no_backtrack", no_backtrack)
        clockwise_exception = check_bool("clockwise_exception", clockwise_exception)
        avoid_failed_tip = check_bool("avoid_failed_tip", avoid_failed_tip)
        super().__init__(observation_space, action_space)
        self.d_star_cm, self.x_s_cm, self.too_close_cm = d_star_cm, x_s_cm, too_close_cm
        self.no_backtrack, self.clockwise_exception = no_backtrack, clockwise_exception
        self.avoid_failed_tip = avoid_failed_tip

    def describe(self):
        return {
            "name": type(self).__name__,
            "d_star_cm": self.d_star_cm,
            "x_s_cm": self.x_s_cm,
            "no_backtrack": self.no_backtrack,
            "clockwise_exception": self.clockwise_exception,
            "avoid_failed_tip": self.avoid_failed_tip,
        }

    def initial_memory(self):
        return np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])

    def act(self, observation, memory):
        reading, too_close, tip_failed = decode_readings(observation, self.too_close_cm)
        sense, last_normal, has_wall, last_action, acted, has_moved, failed = memory
        failed = int(failed)
        if acted and not tip_failed:
            has_moved, failed = 1.0, 0
            last_normal -= _FRAME_TURN[int(last_action)]  # carry the remembered wall into the new frame
        elif acted:
            failed |= 1 << int(last_action)
        distance, normal_az = walls_from_readings(reading)
        if np.isnan(distance).all():
            # No wall in sight (one sensor alone is an object, not a wall): head for the most open direction.
            reach = np.where(np.isnan(reading), 2 * RANGE_MAX_CM, reading)[_FLANKING_SENSORS].min(axis=1)
            cost = -reach
            back = cost[0]
            if has_moved:
                cost[0] = np.inf  # keep going rather than turn back
            has_wall = 0.0
        else:
            i = int(np.nanargmin(distance))
            d, az = distance[i], normal_az[i]
            if self.clockwise_exception and has_wall and libm.cos(az - last_normal) < -0.5:  # > 120° apart
                sense = -sense
            normal = np.array([libm.cos(az), libm.sin(az)])
            along = sense * np.array([-normal[1], normal[0]])
            target = (d - self.d_star_cm) * normal + self.x_s_cm * along
            cost = np.hypot(*(_TIP_VECTORS - target).T)
            back = cost[0]
            if self.no_backtrack and has_moved and not too_close[_FLANKING_SENSORS[1:]].any(axis=1).all():
                cost[0] = np.inf
            last_normal, has_wall = az, 1.0
        if self.avoid_failed_tip and failed:
            if failed & 0b110 == 0b110:  # both forward tips are blocked here: back off
                cost[0] = back
            cost[[j for j in range(3) if failed >> j & 1]] = np.inf
        if np.isinf(cost).all():
            cost = np.zeros(3)
        action = int(np.argmin(cost))
        memory[:] = (sense, last_normal, has_wall, action, 1.0, has_moved, failed)
        return action


class WallFollowExplorer(WallFollower):
    """Explore by following walls: the paper's follower farther from the wall so the beams sweep the rooms.

    Defaults: d* = 70 cm, x_s = 30 cm, no backtracking, the clockwise exception and no repeated blocked
    tips (the fixes keep it moving through doors and past wall ends).
    """

    tunables = WallFollowExplorerTunables
    DEFAULTS = {
        "d_star_cm": WallFollowExplorerTunables.d_star_cm,
        "x_s_cm": WallFollowExplorerTunables.x_s_cm,
        "no_backtrack": True,
        "clockwise_exception": True,
        "avoid_failed_tip": True,
    }

    def __init__(self, observation_space, action_space, **kwargs):
        super().__init__(observation_space, action_space, **{**self.DEFAULTS, **kwargs})


class GoalSeeker(Policy):
    """Greedy goal seeking on the lattice: tip towards the dead-reckoned goal, around obstacles.

    Each tip direction is scored by its alignment with the goal's bearing; directions whose flanking sensors
    read closer than ``clearance_cm`` are avoided, and the robot does not undo its last tip unless nothing else
    is free. When the way ahead is walled off it slides along the wall on the side nearer the goal.

    Args:
        clearance_cm: a tip direction whose flanking sensors read closer than this is treated as obstructed:
            in (0, 182.88] cm (up to the sonar's maximum range ``RANGE_MAX_CM``); ``ValueError`` otherwise, and
            for NaN, infinities, bools and strings.
    """

    memory_size = 1  # has moved
    tunables = GoalSeekerTunables

    def __init__(self, observation_space, action_space, clearance_cm: float = GoalSeekerTunables.clearance_cm):
        clearance_cm = check_in_range("clearance_cm", clearance_cm, 0.0, RANGE_MAX_CM, low_open=True)
        super().__init__(observation_space, action_space)
        self.clearance_cm = clearance_cm

    def describe(self):
        return {"name": type(self).__name__, "clearance_cm": self.clearance_cm}

    def act(self, observation, memory):
        reading, too_close, tip_failed = decode_readings(observation, 0.0)
        lo, _ = SENSOR_OBSERVATION_STRUCTURE["tip_failed"]
        cos_b, sin_b = observation[lo + 1], observation[lo + 2]
        bearing = libm.arctan2(sin_b, cos_b)
        alignment = libm.cos(TIP_ANGLES_RAD - bearing)
        reach = horizontal_range(np.where(np.isnan(reading), 2 * RANGE_MAX_CM, reading))[_FLANKING_SENSORS].min(axis=1)
        obstructed = reach < self.clearance_cm
        score = alignment - 10.0 * obstructed
        if memory[0] and not tip_failed:
            score[0] -= 1.5  # going back is the last resort
        memory[0] = 1.0
        return int(np.argmax(score))
