"""Hand baselines for the bumper cart: the paper's random bounce, and the upper anchors of the tasks on which random
and the paper's policy coincide.

"Drive in a straight(ish) line until it hits something, record how far it went, back up, turn in a random
direction, and drive off again" (Dye, Part 2). The environment does the driving and the backing up; the policy
chooses the turn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from baselines.base import Policy
from polyenvs.bumper.cart import CartModel
from polyenvs.bumper.env import OBSERVATION_STRUCTURE, LocalizationContext
from polyenvs.bumper.maps import make_map
from polyenvs.bumper.odometry import TICK_CM
from polyenvs.core.jit import njit
from polyenvs.core.parameters import parameter
from polyenvs.core.validation import check_in_range, check_int
from polyenvs.estimators.bumper import BumpSpaceMCL

__all__ = ["FixedTurn", "GreedySplit", "RandomBounce"]


@dataclass(frozen=True)
class RandomBounceTunables:
    """What ``polyenvs tune`` searches for the random bounce: the band its turns are drawn from (a draw with
    ``min_turn_deg`` above ``max_turn_deg`` is refused, as the constructor refuses it)."""

    min_turn_deg: float = parameter(0.0, 0.0, 180.0, "deg", "paper: a random direction")
    max_turn_deg: float = parameter(180.0, 0.0, 180.0, "deg", "paper: a random direction")


@dataclass(frozen=True)
class FixedTurnTunables:
    """What ``polyenvs tune`` searches for the fixed turn."""

    turn_deg: float = parameter(150.0, -180.0, 180.0, "deg", "ours: chosen over 90-170 on seeds 0-49")


@dataclass(frozen=True)
class GreedySplitTunables:
    """What ``polyenvs tune`` searches for the greedy split: the resolutions of its look-ahead."""

    bin_cm: float = parameter(5.0, 0.5, 50.0, "cm", "ours")
    hypothesis_cm: float = parameter(20.0, 5.0, 100.0, "cm", "ours")


class RandomBounce(Policy):
    """The paper's random bounce: after every cycle, turn by an angle uniform in ``±[min_turn_deg, max_turn_deg]``.

    Args:
        min_turn_deg: smallest turn, in [0, 180] (default 0: any direction).
        max_turn_deg: largest turn, in [min_turn_deg, 180] (default 180: uniform over the circle).
        seed: seeds the policy's own generator (default 0, so evaluations repeat; ``None``: fresh entropy).
    """

    tunables = RandomBounceTunables

    def __init__(self, observation_space, action_space, min_turn_deg: float = RandomBounceTunables.min_turn_deg,
                 max_turn_deg: float = RandomBounceTunables.max_turn_deg, seed: int | None = 0):  # fmt: skip
        super().__init__(observation_space, action_space)
        self.min_turn_deg = check_in_range("min_turn_deg", min_turn_deg, 0.0, 180.0)
        self.max_turn_deg = check_in_range("max_turn_deg", max_turn_deg, self.min_turn_deg, 180.0)
        self.seed(seed)

    def seed(self, seed: int | None) -> None:
        """Restart the policy's generator (the localization runner gives each logged run its own seed)."""
        self.rng = np.random.default_rng(seed)

    def describe(self) -> dict:
        return {"name": "random_bounce", "min_turn_deg": self.min_turn_deg, "max_turn_deg": self.max_turn_deg}

    def act(self, observation, memory):
        magnitude = self.rng.uniform(self.min_turn_deg, self.max_turn_deg) / 180.0
        sign = 1.0 if self.rng.random() < 0.5 else -1.0
        return np.array([sign * magnitude], dtype=np.float32)


class FixedTurn(Policy):
    """BumperCartExplore-v1's and -v2's upper anchor: after every cycle, turn by the same ``turn_deg`` (counter-clockwise).

    Deliberate where the paper's bounce is random: turned 150°, the cart backs off the wall it just hit and leaves
    it 30° off its way in, so that successive bumps walk round the room instead of falling anywhere; the turn was
    chosen over 90-170° (fixed, or alternating in sign, which bounces between two walls) on seeds 0-49 of
    BumperCartExplore-v1 and checked on seeds 100-149 and 200-249 (the numbers are in that environment's
    docstring). Memoryless and deterministic.

    Args:
        turn_deg: the turn, in [-180, 180] (default 150).
    """

    tunables = FixedTurnTunables

    def __init__(self, observation_space, action_space, turn_deg: float = FixedTurnTunables.turn_deg):
        super().__init__(observation_space, action_space)
        self.turn_deg = check_in_range("turn_deg", turn_deg, -180.0, 180.0)
        self._action = np.array([self.turn_deg / 180.0], dtype=np.float32)

    def describe(self) -> dict:
        return {"name": "fixed_turn", "turn_deg": self.turn_deg}

    def act(self, observation, memory):
        return self._action.copy()


@njit(cache=True)
def _travel_to_bump(x, y, h, walls, front, half, max_cm):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """How far the cart at ``(x, y, h)`` drives straight before its bumper (``front`` cm ahead of the axle,
    ``half`` cm either side) touches a wall: the nearest hit of the rays from the bumper's ends and middle and of
    the wall vertices that the bumper's sweep meets; ``max_cm`` if none."""
    c, s = math.cos(h), math.sin(h)
    best = max_cm
    for k in range(walls.shape[0]):
        if walls[k, 5] == 0.0:
            continue
        qx, qy, ex, ey = walls[k, 0], walls[k, 1], walls[k, 2], walls[k, 3]
        denom = c * ey - s * ex
        for j in range(3):
            lateral = (j - 1) * half
            px, py = x + front * c - lateral * s, y + front * s + lateral * c
            if denom != 0.0:
                t = ((qx - px) * ey - (qy - py) * ex) / denom
                u = ((qx - px) * s - (qy - py) * c) / denom
                if 0.0 <= t < best and 0.0 <= u <= 1.0:
                    best = t
        along = (qx - x) * c + (qy - y) * s - front
        if 0.0 <= along < best and abs((qy - y) * c - (qx - x) * s) <= half:
            best = along
    return best


@njit(cache=True)
def _entropy(counts, total) -> float:
    """The entropy (nats) of the histogram ``counts`` holding ``total``."""
    entropy = 0.0
    for j in range(counts.shape[0]):
        if counts[j] > 0.0:
            p = counts[j] / total
            entropy -= p * math.log(p)
    return entropy


@njit(cache=True)
def _split_informations(particles, groups, turns, walls, geometry, out):
    """For each candidate turn, the information (nats) the predicted drive length, binned in ``bin_cm``, carries
    about which hypothesis holds: its entropy over all particles less its mean entropy within each hypothesis
    (``groups``: the particles' hypothesis cells, sorted: equal cells are contiguous, ``particles`` in the same
    order). The spread within a cell is the filter's own motion noise, not a split worth a bump. ``geometry =
    (front, half, max_cm, bin_cm)``."""
    front, half, max_cm, bin_cm = geometry
    bins = int(max_cm / bin_cm) + 2
    total, within = np.zeros(bins), np.zeros(bins)
    lengths = np.empty(particles.shape[0], dtype=np.int64)
    n = particles.shape[0]
    for k in range(turns.shape[0]):
        total[:] = 0.0
        for i in range(n):
            d = _travel_to_bump(particles[i, 0], particles[i, 1], particles[i, 2] + turns[k], walls, front, half,
                                max_cm)  # fmt: skip
            lengths[i] = min(int(d / bin_cm), bins - 1)
            total[lengths[i]] += 1.0
        conditional, start = 0.0, 0
        for i in range(1, n + 1):
            if i < n and groups[i] == groups[start]:
                continue
            within[:] = 0.0
            for j in range(start, i):
                within[lengths[j]] += 1.0
            conditional += (i - start) / n * _entropy(within, i - start)
            start = i
        out[k] = _entropy(total, n) - conditional


class GreedySplit(Policy):
    """Active localization's upper anchor: keep the paper's bump-space localizer on the logs, and turn where the next
    bump tells its hypotheses apart best.

    The policy runs its own :class:`polyenvs.estimators.bumper.BumpSpaceMCL` on the cycle logs it observes (the
    particles travel in the policy's state, a row per environment, cleared at an episode start; its motion noise
    comes from the policy's own seeded generator), knowing the map as the task's cart does: the belief summary in
    the observation cannot predict a bump, the particles can. Before each cycle it predicts, for each of
    ``candidates`` evenly spaced turns, the drive length every particle would log (straight to the bumper's first
    wall contact, binned at ``bin_cm``) and picks the turn whose length carries the most information about which
    hypothesis holds: the entropy of the predicted length over all particles less its mean entropy within each
    hypothesis (the particles of one ``hypothesis_cm`` x 45° cell), a one-step information-gain look-ahead. The
    within-cell term matters: the filter's own motion noise spreads the lengths of one hypothesis too (most on
    long, glancing drives), and counting that spread as a split sent an earlier, plain-entropy version bouncing
    between the same two walls. Ties (a belief in one cell gains nothing anywhere) are drawn at random among the
    best: the random bounce when no turn splits.

    Args:
        map: the map the cart knows (a name or polygons, as the environment's ``map``).
        particles: the policy's own localizer's size, in [100, 20000].
        candidates: turns considered, evenly spaced over the circle, in [2, 72].
        bin_cm: the drive-length resolution of the split, in [0.5, 50] cm (the localizer's forward noise is
            0.6 cm + 6% of the distance).
        hypothesis_cm: the size of a hypothesis cell, in [1, 200] cm.
        seed: seeds the policy's generator (default 0; ``None``: fresh entropy).
    """

    tunables = GreedySplitTunables

    def __init__(self, observation_space, action_space, *, map="paper", particles: int = 1000, candidates: int = 12,
                 bin_cm: float = GreedySplitTunables.bin_cm, hypothesis_cm: float = GreedySplitTunables.hypothesis_cm,
                 seed: int | None = 0):  # fmt: skip
        super().__init__(observation_space, action_space)
        self.n = check_int("particles", particles, 100, 20_000)
        self.candidates = check_int("candidates", candidates, 2, 72)
        self.bin_cm = check_in_range("bin_cm", bin_cm, 0.5, 50.0)
        self.hypothesis_cm = check_in_range("hypothesis_cm", hypothesis_cm, 1.0, 200.0)
        model = CartModel()
        context = LocalizationContext(make_map(map), TICK_CM, model.wheel_base_cm, model.bumper_offset_cm,
                                      model.bumper_width_cm, dict(OBSERVATION_STRUCTURE))  # fmt: skip
        self.map = context.world.name
        self.memory_size = 1 + 3 * self.n
        self.localizer = BumpSpaceMCL(self.n)
        self.seed(seed)
        self.localizer.reset(context, None, self.rng)
        # Turns as fractions of 180 degrees, (-1, 1]: the action; in radians for the prediction.
        self.turns = -1.0 + 2.0 * np.arange(1, self.candidates + 1) / self.candidates
        self._geometry = (model.bumper_offset_cm, model.bumper_width_cm / 2, model.max_drive_cm, self.bin_cm)
        self._gains = np.zeros(self.candidates)

    def seed(self, seed: int | None) -> None:
        """Restart the policy's generator (the localizer's motion noise and its seeding)."""
        self.rng = np.random.default_rng(seed)
        self.localizer.rng = self.rng

    def describe(self) -> dict:
        return {"name": "greedy_split", "map": self.map, "particles": self.n, "candidates": self.candidates,
                "bin_cm": self.bin_cm, "hypothesis_cm": self.hypothesis_cm}  # fmt: skip

    def act(self, observation, memory):
        particles = memory[1:].reshape(self.n, 3)  # a view: the updated belief goes back into the state
        if memory[0] == 0.0:  # the episode's first observation (the reset's): no log yet, a uniform belief
            particles[:] = self.localizer.seed_particles(self.rng)
            memory[0] = 1.0
        else:
            self.localizer.particles = particles.copy()
            self.localizer.update(observation)
            particles[:] = self.localizer.particles
        gains = self.split_informations(particles)
        best = np.flatnonzero(gains >= gains.max() - 1e-9)
        # A belief in one cell (gains all 0) or a tie: draw among the best (the random bounce when nothing splits).
        choice = best[0] if len(best) == 1 else self.rng.choice(best)
        return np.array([self.turns[choice]], dtype=np.float32)

    def split_informations(self, particles: np.ndarray) -> np.ndarray:
        """Each candidate turn's information about the hypotheses in ``particles`` (``(n, 3)``), in nats."""
        x0, y0 = self.localizer.context.world.bounds[:2]
        cells = np.floor((particles[:, :2] - (x0, y0)) / self.hypothesis_cm).astype(np.int64)
        headings = np.floor((particles[:, 2] + np.pi) / (np.pi / 4)).astype(np.int64) % 8
        groups = (cells[:, 0] * 4096 + cells[:, 1]) * 8 + headings
        order = np.argsort(groups, kind="stable")
        _split_informations(particles[order], groups[order], math.pi * self.turns, self.localizer.walls,
                            self._geometry, self._gains)  # fmt: skip
        return self._gains.copy()
