"""The beasts' hand baselines as policies: the paper's rolling gait, its sharp turn, a righting routine, the crawl.

They read only the sensor part of the observation (encoder angles, tilt switches, foot contacts; a privileged tail,
when the environment has one, is ignored) and run the controllers of :mod:`baselines.beast.gait` and
:mod:`baselines.beast.crawl`, which plan with :mod:`baselines.beast.planner`. Each keeps its plan (the current
joint trajectory and the tumble it is in) in a controller per environment, held in the policy object; the memory
row that ``predict`` carries is that controller's handle, so batches and episode restarts work as for every policy.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from baselines.base import Policy
from baselines.beast.crawl import CrawlConfig, CrawlController, ReorientController
from baselines.beast.gait import RightingController, RollingGaitController
from baselines.beast.observation import joint_ranges_of, n_limbs_of, polyhedron_of, split_observation
from baselines.beast.planner import DEFAULT_CONFIGS, BeastPlanner
from baselines.beast.zero_tip import ZeroTipController
from polyenvs.beast.model import stance_orientation
from polyenvs.beast.sensors import TILT_AXES, observation_layout_of
from polyenvs.core.parameters import parameter
from polyenvs.core.validation import check_bool, check_in_range, check_int

__all__ = ["Crawl", "RollingGait", "SharpTurn", "Righting"]


#: The paper's power budget (12 W with all limbs moving) implies joints at about 15 deg/s; the gaits run at 20.
_RATE_SOURCE = "ours: the feasibility study's (the paper's 12 W implies about 15)"


@dataclasses.dataclass(frozen=True)
class RollingGaitTunables:
    """What ``polyenvs tune`` searches for the rolling gait: the joint rate and the tip keyframe, as offsets from
    the polyhedron's (:data:`baselines.beast.planner.DEFAULT_CONFIGS`): the body's tilt about the tipping edge at the
    keyframe (the first angle of its rotation) and the landing foot's pre-placed roll."""

    rate_deg_s: float = parameter(20.0, 5.0, 45.0, "deg/s", _RATE_SOURCE)
    # Past about 3 degrees either way the keyframe leaves a limb's workspace and no tumble is planned (the gait
    # holds its stance: measured on BeastRoll-v1, seed 1000: -5, +5 and -3 with a roll of -3 degrees, 0 tumbles).
    tip_offset_deg: float = parameter(0.0, -3.0, 3.0, "deg", "ours: the feasibility study's keyframe")
    roll_offset_deg: float = parameter(0.0, -8.0, 8.0, "deg", "ours: the feasibility study's keyframe")


@dataclasses.dataclass(frozen=True)
class SharpTurnTunables:
    """What ``polyenvs tune`` searches for the sharp turn."""

    rate_deg_s: float = parameter(20.0, 5.0, 45.0, "deg/s", _RATE_SOURCE)


@dataclasses.dataclass(frozen=True)
class RightingTunables:
    """What ``polyenvs tune`` searches for the righting routine."""

    rate_deg_s: float = parameter(30.0, 5.0, 60.0, "deg/s", "ours")


@dataclasses.dataclass(frozen=True)
class CrawlTunables:
    """What ``polyenvs tune`` searches for the crawl."""

    rate_deg_s: float = parameter(20.0, 5.0, 45.0, "deg/s", _RATE_SOURCE)
    stride: float = parameter(CrawlConfig.stride, 0.02, 0.2, "m", "ours")
    margin: float = parameter(CrawlConfig.margin, 0.0, 0.06, "m", "ours")


class _ControllerPolicy(Policy):
    """A controller object per environment, found through the handle in that environment's memory row; the planner
    runs at ``rate_deg_s`` with the polyhedron's tip keyframe turned by ``keyframe_offsets_deg`` (tilt, roll)."""

    memory_size = 1

    def __init__(self, observation_space, action_space, rate_deg_s: float = 20.0, keyframe_offsets_deg=(0.0, 0.0)):
        super().__init__(observation_space, action_space)
        self.rate_deg_s = check_in_range("rate_deg_s", rate_deg_s, 5.0, 90.0)
        n_limbs = n_limbs_of(int(np.prod(observation_space.shape)))
        if action_space.shape != (3 * n_limbs,):
            raise ValueError(f"action_space must have shape ({3 * n_limbs},), got {action_space.shape}")
        self.polyhedron = polyhedron_of(n_limbs)
        base = DEFAULT_CONFIGS[self.polyhedron]
        tilt, roll = keyframe_offsets_deg
        config = dataclasses.replace(
            base,
            rate_deg_s=self.rate_deg_s,
            tip_rotation_deg=(base.tip_rotation_deg[0] + tilt, *base.tip_rotation_deg[1:]),
            roll_deg=base.roll_deg + roll,
        )
        self.planner = BeastPlanner(self.polyhedron, joint_ranges=joint_ranges_of(observation_space), config=config)
        self._controllers: dict[int, object] = {}
        self._handles = itertools.count(1)

    def make_controller(self, observation: np.ndarray):
        """A controller for an episode that starts with this observation."""
        raise NotImplementedError

    def _require_tumbles(self) -> None:
        """The tumble planner knows three-foot supports; the 8-beast stands and rolls on squares of four feet."""
        if self.polyhedron == "cube":
            raise ValueError(
                f"observation_space is the 8-beast's (cube): {type(self).__name__} plans tumbles between triangles of "
                "three feet, and the 8-beast stands on squares of four (no tumble is planned for it); the 4- and "
                "6-beast roll"
            )

    def controller(self, memory: np.ndarray, observation: np.ndarray):
        """The controller of the environment whose memory row this is (a new one after a restart)."""
        handle = int(memory[0])
        if handle not in self._controllers:
            handle = next(self._handles)
            memory[0] = handle
            self._controllers[handle] = self.make_controller(observation)
        return self._controllers[handle]

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        if state is not None and episode_start is not None:
            # Controllers of episodes that end here are dropped, so a long evaluation does not pile them up.
            restart = np.broadcast_to(np.asarray(episode_start, dtype=bool), (np.shape(state)[0],))
            for handle in np.asarray(state, dtype=np.float64)[restart, 0]:
                self._controllers.pop(int(handle), None)
        return super().predict(observation, state, episode_start, deterministic)

    def act(self, observation, memory):
        return self.controller(memory, observation)(observation)


class RollingGait(_ControllerPolicy):
    """The paper's rolling gait (section 4), closed loop on the robot's own sensors, re-planned every tumble.

    Each tumble is planned from the feet measured by forward kinematics of the encoders (the contact switches say
    which are planted): tip keyframe, free limb over the top to its next foothold, dynamic tip, stance over the new
    support triangle (:mod:`baselines.beast.gait`). The 4-beast starts with the canonical tumble (1234) and rolls
    along the straight strip (1234)(4213)(4321)(1342), 30 degrees left of the first tip; the 6-beast picks the edge
    of its support face best aligned with the same heading.

    Args:
        rate_deg_s: the joint rate the trajectories are timed for, in [5, 90] deg/s (paper's power budget: ~15).
        tip_offset_deg, roll_offset_deg: the tip keyframe's tilt about the edge and the landing foot's pre-placed
            roll, added to the polyhedron's, in [-10, 10] and [-8, 8] deg (:class:`RollingGaitTunables` says how far a search goes).
        max_tumbles: stop (hold the stance) after this many tumbles, in [1, 1000]; None rolls on.
        disabled_limbs: 1-based limbs known to be broken (paper section 5): lifted first if standing, never landed.
        zero_tip: the paper's zero-tip tumbles instead (section 3, 4-beast only; :mod:`baselines.beast.zero_tip`):
            the landing foot set down before the centre of mass crosses the edge, never fewer than three feet down,
            about twice as slow. Only the strip's first tumble can be made so; then the policy holds its stance.
    """

    tunables = RollingGaitTunables

    def __init__(
        self,
        observation_space,
        action_space,
        rate_deg_s: float = RollingGaitTunables.rate_deg_s,
        max_tumbles: int | None = None,
        disabled_limbs=(),
        zero_tip: bool = False,
        *,
        tip_offset_deg: float = RollingGaitTunables.tip_offset_deg,
        roll_offset_deg: float = RollingGaitTunables.roll_offset_deg,
    ):
        offsets = (
            check_in_range("tip_offset_deg", tip_offset_deg, -10.0, 10.0),
            check_in_range("roll_offset_deg", roll_offset_deg, -8.0, 8.0),
        )
        super().__init__(observation_space, action_space, rate_deg_s, offsets)
        self.tip_offset_deg, self.roll_offset_deg = offsets
        self._require_tumbles()
        self.zero_tip = check_bool("zero_tip", zero_tip)
        if self.zero_tip and self.planner.n_limbs != 4:
            raise ValueError(f"zero_tip is the 4-beast's tumble (paper section 3), got a {self.polyhedron}")
        self.max_tumbles = None if max_tumbles is None else check_int("max_tumbles", max_tumbles, 1, 1000)
        if isinstance(disabled_limbs, (str, bytes)) or not hasattr(disabled_limbs, "__iter__"):
            raise ValueError(f"disabled_limbs must be a sequence of limb numbers, got {disabled_limbs!r}")
        n = self.planner.n_limbs
        self.disabled_limbs = tuple(sorted({check_int("disabled_limbs", v, 1, n) for v in disabled_limbs}))

    def describe(self):
        return {
            "name": "rolling_gait",
            "rate_deg_s": self.rate_deg_s,
            "max_tumbles": self.max_tumbles,
            "disabled_limbs": list(self.disabled_limbs),
            "zero_tip": self.zero_tip,
            **self._keyframe_offsets(),
        }

    def _keyframe_offsets(self) -> dict:
        """The keyframe's offsets where they are not the polyhedron's (descriptions made before them stay as they were)."""
        offsets = {"tip_offset_deg": self.tip_offset_deg, "roll_offset_deg": self.roll_offset_deg}
        return offsets if any(offsets.values()) else {}

    def make_controller(self, observation):
        controller = ZeroTipController if self.zero_tip else RollingGaitController
        return controller(self.planner, max_tumbles=self.max_tumbles, disabled_limbs=self.disabled_limbs)


class SharpTurn(_ControllerPolicy):
    """The sharp turn (paper section 5, Figures 10 and 11): roll off in the direction the task commands.

    The turn comes from the observation's ``command`` part (``BeastTurn-v0``: cos and sin of ``turn_deg``), so the
    policy follows whatever turn the environment was made with. The paper keeps limb 1 planted while the robot rolls
    about it. On a straight strip every limb is planted through two tumbles in a row; a turn keeps one planted
    through a third, which rolls the strip by 60 degrees about that foot and winds its joint 1 by a further 120
    degrees (hence ``BeastTurn-v0``'s joint-1 range of +-250 degrees for the 4-beast). By default the controller is
    our look-ahead steering (registered as ``sharp_turn``): the rolling gait's look-ahead for the turned heading,
    allowed to tip back over the last edge; ``pivot`` (1-based limb) instead restricts every tumble to edges
    containing that limb, the literal cone, and stops when none is plannable. ``pivot="inside"`` is the paper's turn
    as written (registered as ``sharp_turn_cone``, the ``BeastTurn`` ids' paper policy): the 4-beast
    keeps planted the edge limb of its first tumble (1234) on the inside of the turn, limb 1 for a right turn as
    the paper has it and its mirror image, limb 2, for a left one. Within joint 1's +-250 degrees the cone about
    limb 1 lasts two tumbles (its joint 1 winds 0 -> 240 degrees) and turns by about -53 degrees; about limb 2
    three (120 -> -240) and about +50.

    Args:
        pivot: None, the limb kept planted (1..n_limbs), or "inside" (4-beast only).
        rate_deg_s, max_tumbles: as for :class:`RollingGait` (max_tumbles default 4).
    """

    tunables = SharpTurnTunables

    def __init__(
        self,
        observation_space,
        action_space,
        pivot: int | str | None = None,
        rate_deg_s: float = SharpTurnTunables.rate_deg_s,
        max_tumbles: int = 4,
    ):
        super().__init__(observation_space, action_space, rate_deg_s)
        self._require_tumbles()
        self.command = observation_layout_of(int(np.prod(observation_space.shape))).get("command")
        if self.command is None:
            raise ValueError("SharpTurn needs an observation with a command part (the turn), as BeastTurn-v0's")
        if pivot == "inside" and self.planner.n_limbs != 4:
            raise ValueError(f'pivot "inside" is the 4-beast\'s turn (limb 1 or 2), got a {self.polyhedron}')
        self.pivot = pivot if pivot in (None, "inside") else check_int("pivot", pivot, 1, self.planner.n_limbs)
        self.max_tumbles = check_int("max_tumbles", max_tumbles, 1, 1000)

    def describe(self):
        return {"name": "sharp_turn", "pivot": self.pivot, "rate_deg_s": self.rate_deg_s}

    def make_controller(self, observation):
        cos_turn, sin_turn = np.asarray(observation, dtype=np.float64)[self.command]
        strip = math.radians(30.0 if self.planner.n_limbs == 4 else 0.0)
        angle = strip + math.atan2(sin_turn, cos_turn)
        heading = np.array([math.cos(angle), math.sin(angle), 0.0])
        # The first tumble (1234) tips along +x over edge 1-2 with limb 2 on the left: a left turn rolls about it.
        pivot = (2 if sin_turn > 0 else 1) if self.pivot == "inside" else self.pivot
        return RollingGaitController(
            self.planner, max_tumbles=self.max_tumbles, heading=heading, pivot=pivot, allow_back=True
        )


class Righting(_ControllerPolicy):
    """Righting after a topple (paper section 5): from the tilt switches, stand on the three limbs pointing down.

    The twelve tilt bits give gravity's direction in the body frame (the mean of the switch axes that read "below
    horizontal"); the three limbs whose axes point most nearly down swing in joint space to their nominal stance and
    the others fold up, and the routine repeats from the new reading until the contact switches report those three
    feet down; then, with ``roll_after``, it hands over to the rolling gait. ``rate_deg_s`` as for
    :class:`RollingGait`.
    """

    tunables = RightingTunables

    def __init__(
        self, observation_space, action_space, rate_deg_s: float = RightingTunables.rate_deg_s, roll_after: bool = False
    ):
        super().__init__(observation_space, action_space, rate_deg_s)
        self.roll_after = check_bool("roll_after", roll_after)

    def describe(self):
        return {"name": "righting", "rate_deg_s": self.rate_deg_s, "roll_after": self.roll_after}

    def make_controller(self, observation):
        return RightingController(self.planner, roll_after=self.roll_after)


class Crawl(_ControllerPolicy):
    """The quadruped crawl of a 6-beast with a broken limb on top (paper section 5), closed loop on its own sensors.

    The broken limb points up and its opposite is folded away under the body; the four limbs perpendicular to it
    walk a statically stable crawl (one leg at a time, lateral sequence left-hind, left-front, right-hind,
    right-front; before each lift the body shifts the centre of mass into the other three feet's triangle with a
    margin), each shift and swing planned from the encoder angles (feet by forward kinematics) and the contact
    switches (:mod:`baselines.beast.crawl`). From the crawl stance (:func:`baselines.beast.crawl.crawl_stance_qpos`;
    the tilt switches say the broken limb points up) it crawls at once, the heading fixed to the body. From the
    task's three-foot rolling stance with the broken limb free it first reorients
    (:class:`baselines.beast.crawl.ReorientController`: a partial roll of about 55 degrees that lands two upper limbs
    as legs and folds the broken limb's opposite, about 25 s), then crawls along the start stance's forward
    direction (the task's heading) turned by ``heading_deg``. A broken limb that stands in the start support cannot
    be reoriented (the controller holds; see the module's notes).

    Args:
        disabled_limbs: the one broken 1-based limb (a sequence of one limb number, 1..6), put on top.
        heading_deg: direction of travel, counter-clockwise about the broken limb from the crawl's forward (the
            bisector of the two lowest-numbered perpendicular legs; from the task's start: from the task's
            heading), in [-180, 180].
        rate_deg_s: the joint rate the trajectories are timed for, in [5, 90] deg/s.
        stride: foot advance per crawl cycle (m), in [0, 0.2].
        margin: least distance of the centre of mass from the support triangle's edges while a leg swings (m),
            in [0, 0.06].
        max_cycles: stop (hold) after this many crawl cycles of four steps, in [1, 1000]; None walks on.
    """

    tunables = CrawlTunables

    def __init__(
        self,
        observation_space,
        action_space,
        disabled_limbs=(1,),
        *,
        heading_deg: float = 0.0,
        rate_deg_s: float = CrawlTunables.rate_deg_s,
        stride: float = CrawlTunables.stride,
        margin: float = CrawlTunables.margin,
        max_cycles: int | None = None,
    ):
        super().__init__(observation_space, action_space, rate_deg_s)
        if self.planner.n_limbs != 6:
            raise ValueError(f"Crawl needs a 6-beast (octahedron) observation space, got a {self.polyhedron}")
        if isinstance(disabled_limbs, (str, bytes)) or not hasattr(disabled_limbs, "__iter__"):
            raise ValueError(f"disabled_limbs must be a sequence of one limb number, got {disabled_limbs!r}")
        limbs = tuple(sorted({check_int("disabled_limbs", v, 1, 6) for v in disabled_limbs}))
        if len(limbs) != 1:
            raise ValueError(f"disabled_limbs must name exactly one limb (the one put on top), got {disabled_limbs!r}")
        self.disabled_limbs = limbs
        self.heading_deg = check_in_range("heading_deg", heading_deg, -180.0, 180.0)
        self.stride = check_in_range("stride", stride, 0.0, 0.2)
        self.margin = check_in_range("margin", margin, 0.0, 0.06)
        self.max_cycles = None if max_cycles is None else check_int("max_cycles", max_cycles, 1, 1000)
        self.config = CrawlConfig(rate_deg_s=self.rate_deg_s, stride=self.stride, margin=self.margin)

    def describe(self):
        return {
            "name": "crawl",
            "disabled_limbs": list(self.disabled_limbs),
            "heading_deg": self.heading_deg,
            "rate_deg_s": self.rate_deg_s,
            "stride": self.stride,
            "margin": self.margin,
            "max_cycles": self.max_cycles,
        }

    def make_controller(self, observation):
        """The crawl itself when the tilt switches say the broken limb already points up (within 30 degrees);
        otherwise (the task's rolling start) the reorientation first, heading along the start's forward."""
        k = self.disabled_limbs[0] - 1
        tilt = split_observation(observation)["tilt"] > 0.5
        down = TILT_AXES[tilt].mean(axis=0) if tilt.any() else np.zeros(3)
        norm = float(np.linalg.norm(down))
        if norm > 0 and float(self.planner.dirs[k] @ -down) / norm > math.cos(math.radians(30.0)):
            return CrawlController(
                self.planner,
                k,
                config=self.config,
                heading_rad=math.radians(self.heading_deg),
                max_cycles=self.max_cycles,
            )
        return ReorientController(
            self.planner,
            k,
            stance_orientation(self.polyhedron)[0][0],
            config=self.config,
            heading_rad=math.radians(self.heading_deg),
            max_cycles=self.max_cycles,
        )
