"""BuckybotWallFollow: follow the nearest wall counter-clockwise at a fixed distance."""

from __future__ import annotations

import math

import numpy as np

from polyenvs.buckybot import simulator as S
from polyenvs.buckybot.env import BuckybotEnv, BuckybotParams, reset_task, step_task
from polyenvs.buckybot.floor_plans import LAYOUT_SPLIT
from polyenvs.buckybot.geometry import STEP_LENGTH_CM
from polyenvs.core.floor_plan import FloorPlan
from polyenvs.core.jit import njit
from polyenvs.core.layouts import documents_layouts
from polyenvs.core.parameters import documents_arguments
from polyenvs.core.validation import check_in_range

__all__ = ["BuckybotWallFollowEnv"]


#: The reward terms and the task's own metrics, by name (``info["reward_<term>"]``, ``info["episode_metrics"]``).
REWARD_TERMS = ("progress", "distance", "blocked")
METRICS = ("wall_distance_error_cm", "perimeter_fraction", "laps", "progress_cm")
OUT = BuckybotEnv.task_columns(REWARD_TERMS, METRICS)
_R_PROGRESS, _R_DISTANCE, _R_BLOCKED = OUT.term_columns("progress", "distance", "blocked")
_M_ERROR, _M_PERIMETER = OUT.metric_columns("wall_distance_error_cm", "perimeter_fraction")
_M_LAPS, _M_PROGRESS = OUT.metric_columns("laps", "progress_cm")

_PERIMETER_BIN_CM = 10.0
# Columns of the task state: pose terms after the last step (x, y, unit normal towards the nearest wall, angle
# about the room's centre) and the episode's sums.
_PX, _PY, _NX, _NY, _ANGLE, _ERROR_SUM, _PROGRESS, _WINDING, _FOLLOWED = range(9)
_TASK_COLUMNS = 9
_D_STAR, _TOLERANCE, _REACH, _NORM = range(4)


@njit(cache=True)
def _pose_terms(b, state, slot_info, task):
    x, y = state[b, S.X], state[b, S.Y]
    fx, fy = state[b, S.FOOT_X], state[b, S.FOOT_Y]
    gap = max(math.hypot(fx - x, fy - y), 1e-9)
    task[b, _PX], task[b, _PY] = x, y
    task[b, _NX], task[b, _NY] = (fx - x) / gap, (fy - y) / gap
    task[b, _ANGLE] = math.atan2(y - slot_info[1], x - slot_info[0])


@njit(cache=True)
def _write_metrics(b, state, task, slot_info, out):
    out[b, _M_ERROR] = task[b, _ERROR_SUM] / max(state[b, S.STEPS], 1.0)
    out[b, _M_PERIMETER] = task[b, _FOLLOWED] / slot_info[2]
    out[b, _M_LAPS] = math.floor(max(task[b, _WINDING], 0.0) / (2 * math.pi))
    out[b, _M_PROGRESS] = task[b, _PROGRESS]


@njit(cache=True)
def _start_row(b, sim, task_arrays, out):
    """Freshly placed robot ``b``: nothing followed yet, its pose terms."""
    state, slot = sim[S.A_STATE], task_arrays[4][S.plan_slot(b, sim)]
    task, followed = task_arrays[0], task_arrays[1]
    followed[b, :] = False
    task[b, :] = 0.0
    _pose_terms(b, state, slot, task)
    _write_metrics(b, state, task, slot, out)
    return False  # never terminates


@njit(cache=True)
def _score_row(b, sim, task_arrays, out):
    """Robot ``b`` after its tip: progress along the wall, distance error, the wall it followed."""
    state, w = sim[S.A_STATE], S.plan_slot(b, sim)
    task, followed, bins, seg_bins, slot, tp = task_arrays
    x, y = state[b, S.X], state[b, S.Y]
    # Progress along the tangent z x (centre-to-wall) of the wall nearest before the tip: counter-clockwise.
    progress = (x - task[b, _PX]) * -task[b, _NY] + (y - task[b, _PY]) * task[b, _NX]
    task[b, _PROGRESS] += progress
    error = state[b, S.WALL_DISTANCE] - tp[_D_STAR]
    task[b, _ERROR_SUM] += abs(error)
    if abs(error) <= tp[_TOLERANCE]:  # following: mark the nearest wall's bins within reach
        k = int(state[b, S.WALL_SEGMENT])
        first, stop = seg_bins[w, k, 0], seg_bins[w, k, 1]
        # Bins sit evenly along the wall: only those within reach of the foot along it can be within reach.
        wall = sim[S.A_WALLS][w, k]
        along = ((state[b, S.FOOT_X] - wall[0]) * wall[2] + (state[b, S.FOOT_Y] - wall[1]) * wall[3]) * wall[4]
        spread = tp[_REACH] * math.sqrt(wall[4]) * (stop - first)  # reach in bins
        centre = along * (stop - first) - 0.5
        lo, hi = max(first, first + int(math.ceil(centre - spread))), min(stop, first + int(centre + spread) + 1)
        for i in range(lo, hi):
            if not followed[b, i] and math.hypot(bins[w, i, 0] - x, bins[w, i, 1] - y) <= tp[_REACH]:
                followed[b, i] = True
                task[b, _FOLLOWED] += bins[w, i, 2]
    angle0 = task[b, _ANGLE]
    _pose_terms(b, state, slot[w], task)
    task[b, _WINDING] += (task[b, _ANGLE] - angle0 + math.pi) % (2 * math.pi) - math.pi
    out[b, _R_PROGRESS] = progress / STEP_LENGTH_CM
    out[b, _R_DISTANCE] = -(error * error) / tp[_NORM]
    out[b, _R_BLOCKED] = -1.0 if state[b, S.BLOCKED] > 0.5 else 0.0
    _write_metrics(b, state, task, slot[w], out)
    return False  # never terminates


@njit(cache=True)
def _reset_kernel(rows, kernel):
    reset_task(rows, kernel, _start_row, REWARD_TERMS)


@njit(cache=True)
def _step_kernel(actions, kernel):
    step_task(actions, kernel, _score_row, REWARD_TERMS)


@documents_arguments(BuckybotParams)
@documents_layouts(LAYOUT_SPLIT)
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
    ``Discrete(3)`` (:class:`~polyenvs.buckybot.env.BuckybotAction`: 0 BACK, 1 FORWARD_RIGHT, 2 FORWARD_LEFT):
    tip towards frame direction 0, 1 or 2 (azimuths 0°, 120°, 240° in the resting face's frame,
    counter-clockwise from above). Direction 0 points back over the edge the robot last tipped over (after a
    reset: the edge opposite the resting face's first-lettered actuator), so action 0 undoes the previous tip.
    A tip whose landing point would bring the body (radius 13 cm) against a wall, or whose motion would cross a
    wall, is blocked: the robot stays. ``gymnasium.utils.play`` keys: s, d, a.

    ## Observation Space
    ``Box(0, 1, (19,), float32)``, described by ``env.observation_structure``:

    | index | name | meaning |
    |-------|------|---------|
    | 0-5 | range | reading / 182.88 cm of the sensors at azimuths 22.24°, 97.76°, 142.24°, 217.76°, 262.24°, 337.76°; 0 if too close, 1 if no return |
    | 6-11 | too_close | 1 where the sensor did not settle (< 30.48 cm) |
    | 12-17 | no_return | 1 where nothing was seen within 182.88 cm |
    | 18 | tip_failed | 1 if the last tip was blocked |

    Readings follow the paper's eq. 6, ``d + (0.013 d + 0.448) w`` cm, rounded to 2.54 cm.

    Ground truth stays out of the observation and goes into ``info`` (in reset and step alike):

    | key | meaning |
    |-----|---------|
    | ground_truth | one float64 array of 16: ``pose`` (0-2) and ``dead_reckoned_pose`` (3-5), each x cm, y cm and the heading of frame direction 0 in degrees; ``tip_directions_deg`` (6-8), the world azimuths of the three actions; ``true_range_cm`` (9-14), the slant range along each observed beam to the first wall (inf if none); ``wall_distance_cm`` (15), from the centre to the nearest wall. ``env.unwrapped.ground_truth_structure`` names the parts, :func:`~polyenvs.buckybot.env.ground_truth_parts` splits them |
    | face | the resting face, 1-20 |
    | blocked | whether the last tip was blocked |
    | action_mask | int8, tips that would not hit a wall (also ``env.action_masks()`` for MaskablePPO) |
    | reward_progress, reward_distance, reward_blocked | the reward's terms |
    | episode_metrics | the episode's metrics (see Episode End), in the info of the step that ends it only |

    ``env.unwrapped.frame_labels()`` gives what the frame is on the body: the actuator letter each action extends
    and the faces carrying the six observed sensors. (Before 2026-12-02 each part of the ground truth and those
    labels were entries of their own: building a dozen fresh arrays per step cost half a CartPole step.) A native
    vector env's ``info["ground_truth"]`` is a read-only view of its state, valid until the next step or reset:
    copy it to keep it.

    ## Rewards
    The paper's per-step cost ``(d - d*)² - 2 x_s · Δs`` (its eq. 5 weighs distance error against progress; the
    exact weight is garbled in the paper), negated and normalised by ``2 x_s · 9.129 cm`` so a step along the wall
    earns about 1: ``reward_progress = Δs / 9.129`` with Δs the displacement along the nearest wall's
    counter-clockwise tangent (z × centre-to-wall), ``reward_distance = -(d - d*)² / (2 x_s · 9.129)`` with d the
    true distance to the nearest wall after the tip, and ``reward_blocked = -1`` for a blocked tip.
    Why 2 x_s: for one straight wall, the paper's rule (tip towards the point d* off the wall and x_s along it)
    minimises the squared distance to that point, ``(d - d*)² - 2 x_s Δs + Δs² + const``: this cost plus Δs².
    The rule is therefore close to the greedy maximiser of this reward but not the same: the Δs² term favours
    shorter moves along the wall, and the reward measures d to the nearest of all walls, so the two choose
    different tips in a small fraction of states (1.4-2.9% of random single-wall states, measured in issue 5).

    ## Starting State
    A seeded position at least 23 cm from every wall, uniform heading and resting face; or
    ``reset(options={"pose": (x_cm, y_cm, heading_deg), "face": 1..20})``.

    ## Episode End
    Never terminates; truncated after ``max_episode_steps`` (500 at registration). The metrics
    (``env.unwrapped.episode_metrics()`` at any time; under Gymnasium's time limit, the last ``info`` has them through
    :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics`) are ``wall_distance_error_cm`` (mean |d - d*|),
    ``perimeter_fraction`` (fraction of the wall length passed within ``follow_tolerance_cm`` of d*), ``laps``
    (completed counter-clockwise turns about the room's centre), ``progress_cm``, ``blocked_tips`` and
    ``oscillation_events`` (tips that undo the previous tip).

    ## Task score
    ``perimeter_fraction`` (max, ceiling 1; ties at the ceiling broken by the lower ``wall_distance_error_cm``).
    The paper's task is to follow the closest wall at d*, and its failure is getting stuck (in 90° corners and
    narrow hallways), which the return can hide: hovering at d* beside one wall earns the distance term at every
    step. The score is the fraction of the room's wall length passed within ``follow_tolerance_cm`` of d*, so
    only following the wall, at the paper's distance and all the way round, raises it; two robots that follow it
    all are told apart by how close to d* they kept (the distance half of the paper's eq. 5).

    ## Arguments
    | argument | default | meaning |
    |----------|---------|---------|
    | floor_plan | "rectangle" | a built-in plan ("rectangle", "l_room", "corner", "hallway", "office"), "random", or a list of (x1, y1, x2, y2) wall segments in cm |
    {layouts}
    | d_star_cm | 50.0 | wall-following distance d* from the centre, in [20, 150] (the paper leaves it free; the sonar sees to 184 cm) |
    | x_s_cm | 20.0 | the paper's x_s, look-ahead along the wall and weight of progress, in [1, 100] |
    | follow_tolerance_cm | 20.0 | \\|d - d*\\| within which the wall counts as followed, in [1, 100] |
    {arguments}
    | render_mode | None | "rgb_array" or "human" |
    | window_scale | 1.0 | with render_mode="human", the window shows each frame zoomed by this factor, in [0.25, 8]; rgb_array frames are unchanged |
    | num_rows | 1 | rows simulated at once, an integer in [1, 1e6]: the native vector env sets it (``gym.make_vec``) |

    Out-of-range, non-finite, ``bool`` or ``str`` values raise ``ValueError`` naming the argument.

    ## Version History
    {version_history}
    """

    out_columns = OUT

    def __init__(
        self,
        *,
        d_star_cm: float = 50.0,
        x_s_cm: float = 20.0,
        follow_tolerance_cm: float = 20.0,
        **kwargs,
    ):
        self.d_star_cm = check_in_range("d_star_cm", d_star_cm, 20.0, 150.0)
        self.x_s_cm = check_in_range("x_s_cm", x_s_cm, 1.0, 100.0)
        self.follow_tolerance_cm = check_in_range("follow_tolerance_cm", follow_tolerance_cm, 1.0, 100.0)
        super().__init__(**kwargs)

    def _task_init(self):
        n, slots, n_walls = self._batch_size, self._n_slots, self.sim.walls.shape[1]
        # d*, tolerance, reach within which a followed wall's bins count, the reward's normaliser.
        self._task_params = np.array(
            [self.d_star_cm, self.follow_tolerance_cm, self.d_star_cm + self.follow_tolerance_cm,
             2.0 * self.x_s_cm * STEP_LENGTH_CM]
        )  # fmt: skip
        self._task_state = np.zeros((n, _TASK_COLUMNS))
        self._bins = np.zeros((slots, 1, 3))  # per plan slot: ~10 cm wall bins (centre x, y, length)
        self._segment_bins = np.zeros((slots, n_walls, 2), dtype=np.int64)  # each wall's [first, stop) bins
        self._slot_info = np.zeros((slots, 3))  # lap centre x, y, total wall length
        self._followed = np.zeros((n, 1), dtype=np.bool_)

    def _task_arrays(self):
        return (self._task_state, self._followed, self._bins, self._segment_bins, self._slot_info, self._task_params)

    def _task_install_plan(self, slot: int, plan: FloorPlan) -> None:
        """Cut every wall into ~10 cm bins, stored segment by segment so a step looks at one segment's run."""
        seg = plan.segments
        length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
        counts = np.maximum(1, np.ceil(length / _PERIMETER_BIN_CM).astype(np.int64))
        owner = np.repeat(np.arange(len(seg)), counts)
        frac = (np.concatenate([np.arange(n) for n in counts]) + 0.5) / counts[owner]
        if len(owner) > self._bins.shape[1]:  # a larger room than any before: grow the tables (rare)
            grown = np.zeros((self._bins.shape[0], len(owner), 3))
            grown[:, : self._bins.shape[1]] = self._bins
            followed = np.zeros((self._batch_size, len(owner)), dtype=np.bool_)
            followed[:, : self._followed.shape[1]] = self._followed
            self._bins, self._followed = grown, followed
            self._repack_task()
        self._bins[slot] = 0.0
        self._bins[slot, : len(owner), 0:2] = seg[owner, :2] + frac[:, None] * (seg[owner, 2:] - seg[owner, :2])
        self._bins[slot, : len(owner), 2] = (length / counts)[owner]
        bounds = np.concatenate([[0], np.cumsum(counts)])
        self._segment_bins[slot] = 0
        self._segment_bins[slot, : len(seg), 0], self._segment_bins[slot, : len(seg), 1] = bounds[:-1], bounds[1:]
        g = plan.grid()
        self._slot_info[slot, 0:2] = g.centres()[g.region == g.main_region].mean(axis=0)
        self._slot_info[slot, 2] = float(length.sum())

    _step_kernel = staticmethod(_step_kernel)
    _reset_kernel = staticmethod(_reset_kernel)
