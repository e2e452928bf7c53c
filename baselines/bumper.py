"""Hand baseline for the bumper cart: the paper's random bounce.

"Drive in a straight(ish) line until it hits something, record how far it went, back up, turn in a random
direction, and drive off again" (Dye, Part 2). The environment does the driving and the backing up; the policy
chooses the turn.
"""

from __future__ import annotations

import numpy as np

from baselines.base import Policy
from polyenvs.core.validation import check_in_range

__all__ = ["RandomBounce"]


class RandomBounce(Policy):
    """The paper's random bounce: after every cycle, turn by an angle uniform in ``±[min_turn_deg, max_turn_deg]``.

    Args:
        min_turn_deg: smallest turn, in [0, 180] (default 0: any direction).
        max_turn_deg: largest turn, in [min_turn_deg, 180] (default 180: uniform over the circle).
        seed: seeds the policy's own generator (default 0, so evaluations repeat; ``None``: fresh entropy).
    """

    def __init__(self, observation_space, action_space, min_turn_deg: float = 0.0, max_turn_deg: float = 180.0,
                 seed: int | None = 0):  # fmt: skip
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
