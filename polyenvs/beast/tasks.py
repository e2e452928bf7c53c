"""The four beast tasks: one canonical tumble, rolling along a heading, the sharp turn, recovery from a throw.

Each is a small subclass of :class:`polyenvs.beast.env.BeastEnv`: its start state, its reward terms and its metrics.
The docstrings share their Action Space, Observation Space and common Arguments sections (``_doc``).
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.beast import kernel as KR
from polyenvs.beast import kinematics as K
from polyenvs.beast.env import POWER_METRICS, TRAVEL_METRICS, BeastEnv, RobotContactParams, SensorParams
from polyenvs.beast.layouts import LAYOUT_SPLIT
from polyenvs.beast.mujoco_extra import mujoco
from polyenvs.core.parameters import argument_rows
from polyenvs.core.validation import check_in_range

__all__ = [
    "BeastRecoverEnv",
    "BeastRecoverV1Env",
    "BeastRollEnv",
    "BeastRollV1Env",
    "BeastTumbleEnv",
    "BeastTumbleV1Env",
    "BeastTurnEnv",
    "BeastTurnV1Env",
    "STRIP_OFFSET_DEG",
]

#: Direction of the straight rolling strip relative to the first tumble's direction (deg). For the 4-beast the
#: working tumble's sequence (1234)(4213)(4321)(1342) runs from foot 3 towards foot 2 of K0, 30 degrees to the left
#: of the first tumble (spec appendix); the other beasts have no measured strip and roll along their first tumble.
STRIP_OFFSET_DEG = {"tetrahedron": 30.0, "octahedron": 0.0, "cube": 0.0}
#: The sharp turn's joint-1 range (deg): a limb planted through three tumbles in a row winds joint 1 by 360 degrees.
TURN_JOINT1_RANGE = {"joint1_low_deg": -250.0, "joint1_high_deg": 250.0}
#: Limbs on the floor after the canonical tumble (1234): 1, 4 and 2, with 3 free (bitmask of limb numbers).
CANONICAL_END = (1 << 0) | (1 << 3) | (1 << 1)

_SHARED = """
    ## Action Space
    ``Box(-1, 1, (n_joints,), float32)``, n_joints = 3 x limbs (12 for the 4-beast), ordered limb-major: joint k of
    limb i (1-based) is index 3(i - 1) + (k - 1), the MuJoCo joint and actuator ``limb{i}_joint{k}``. With
    ``control="position"`` (default) an action is a joint position target scaled linearly to the joint's range,
    target = low + (a + 1)/2 (high - low), tracked by a servo of kp 300 N m/rad limited to +-6 N m; ranges (deg)
    theta1 [-180, 180], theta2 [-120, 160], theta3 [-150, 150]. With ``control="torque"`` an action is a torque,
    a x 6 N m. The joint angles are the DH angles of Table 1 (``polyenvs.beast.kinematics``). Joints of
    ``disabled_limbs`` are locked where they start (a failed worm drive does not backdrive) and ignore the action.
    An action outside [-1, 1], non-finite or of the wrong shape raises ``ValueError`` and changes nothing.

    ## Control period
    An action is held for ``control_timestep`` seconds: 10 ms by default (the sensor tick), up to 100 ms in whole
    ticks. A step runs that many ticks (the sensors, switches, stance and tumble counts keep the 10 ms tick), sums
    their rewards and reward terms, and ends early on the tick the task terminates; the observation is the last
    tick's. So an episode over the same simulated time returns what a 10 ms agent repeating each action would. The
    registered ``max_episode_steps`` counts 10 ms steps: for the same simulated time pass ``max_episode_steps =
    registered x 0.01 / control_timestep`` to ``gym.make`` (BeastRoll: 8000 steps at 10 ms, 1600 at 50 ms). The
    paper's gaits (``baselines.beast``) count their clock in 10 ms steps: they run at the default period only.

    ## Observation Space
    ``Box(float32)``: the robot's own sensors, concatenated (``env.unwrapped.observation_structure`` maps each name
    to its slice):

    | part | size | meaning | unit |
    | --- | --- | --- | --- |
    | joint_pos | n_joints | encoder angles, behind a backlash dead band of ``backlash_deg`` | rad |
    | joint_vel | n_joints | encoder angle differences over the 10 ms tick, clipped to +-50 | rad/s |
    | tilt | 12 | tilt switches on the icosahedron's vertex axes: 1 when the axis points more than ``tilt_threshold_deg`` below horizontal | 0/1 |
    | foot_contact | n_limbs | foot switches: 1 while the foot sphere touches the floor | 0/1 |
    | prev_action | n_joints | the last action applied (at reset: the action that holds the start pose) | |
    | body_pos, body_quat, body_linvel, body_angvel | 3, 4, 3, 3 | only with ``privileged=True``: torso position (world, m), orientation (w, x, y, z), linear velocity (world, m/s), angular velocity (body frame, rad/s), velocities clipped to +-50 | |
    | command | 2 | ``BeastTurn-v0`` only: cos and sin of ``turn_deg``, constant through the episode | |

    The encoder angles are clipped to the joint limits, which are their bounds in the observation space.
"""


def _common_args(params) -> str:
    """The Arguments rows every beast id shares, with ``params``' defaults (the -v0 or the -v1 ids')."""
    return f"""
    | polyhedron | "tetrahedron" | the 4-beast; "octahedron" (6-beast, limbs on +-x, +-y, +-z), "cube" (8-beast) |
    | privileged | False | append the true body pose and velocity to the observation |
    | disabled_limbs | () | 1-based limb numbers whose joints are locked (paper section 5's faults) |
    | control | "position" | "position" servos or "torque" motors (a motor has no servo dead band) |
{argument_rows(params)}
    | physics | None | dict of model parameters (``polyenvs.beast.model.BeastModelParams``: link lengths, masses, kp, torque_limit, friction, foot_radius, joint ranges, timestep dividing 10 ms), each bounded; with ``layouts="train"`` or ``"test"`` it may not set the parameters the layouts draw |
    {LAYOUT_SPLIT.argument_row()}
    | render_mode | None | "rgb_array" or "depth_array" through MuJoCo's renderer, camera ``track`` following the torso |
    | width, height | 480, 480 | frame size, fixed per instance |
"""


_V0_HISTORY = """    - v0: first version (MuJoCo 4.0). Since 2026-12 a drawn start state is rounded to 1e-9, so an episode no
      longer depends on the CPU kernels numpy and OpenBLAS pick (the same start distribution; the reference
      leaderboard was regenerated with it, a version bump was not warranted for a last-bit change). Its servos
      and foot switches are ideal: under Gaussian action noise of sd 0.003 (half a degree of joint-1 target) at
      100 Hz the feet chatter, the switches flip thousands of times an episode and the paper's gait stalls.
      Changed in place on 2026-12-01, with the reference leaderboard re-evaluated: a tumble counts only when it
      ends in a stance on the feet (a trained agent had "succeeded" by flopping onto its body), and BeastTurn-v0
      gives joint 1 a range of +-250 degrees and has the commanded turn (cos, sin) in its observation (Box(54)).
      Added on 2026-12-02 without changing a default episode: ``layouts=`` (held-out friction, mass, servo gain
      and damping). Added on 2026-12-05 without changing an episode (returns, lengths, observations and the other
      metrics as before), to every beast id: the metrics ``mean_power_w``, ``peak_power_w`` and, on Tumble, Roll
      and Turn, ``cost_of_transport`` (the actuators' mechanical power, see Episode End).
"""
_V1_HISTORY = """    - v1: the robot's contact model by default (``RobotContactParams``): each servo stops within
      ``servo_deadband_deg`` = 0.25 of its target, where the worm drive holds the joint, and each foot switch
      reports a change once it has held for ``switch_debounce_ms`` = 30 (3 ticks). With action noise of sd 0.003
      the paper's gait rolls on (BeastRoll, seeds 0 and 1: 5 tumbles, 0.80 m in 80 s, against 0 tumbles on v0).
"""

#: Issue 33's lean info and native vector env, in every beast id's history (the lean info in the project's words).
_LEAN_INFO = """    - ``info`` made lean without changing an episode (2026-12-05): ``info["episode_metrics"]`` is only in the
      info of the step that ends the episode (terminated, or truncated by the env itself; on a native vector env's
      rows that end, time limit included), ``env.unwrapped.episode_metrics()`` returns them at any time, and
      :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics` adds them where Gymnasium's ``TimeLimit``
      truncates. Added the same day without changing an episode: the native vector env (``gym.make_vec``, see
      Vector environment).
"""


#: The power metrics every task reports after its own (``polyenvs.beast.env.POWER_METRICS``).
_POWER = """    The last metrics are the actuators' mechanical power P, the sum over the joints of max(0, torque x joint
    speed), sampled every 10 ms tick: the actuator's torque over the tick's last physics step (2 ms; MuJoCo's
    ``actuator_force``) times the joint's speed at its end. The model is SI (kg, m, s; torques in N m, speeds in
    rad/s), so P is in watts: the mechanical power the motors deliver to the joints, what the joints' damping (the
    worm drive's friction) dissipates included; negative work is not recovered (a worm drive does not backdrive).
    It is not the electrical power the robot draws (the paper's "under 12 W" includes the motors' and the gears'
    losses and four microcontrollers). ``mean_power_w`` (W): the mean of P over the episode's ticks so far;
    ``peak_power_w`` (W): the largest P of any tick so far (of the 10 ms samples: a shorter spike between them is
    not seen)."""
_COST_OF_TRANSPORT = """ ``cost_of_transport`` (dimensionless): the energy (the ticks' P x 10 ms, J) over
    the robot's weight (the model's total mass, with a layout's body mass, x 9.81 m/s^2, N) times ``distance_m``;
    0 while ``distance_m`` is not positive, so that it stays finite."""


def _doc(summary, rewards, start, end, args, *, score: str, v1: str | None = None, travels: bool = True) -> str:
    """A beast id's docstring; ``v1`` (what its reward changed, or None for a -v0 id) makes it the -v1 id's;
    ``travels``: the task reports a ``distance_m`` and so a cost of transport."""
    params = SensorParams if v1 is None else RobotContactParams
    power = _POWER + (_COST_OF_TRANSPORT if travels else "")
    history = (_V0_HISTORY if v1 is None else _V0_HISTORY + _V1_HISTORY + v1) + _LEAN_INFO
    return f"""{summary}
{_SHARED}
    ## Rewards
{rewards}
    Each term is in ``info["reward_<name>"]``; they sum to the reward. ``info["sim_unstable"]`` is True on the step
    where the simulation diverged. ``info["episode_metrics"]`` holds the metrics in the info of the step that ends
    the episode (terminated, or truncated by a divergence); ``env.unwrapped.episode_metrics()`` returns them at any
    time (the final ones after the end, until the next reset).

    ## Vector environment
    ``gym.make_vec(id, num_envs=N)`` is the id's native vector env (:mod:`polyenvs.beast.vector`): N of these
    environments stepped on ``threads`` threads (a keyword, default ``os.cpu_count()``) in one compiled call each,
    with the GIL released; sub-env ``i`` reset with seed ``s`` is ``gym.make(id)`` reset with seed ``s + i``, bit for
    bit, through autoresets.

    ## Task score
{score}
    ## Starting State
{start}
    ## Episode End
{end}
{power}

    A diverged simulation (non-finite or speeds over 1000) truncates the episode with ``info["sim_unstable"]``,
    the last finite observation and a reward of 0.

    ## Arguments
    | argument | default | meaning |
    | --- | --- | --- |
{args}{_common_args(params)}
    ## Version History
{history}"""


_TUMBLE = (
    """One canonical tumble (1234) of a Platonic beast (Pai, Barman and Ralph, section 3).

    ## Description
    The 4-beast stands on limbs 1, 2, 3 with limb 4 straight up, in the working tumble's start stance K0 (feet on
    an equilateral pattern of side 300 mm, body centre 168 mm up, ``../shared/spec/beast.md``). The task is the
    paper's canonical tumble: move the centre of mass over the edge of feet 1 and 2, place foot 4 so that it lands
    after the tip, and end standing on limbs 1, 4 and 2 with limb 3 free. The tumble goes along world +x. For the
    6- and 8-beast any tumble (a new stance after the body has rolled by more than 45 degrees) counts.""",
    """    - ``progress``: body velocity along +x (m/s);
    - ``success``: ``success_reward`` on the step the tumble completes;
    - ``ctrl``: minus ``ctrl_cost_weight`` x mean squared joint torque / limit^2.
""",
    """    K0 (or the start stance of the 6-/8-beast: three or four feet down, free limbs straight out), turned by a
    random yaw of up to 2 degrees and shifted up to 5 mm; free limbs jittered by up to 2 degrees; the encoders'
    positions in their backlash band drawn at random. ``reset(options={"qpos": ..., "qvel": ...})`` starts from a
    given MuJoCo state instead.
""",
    """    Terminates on success: limbs 1, 4, 2 on the floor and 3 free, nothing else touching the floor (a stance,
    not a fall), held 0.2 s, after the body rolled by more than 45 degrees. Metrics: ``success`` (0/1), ``time_s`` (time to success, or elapsed), ``distance_m`` (along +x).
    Truncated after 3000 steps (30 s; the working tumble takes 17 s at 20 deg/s) by the registry's time limit.
""",
    """    | success_reward | 10 | reward for completing the tumble |
""",
)

_ROLL = (
    """Rolling along a commanded heading by a sequence of tumbles (the paper's rolling gait, section 3).

    ## Description
    A Platonic beast starts in its start stance (the working tumble's K0 for the 4-beast) and is rewarded for
    moving its body along the commanded heading. The start stance is turned so that the straight strip of
    support triangles of the working tumble's sequence (1234)(4213)(4321)(1342), which runs from foot 3 towards
    foot 2, points along the heading (for the 6- and 8-beast, the first tumble's direction does). The feasibility
    study's rolling gait makes about 0.155 m per tumble and 17 s per tumble at 20 deg/s joint rates.""",
    """    - ``forward``: body velocity along the commanded heading (m/s);
    - ``ctrl``: minus ``ctrl_cost_weight`` x mean squared joint torque / limit^2.
""",
    """    The start stance turned to the heading (see Description), plus a random yaw of up to 2 degrees and a shift
    of up to 5 mm; free limbs jittered by up to 2 degrees; encoder backlash positions random.
""",
    """    Never terminates; truncated after 8000 steps (80 s) by the registry's time limit. Metrics: ``distance_m``
    (body displacement along the heading), ``tumbles`` (support changes after which the body has rolled by more
    than 45 degrees), ``speed_m_s`` (distance / elapsed time).
""",
    """    | heading_deg | 0 | commanded heading, counter-clockwise from world +x, [-180, 180] |
""",
)

_TURN = (
    """The sharp turn of a Platonic beast (paper section 5, Figures 10 and 11): change the rolling direction.

    ## Description
    The beast starts as in ``BeastRoll-v0``, facing world +x along its strip, and must roll off in the direction
    turned by ``turn_deg`` from it, as a beast turning a sharp corner or passing a wall does: the paper keeps limb 1
    planted while the robot rolls about it, synthesising a cone. The heading of travel is measured over the last
    two tumbles (a straight strip zig-zags by +-30 degrees from one tumble to the next, and two tumbles follow it).
    The commanded turn is part of the observation (``command``). On a straight strip every limb stays planted
    through two tumbles in a row; turning keeps one planted through a third, which winds its joint 1 by 360
    degrees, so here joint 1's range defaults to +-250 degrees (a cable wrap, *ours*; ``physics`` may override it:
    with +-180 the 4-beast can only roll along its strip).""",
    """    - ``forward``: body velocity along the target direction (+x turned by ``turn_deg``) (m/s);
    - ``ctrl``: minus ``ctrl_cost_weight`` x mean squared joint torque / limit^2.
""",
    """    As ``BeastRoll-v0`` with heading 0: the strip along world +x; random yaw up to 2 degrees, shift up to 5 mm.
""",
    """    Never terminates; truncated after 8000 steps (80 s). Metrics: ``heading_change_deg`` (direction of the body's
    displacement over the last two tumbles, counter-clockwise from +x; 0 before two tumbles), ``heading_error_deg``
    (its difference from ``turn_deg``, 180 before two tumbles), ``tumbles``, ``distance_m`` (along the target).
""",
    """    | turn_deg | 60 | commanded change of heading, counter-clockwise, [-180, 180] |
""",
)

_RECOVER = (
    """Recovering from a throw (paper section 5: a Platonic beast has no preferred "up" and can recover from a
    topple).

    ## Description
    The beast starts in the air in a random orientation with random joint angles, moving and spinning as if
    thrown, falls, and must reach a stance: three or more feet on the floor, nothing else touching it, the body
    turning slower than 0.1 rad/s, held for 0.2 s.""",
    """    - ``support``: 0.01 x (feet on the floor - 3 if the body or a link touches the floor);
    - ``success``: ``success_reward`` on the step the stance is reached;
    - ``ctrl``: minus ``ctrl_cost_weight`` x mean squared joint torque / limit^2.
""",
    """    Orientation uniform over rotations; joint angles uniform over their ranges (redrawn while limbs or body
    overlap; after 20 draws the limbs straight out); lowest point 5-25 cm above the floor; horizontal velocity up to
    0.5 m/s, angular velocity up to 2 rad/s about each axis. All drawn from the env's generator.
""",
    """    Terminates on success. Metrics: ``success`` (0/1), ``time_to_stance_s`` (time when the final stance began;
    the elapsed time if none). Truncated after 2000 steps (20 s).
""",
    """    | success_reward | 10 | reward for reaching the stance |
""",
)


#: Each task's score (the registry row's ``score``), decided from the paper before any trained agent was looked at.
_TUMBLE_SCORE = """    ``success`` (max, ceiling 1; ties broken by ``time_s``, min): the paper verifies its prototype by performing
    the canonical tumble (section 2, Figure 4), which is done or not; moving forward without tumbling is not it.
"""
_ROLL_SCORE = """    ``distance_m`` along the commanded heading (max): the rolling gait is locomotion along a straight path
    (section 3, Figures 6 and 7), and how far the body got along it is what a path asks for.
"""
_TURN_SCORE = """    ``heading_error_deg`` at the episode's end (min, floor 0): the sharp turn changes the direction of rolling to
    pass a corner or a wall (section 5, Figures 10 and 11); only the direction rolled off in matters.
"""
_RECOVER_SCORE = """    ``success`` (max, ceiling 1; ties broken by ``time_to_stance_s``, min): the paper's claim is that a beast can
    recover from a topple, "a statically stable foot placement is available in all orientations" (section 5).
"""


class BeastTumbleEnv(BeastEnv):
    __doc__ = _doc(*_TUMBLE, score=_TUMBLE_SCORE)
    reward_names = ("progress", "success", "ctrl")
    metric_names = ("success", "time_s", "distance_m", *TRAVEL_METRICS)
    task_kind = KR.TUMBLE

    def __init__(self, success_reward: float = 10.0, **kwargs):
        self.success_reward = check_in_range("success_reward", success_reward, 0.0, 1000.0)
        super().__init__(**kwargs)

    def _task_reset(self, feet_mask: int) -> None:
        # The 4-beast must end on limbs 1, 4, 2 (the canonical tumble); the others on any new support.
        self._task[KR.TARGET_MASK] = CANONICAL_END if self.polyhedron == "tetrahedron" else -1.0


class BeastRollEnv(BeastEnv):
    __doc__ = _doc(*_ROLL, score=_ROLL_SCORE)
    reward_names = ("forward", "ctrl")
    metric_names = ("distance_m", "tumbles", "speed_m_s", *TRAVEL_METRICS)
    task_kind = KR.ROLL

    def __init__(self, heading_deg: float = 0.0, **kwargs):
        self.heading_deg = check_in_range("heading_deg", heading_deg, -180.0, 180.0)
        self.heading_rad = math.radians(self.heading_deg)
        super().__init__(**kwargs)

    def _initial_state(self, rng):
        qpos, qvel = self._stance_state(rng)
        yaw = math.radians(self.heading_deg - STRIP_OFFSET_DEG[self.polyhedron])
        return _turned(qpos, yaw), qvel

    def _task_reset(self, feet_mask: int) -> None:
        """Nothing beyond the shared start (the tumble counter, zero metrics)."""


class BeastTurnEnv(BeastEnv):
    __doc__ = _doc(*_TURN, score=_TURN_SCORE)
    reward_names = ("forward", "ctrl")
    metric_names = ("heading_change_deg", "heading_error_deg", "tumbles", "distance_m", *TRAVEL_METRICS)
    task_kind = KR.TURN

    def __init__(self, turn_deg: float = 60.0, physics: dict | None = None, **kwargs):
        self.turn_deg = check_in_range("turn_deg", turn_deg, -180.0, 180.0)
        self.heading_rad = math.radians(self.turn_deg)
        self.command = (math.cos(self.heading_rad), math.sin(self.heading_rad))
        if physics is None or isinstance(physics, dict):
            physics = {**TURN_JOINT1_RANGE, **(physics or {})}
        super().__init__(physics=physics, **kwargs)

    def _initial_state(self, rng):
        qpos, qvel = self._stance_state(rng)
        return _turned(qpos, math.radians(-STRIP_OFFSET_DEG[self.polyhedron])), qvel

    def _task_reset(self, feet_mask: int) -> None:
        # The heading is measured between stances, the first of them the start; the error is 180 until it is.
        task = self._task
        task[KR.STANCES : KR.STANCES + 2] = self._qpos[:2]
        task[KR.N_STANCES] = 1.0
        self._metric_row[self.metric_names.index("heading_error_deg")] = 180.0


class BeastRecoverEnv(BeastEnv):
    __doc__ = _doc(*_RECOVER, score=_RECOVER_SCORE, travels=False)
    reward_names = ("support", "success", "ctrl")
    metric_names = ("success", "time_to_stance_s", *POWER_METRICS)
    task_kind = KR.RECOVER

    def __init__(self, success_reward: float = 10.0, **kwargs):
        self.success_reward = check_in_range("success_reward", success_reward, 0.0, 1000.0)
        super().__init__(**kwargs)

    def _initial_state(self, rng):
        m = self.model
        data = mujoco.MjData(m)  # a scratch copy: drawing a start state must not touch the live simulation
        ranges = np.tile(self.params.joint_ranges, (self.n_limbs, 1))
        floor = m.geom("floor").id
        for attempt in range(21):
            quat = rng.normal(size=4)
            quat /= np.linalg.norm(quat)
            if attempt < 20:
                joints = rng.uniform(ranges[:, 0], ranges[:, 1])
            else:
                joints = np.tile(K.STRAIGHT_OUT, self.n_limbs)
            data.qpos[:] = np.concatenate([[0.0, 0.0, 2.0], quat, joints])
            mujoco.mj_forward(m, data)
            clash = any(c.geom1 != floor and c.geom2 != floor for c in data.contact[: data.ncon])
            if not clash:
                break
        lowest = min(
            data.geom_xpos[g, 2] - m.geom_rbound[g] if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE else np.inf
            for g in range(m.ngeom)
        )
        qpos = data.qpos.copy()
        qpos[2] += -lowest + rng.uniform(0.05, 0.25)
        qvel = np.zeros(m.nv)
        qvel[:2] = rng.uniform(-0.5, 0.5, 2)
        qvel[3:6] = rng.uniform(-2.0, 2.0, 3)
        return qpos, qvel

    def _task_reset(self, feet_mask: int) -> None:
        """Nothing beyond the shared start (no still stance held, zero metrics)."""


class _RobotContact(BeastEnv):
    """Mixin of the -v1 ids: the robot's contact model (:class:`polyenvs.beast.env.RobotContactParams`) as the
    defaults of the servo dead band and the foot-switch debounce."""

    params_class: type[SensorParams] = RobotContactParams


_TIME_COST = """    - ``time``: minus ``time_cost`` per second (0.2: 6 over the 30 s limit, less than ``success_reward``, so
      any success outscores every failure and a sooner one a later one);
"""


class _PaysSuccessAndTime(BeastEnv):
    """v1's reward for a task whose score is a success and its time: v0's success bonus and control cost, its shaping
    term replaced by ``time``, minus ``time_cost`` per second."""

    reward_names = ("success", "time", "ctrl")
    reward_kind = KR.SUCCESS_AND_TIME

    def __init__(self, *, time_cost: float = 0.2, **kwargs):
        self.time_cost = check_in_range("time_cost", time_cost, 0.0, 10.0)
        super().__init__(**kwargs)


class BeastTumbleV1Env(_PaysSuccessAndTime, _RobotContact, BeastTumbleEnv):
    __doc__ = _doc(
        _TUMBLE[0],
        """    - ``success``: ``success_reward`` on the step the tumble completes;
"""
        + _TIME_COST
        + """    - ``ctrl``: minus ``ctrl_cost_weight`` x mean squared joint torque / limit^2.
""",
        *_TUMBLE[2:4],
        _TUMBLE[4] + "    | time_cost | 0.2 | reward lost per second until the tumble completes, [0, 10] |\n",
        score=_TUMBLE_SCORE,
        v1="""      The reward is the score's: v0's ``progress`` (body velocity) paid for shuffling forward without tumbling
      (a PPO agent: 0.55 normalised return, 1 success in 100 episodes), v1 pays the success and charges time.
""",
    )


class BeastRollV1Env(_RobotContact, BeastRollEnv):
    __doc__ = _doc(
        *_ROLL,
        score=_ROLL_SCORE,
        v1="""      The reward is v0's, which already tracks the score: ``forward`` sums to the distance along the heading
      divided by the 10 ms tick (locomotion of any kind that goes along the heading is what the score measures).
""",
    )


class BeastTurnV1Env(_RobotContact, BeastTurnEnv):
    __doc__ = _doc(
        _TURN[0],
        """    - ``heading``: ``heading_reward`` x (the heading error's decrease) / 180 degrees, paid when a tumble
      changes it (it starts at 180), so an episode's terms sum to ``heading_reward`` x (1 - final error / 180);
    - ``ctrl``: minus ``ctrl_cost_weight`` x mean squared joint torque / limit^2.
""",
        *_TURN[2:4],
        _TURN[4] + "    | heading_reward | 10 | reward for a final heading error of 0, [0, 1000] |\n",
        score=_TURN_SCORE,
        v1="""      The reward is the score's: v0's ``forward`` (velocity along the target direction) paid rolling straight
      on at cos(60 degrees) of the turn's rate; v1 pays the decrease of the heading error.
""",
    )
    reward_names = ("heading", "ctrl")
    reward_kind = KR.HEADING_GAIN

    def __init__(self, heading_reward: float = 10.0, **kwargs):
        self.heading_reward = check_in_range("heading_reward", heading_reward, 0.0, 1000.0)
        super().__init__(**kwargs)


class BeastRecoverV1Env(_PaysSuccessAndTime, _RobotContact, BeastRecoverEnv):
    __doc__ = _doc(
        _RECOVER[0],
        """    - ``success``: ``success_reward`` on the step the stance is reached;
"""
        + _TIME_COST.replace("30 s", "20 s").replace("6 over", "4 over")
        + """    - ``ctrl``: minus ``ctrl_cost_weight`` x mean squared joint torque / limit^2.
""",
        *_RECOVER[2:4],
        _RECOVER[4] + "    | time_cost | 0.2 | reward lost per second until the stance is reached, [0, 10] |\n",
        score=_RECOVER_SCORE,
        travels=False,
        v1="""      The reward is the score's: v0's ``support`` paid 0.03 a step for standing on three feet without
      keeping still (60 over the 20 s limit against a success bonus of 10); v1 pays the success and charges time.
""",
    )


def _turned(qpos: np.ndarray, yaw: float) -> np.ndarray:
    """A free-body qpos turned by ``yaw`` about the vertical through the body centre."""
    out = qpos.copy()
    half = yaw / 2
    turn = np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
    mujoco.mju_mulQuat(out[3:7], turn, qpos[3:7].copy())
    out[:2] = K.rot_z(yaw)[:2, :2] @ qpos[:2]
    return out
