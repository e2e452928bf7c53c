"""The hand baselines of every environment, in one table keyed by its id (a Gymnasium id or a PettingZoo module path).

Each row lists the environment's hand baselines (:class:`Baseline`: a name, a ``"module:attribute"`` factory and
fixed keyword arguments) and which of them is the paper's main algorithm, reachable as policy ``"paper"``
(:mod:`baselines.factory` builds them by name). A baseline acts on one agent's observation; for a parallel
environment the evaluation applies it to each robot's own observation (parameter sharing).

The environments themselves are the rows of :data:`polyenvs.registry.REGISTRY`; every id there has its row here and
no other (``tests/test_baselines.py`` checks both, and that every factory imports). A new task's baselines go here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from polyenvs.registry import bare_id

__all__ = ["BASELINES", "Baseline", "HandBaselines", "hand_baselines"]


@dataclass(frozen=True)
class Baseline:
    """A hand baseline: ``factory(observation_space, action_space, **kwargs)`` builds a ``baselines.base.Policy``."""

    name: str
    factory: str  # "module:attribute"
    kwargs: dict = field(default_factory=dict)


@dataclass(frozen=True)
class HandBaselines:
    """One environment's hand baselines and the name of the one that is the paper's main algorithm (policy
    ``"paper"``); ``paper`` is ``None`` only for an environment without a row (a user's own)."""

    baselines: tuple[Baseline, ...] = ()
    paper: str | None = None

    @property
    def names(self) -> list[str]:
        return [b.name for b in self.baselines]


def _buckybot(name: str, cls: str, **kwargs) -> Baseline:
    return Baseline(name, f"baselines.buckybot:{cls}", kwargs)


def _beast(name: str, cls: str, **kwargs) -> Baseline:
    return Baseline(name, f"baselines.beast:{cls}", kwargs)


def _swarm(name: str, cls: str, **kwargs) -> Baseline:
    return Baseline(name, f"baselines.swarm:{cls}", kwargs)


def _bumper(name: str, cls: str, **kwargs) -> Baseline:
    return Baseline(name, f"baselines.bumper:{cls}", kwargs)


_WALL_FOLLOW = HandBaselines(
    (
        _buckybot("wall_follower", "WallFollower"),
        _buckybot("wall_follower_rules", "WallFollower", x_s_cm=30.0, no_backtrack=True, clockwise_exception=True),
    ),
    paper="wall_follower",
)
_TUMBLE = HandBaselines((_beast("rolling_gait", "RollingGait", max_tumbles=1),), paper="rolling_gait")
_ROLL = HandBaselines((_beast("rolling_gait", "RollingGait"),), paper="rolling_gait")
_TURN = HandBaselines(
    (_beast("sharp_turn", "SharpTurn"), _beast("sharp_turn_cone", "SharpTurn", pivot="inside")),
    paper="sharp_turn_cone",
)
_RECOVER = HandBaselines((_beast("righting", "Righting"),), paper="righting")
#: The cart's budgeted exploration (BumperCartExplore-v1 on): the paper's random bounce and the fixed turn, which
#: anchors the score since random and the paper's random bounce coincide on the cart.
_CART_BUDGET = HandBaselines(
    (_bumper("random_bounce", "RandomBounce"), _bumper("fixed_turn", "FixedTurn", turn_deg=150.0)),
    paper="random_bounce",
)
# A policy cannot tell the platform from the observation space: the corridor's X80Pro reads the inverted 0..80
# IR scale, and the paper's AP-lite reads only its two outer sensors there (the platform's controller_sensors).
_X80PRO = {"platform": "x80pro"}
_CORRIDOR = HandBaselines(
    (_swarm("aplite", "APLite", **_X80PRO), _swarm("aplite_goal_seeking", "APLiteGoalSeeking", **_X80PRO)),
    paper="aplite",
)
_FIELD = HandBaselines((_swarm("aplite", "APLite"), _swarm("aplite_goal_seeking", "APLiteGoalSeeking")), paper="aplite")

#: Environment id -> its hand baselines, in the registry's order.
BASELINES: dict[str, HandBaselines] = {
    "polyenvs/BuckybotWallFollow-v0": _WALL_FOLLOW,
    "polyenvs/BuckybotExplore-v0": HandBaselines(
        (_buckybot("wall_follow_explorer", "WallFollowExplorer"),), paper="wall_follow_explorer"
    ),
    "polyenvs/BuckybotGoal-v0": HandBaselines((_buckybot("goal_seeker", "GoalSeeker"),), paper="goal_seeker"),
    "polyenvs/BeastTumble-v0": _TUMBLE,
    "polyenvs/BeastRoll-v0": _ROLL,
    "polyenvs/BeastTurn-v0": _TURN,
    "polyenvs/BeastRecover-v0": _RECOVER,
    "polyenvs/BeastTumble-v1": _TUMBLE,
    "polyenvs/BeastRoll-v1": _ROLL,
    "polyenvs/BeastTurn-v1": _TURN,
    "polyenvs/BeastRecover-v1": _RECOVER,
    "polyenvs/BumperCartExplore-v0": HandBaselines((_bumper("random_bounce", "RandomBounce"),), paper="random_bounce"),
    "polyenvs/BumperCartExplore-v1": _CART_BUDGET,
    "polyenvs/BumperCartExplore-v2": _CART_BUDGET,
    "polyenvs/BumperCartLocalize-v0": HandBaselines(
        (_bumper("random_bounce", "RandomBounce"), _bumper("greedy_split", "GreedySplit")), paper="random_bounce"
    ),
    "polyenvs/APLiteCorridor-v0": _CORRIDOR,
    "polyenvs/APLiteObstacleField-v0": _FIELD,
    "polyenvs.swarm.corridor_v0": _CORRIDOR,
    "polyenvs.swarm.obstacle_field_v0": _FIELD,
    "polyenvs.swarm.formation_v0": HandBaselines(
        (_swarm("formation", "FormationController"), _swarm("aplite_goal_seeking", "APLiteGoalSeeking")),
        paper="formation",
    ),
}


def hand_baselines(env_id: str) -> HandBaselines:
    """The row of ``env_id`` (a Gymnasium id, ``polyenvs:`` prefix allowed, or a module path); an empty one, with
    no paper, for an environment that has none (a user's own)."""
    return BASELINES.get(bare_id(env_id), HandBaselines())
