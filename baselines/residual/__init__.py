"""Residual policies: a hand baseline's action plus a learned correction (Silver et al. 2018; Johannink et al. 2019).

``action = clip(base + scale x residual, low, high)``, where ``base`` is the baseline's action for the same
observation and ``residual`` in ``[-1, 1]`` per dimension is what an agent learns. Two places compose it the same
way, through :class:`ResidualComposer`:

- while training, the Gymnasium wrapper :class:`~baselines.residual.wrappers.ResidualPolicy` runs the baseline
  inside the environment, so the agent's action is the residual;
- while evaluating, a trained residual agent (a training directory whose ``run.json`` has a ``residual`` entry,
  :mod:`baselines.trained`) runs the baseline inside the policy, so it acts on the environment as registered.

The combined action keeps the base action's dtype: with a zero residual it is the base action bit for bit
(``base + 0.0 == base``), so the untrained agent reproduces the baseline's episodes exactly; casting a float64 base
to float32 first would not. The baseline's memory (its ``state``, Stable-Baselines3's ``predict`` convention) is
the caller's to carry between steps and to restart with ``episode_start`` (:mod:`baselines.base`).

A residual may be *held*: with ``hold = k`` the agent decides every k control ticks and its correction stays for
those k ticks, while the baseline runs and is recombined on every tick (holding the baseline's own output would slow
a trajectory it times by its calls, the beasts' gait, and break the zero-correction match). The wrapper steps the
environment k times per agent step; a loaded agent, called every tick on the environment as registered, keeps the
held correction and a tick counter in its ``state`` (:meth:`ResidualComposer.act`) and asks its network only every
k ticks, so it acts exactly as it did in training.

By default the agent also observes the base action (appended to the observation, in the observation's dtype): the
correction a baseline needs depends on what it is about to do, which its memory hides from the observation alone
(the feasibility study's residuals learned with it, ``../shared/spec/learning.md``).
"""

from baselines.residual.compose import MAX_HOLD, MAX_SCALE, ResidualComposer, ResidualSpec, make_composer
from baselines.residual.wrappers import ParallelResidualPolicy, ResidualPolicy

__all__ = [
    "MAX_HOLD",
    "MAX_SCALE",
    "ParallelResidualPolicy",
    "ResidualComposer",
    "ResidualPolicy",
    "ResidualSpec",
    "make_composer",
]
