"""BuckybotWallFollow: follow the nearest wall counter-clockwise at a fixed distance."""

from __future__ import annotations

import math

import numpy as np

from polyenvs.buckybot.env import BuckybotEnv
from polyenvs.buckybot.geometry import STEP_LENGTH_CM
from polyenvs.core.jit import njit
from polyenvs.core.validation import check_positive

__all__ = ["BuckybotWallFollowEnv"]

_PERIMETER_BIN_CM = 10.0


class BuckybotWallFollowEnv(BuckybotEnv):
    """Follow the closest wall counter-clockwise at distance d*, with only six ultrasonic range finders.

    ## Description
    Buckybot (Buckybot paper: "Buckybot: preliminary control and mapping algorithms") is a truncated icosahedron
    that moves by tipping from one hexagonal face to the next, so its centre walks on a honeycomb lattice with
    9.27 cm steps whose three directions shift by 60° at every step. It senses walls with six LV-MaxSonar-EZ range
    finders tilted 19.47° up. The task is the paper's: follow the closest wall counter-clockwise at distance d*,
    trading distance error against progress along the wall (the paper's cost, eq. 5). The paper's hand algorithm,
    ``baselines.buckybot.WallFollower``, is the baseline; it gets stuck in 90° corners and narrow hallways.

    ## Action Space
    ``Discrete(3)``: tip towards frame direction 0, 1 or 2 (azimuths 0°, 120°, 240° in the resting face's frame,
    counter-clockwise from above). Direction 0 points back over the edge the robot last tipped over (after a
    reset: the edge opposite the resting face's first-lettered actuator), so action 0 undoes the previous tip.
    A tip whose landing point would bring the body (radius 13 cm) against a wall is blocked: the robot stays.

    ## Observation Space
    ``Box(0, 1, (19,), float32)``, described by ``env.observation_structure``:

    | index | name | meaning |
    |-------|------|---------|
    | 0-5 | range | reading / 182.88 cm of the sensors at azimuths 22.24°, 97.76°, 142.24°, 217.76°, 262.24°, 337.76°; 0 if too close, 1 if no return |
    | 6-11 | too_close | 1 where the sensor did not settle (< 30.48 cm) |
    | 12-17 | no_return | 1 where nothing was seen within 182.88 cm |
    | 18 | tip_failed | 1 if the last tip was blocked |

    Readings follow the paper's eq. 6, ``d + (0.013 d + 0.448) w`` cm, rounded to 2.54 cm.

    Ground truth stays out of the observation and goes into ``info`` (in reset and step alike): ``pose`` and
    ``dead_reckoned_pose`` (x cm, y cm, heading of frame direction 0 in degrees), ``face`` (1-20),
    ``tip_directions_deg`` (world azimuths of the three actions), ``actuators`` (the actuator letter each action
    extends), ``sensor_faces`` (the faces carrying the six observed sensors), ``true_range_cm``,
    ``wall_distance_cm``, ``blocked``, ``action_mask`` (int8, tips that would not hit a wall; also
    ``env.action_masks()`` for MaskablePPO), the ``reward_*`` terms and ``episode_metrics``.

    ## Rewards
    The paper's per-step cost ``(d - d*)² - x_s · progress``, normalised by ``2 x_s · 9.129 cm`` so a step along
    the wall earns about 1 (the weight 2 x_s makes the paper's target-tracking rule the greedy minimiser):
    ``reward_progress = Δs / 9.129`` with Δs the displacement along the nearest wall's counter-clockwise
    tangent (z × centre-to-wall), ``reward_distance = -(d - d*)² / (2 x_s · 9.129)`` with d the true distance to
    the nearest wall after the tip, and ``reward_blocked = -1`` for a blocked tip.

    ## Starting State
    A seeded position at least 23 cm from every wall, uniform heading and resting face; or
    ``reset(options={"pose": (x_cm, y_cm, heading_deg), "face": 1..20})``.

    ## Episode End
    Never terminates; truncated after ``max_episode_steps`` (500 at registration).
    ``info["episode_metrics"]`` holds ``wall_distance_error_cm`` (mean |d - d*|), ``perimeter_fraction``
    (fraction of the wall length passed within ``follow_tolerance_cm`` of d*), ``laps`` (completed
    counter-clockwise turns about the room's centre), ``progress_cm``, ``blocked_tips`` and
    ``oscillation_events`` (tips that undo the previous tip).

    ## Arguments
    | argument | default | meaning |
    |----------|---------|---------|
    | floor_plan | "rectangle" | a built-in plan ("rectangle", "l_room", "corner", "hallway", "office"), "random", or a list of (x1, y1, x2, y2) wall segments in cm |
    | d_star_cm | 50.0 | wall-following distance d* (the paper leaves it free) |
    | x_s_cm | 20.0 | the paper's x_s, weight of progress against distance error |
    | follow_tolerance_cm | 20.0 | \\|d - d*\\| within which the wall counts as followed |
    | noise_scale | 1.0 | tipping noise: 0 = ideal lattice, 1 = the paper's Vicon measurements |
    | range_noise_scale | 1.0 | multiplies the eq. 6 range noise sd |
    | step_forward_cm, step_forward_sd_cm | 9.266, 0.105 | forward step per tip (paper, Test Results) |
    | step_lateral_cm, step_lateral_sd_cm | -0.745, 0.149 | lateral step per tip (paper) |
    | heading_change_deg, heading_sd_deg | 0.31, 0.44 | heading change per tip (paper) |
    | body_radius_cm | 13.0 | contact radius (the 26 cm diameter) |
    | render_mode | None | "rgb_array" or "human" |

    ## Version History
    * v0: initial version.
    """

    reward_names = ("progress", "distance", "blocked")

    def __init__(
        self,
        *,
        d_star_cm: float = 50.0,
        x_s_cm: float = 20.0,
        follow_tolerance_cm: float = 20.0,
        **kwargs,
    ):
        self.d_star_cm = check_positive("d_star_cm", d_star_cm)
        self.x_s_cm = check_positive("x_s_cm", x_s_cm)
        self.follow_tolerance_cm = check_positive("follow_tolerance_cm", follow_tolerance_cm)
        super().__init__(**kwargs)
        n = self._batch_size
        self._distance_norm = 2.0 * self.x_s_cm * STEP_LENGTH_CM
        self._follow_reach = self.d_star_cm + self.follow_tolerance_cm
        # Per row: pose terms after the last step (x, y, wall normal x, y, angle about the room's centre) and sums.
        self._previous = np.zeros((n, 5))
        self._distance_error_sum = np.zeros(n)
        self._progress_cm = np.zeros(n)
        self._winding = np.zeros(n)
        self._followed_length = np.zeros(n)
        self._bins_plan = None

    def _prepare_bins(self) -> None:
        """Cut every wall into ~10 cm bins, stored segment by segment so a step looks at one segment's run."""
        plan = self.plan
        seg = plan.segments
        length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
        counts = np.maximum(1, np.ceil(length / _PERIMETER_BIN_CM).astype(np.int64))
        owner = np.repeat(np.arange(len(seg)), counts)
        frac = (np.concatenate([np.arange(n) for n in counts]) + 0.5) / counts[owner]
        self._bin_centre = seg[owner, :2] + frac[:, None] * (seg[owner, 2:] - seg[owner, :2])
        self._bin_length = (length / counts)[owner]
        bounds = np.concatenate([[0], np.cumsum(counts)])
        self._segment_first, self._segment_stop = bounds[:-1].copy(), bounds[1:].copy()
        self._wall_length = float(length.sum())
        g = plan.grid()
        self._lap_centre = g.centres()[g.region == g.main_region].mean(axis=0)
        self._followed = np.zeros((self._batch_size, len(self._bin_centre)), dtype=bool)
        self._bins_plan = plan

    def _task_reset(self, rows, options):
        if self._bins_plan is not self.plan:
            self._prepare_bins()
        self._followed[rows] = False
        for record in (self._distance_error_sum, self._progress_cm, self._winding, self._followed_length):
            record[rows] = 0.0
        _pose_terms(rows, self.sim.position, self.sim.wall_foot, self._lap_centre, self._previous)

    def _task_step(self, actions, blocked, active):
        sim = self.sim
        _wall_follow_step(
            active, blocked, sim.position, sim.wall_foot, sim.wall_distance, sim.wall_segment, self._lap_centre,
            self._previous, self.d_star_cm, self.follow_tolerance_cm, self._follow_reach, self._distance_norm,
            self._bin_centre, self._bin_length, self._segment_first, self._segment_stop, self._followed,
            self._followed_length, self._distance_error_sum, self._progress_cm, self._winding, self._rewards,
        )  # fmt: skip

    def _episode_metrics(self, row):
        metrics = super()._episode_metrics(row)
        metrics.update(
            wall_distance_error_cm=float(self._distance_error_sum[row]) / max(int(self.steps[row]), 1),
            perimeter_fraction=float(self._followed_length[row]) / self._wall_length,
            laps=int(max(float(self._winding[row]), 0.0) // (2 * math.pi)),
            progress_cm=float(self._progress_cm[row]),
        )
        return metrics


@njit(cache=True)
def _pose_terms(rows, position, wall_foot, lap_centre, out):
    """(x, y, unit normal towards the nearest wall, angle about the room's centre) of each row, into ``out``."""
    for n in range(rows.shape[0]):
        b = rows[n]
        x, y = position[b, 0], position[b, 1]
        fx, fy = wall_foot[b, 0], wall_foot[b, 1]
        gap = max(math.hypot(fx - x, fy - y), 1e-9)
        out[b, 0], out[b, 1] = x, y
        out[b, 2], out[b, 3] = (fx - x) / gap, (fy - y) / gap
        out[b, 4] = math.atan2(y - lap_centre[1], x - lap_centre[0])


@njit(cache=True)
def _wall_follow_step(
    active, blocked, position, wall_foot, wall_distance, wall_segment, lap_centre, previous, d_star, tolerance,
    reach, distance_norm, bin_centre, bin_length, segment_first, segment_stop, followed, followed_length,
    distance_error_sum, progress_sum, winding, rewards,
):  # fmt: skip
    for b in range(active.shape[0]):
        if not active[b]:
            rewards[b, :] = 0.0
            continue
        x0, y0, nx, ny, angle0 = previous[b, 0], previous[b, 1], previous[b, 2], previous[b, 3], previous[b, 4]
        x, y = position[b, 0], position[b, 1]
        # Progress along the tangent z x (centre-to-wall) of the wall nearest before the tip: counter-clockwise.
        progress = (x - x0) * -ny + (y - y0) * nx
        progress_sum[b] += progress
        error = wall_distance[b] - d_star
        distance_error_sum[b] += abs(error)
        if abs(error) <= tolerance:  # following: mark the nearest wall's bins within reach
            k = wall_segment[b]
            for i in range(segment_first[k], segment_stop[k]):
                if not followed[b, i] and math.hypot(bin_centre[i, 0] - x, bin_centre[i, 1] - y) <= reach:
                    followed[b, i] = True
                    followed_length[b] += bin_length[i]
        fx, fy = wall_foot[b, 0], wall_foot[b, 1]
        gap = max(math.hypot(fx - x, fy - y), 1e-9)
        angle = math.atan2(y - lap_centre[1], x - lap_centre[0])
        winding[b] += (angle - angle0 + math.pi) % (2 * math.pi) - math.pi
        previous[b, 0], previous[b, 1], previous[b, 2], previous[b, 3], previous[b, 4] = (
            x, y, (fx - x) / gap, (fy - y) / gap, angle,
        )  # fmt: skip
        rewards[b, 0] = progress / STEP_LENGTH_CM
        rewards[b, 1] = -(error * error) / distance_norm
        rewards[b, 2] = -1.0 if blocked[b] else 0.0
