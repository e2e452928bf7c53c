"""``polyenvs/BumperCartExplore-v2``: BumperCartExplore-v1 with each bump credited to the wall its bumper touched
(v0 and v1 credited the back-up's contact when backing up touched a wall after the bump)."""

from __future__ import annotations

from polyenvs.bumper.cart import CartModel
from polyenvs.bumper.explore_v1 import BumperCartExploreV1Env
from polyenvs.bumper.maps import LAYOUT_SPLIT
from polyenvs.core.layouts import documents_layouts
from polyenvs.core.parameters import documents_arguments

__all__ = ["BumperCartExploreV2Env"]


@documents_arguments(CartModel)
@documents_layouts(LAYOUT_SPLIT)
class BumperCartExploreV2Env(BumperCartExploreV1Env):
    """Touch as much wall as possible within a budget of cycles, scored against the most that budget allows; a bump
    credits the wall the bumper touched.

    ## Description
    BumperCartExplore-v1 (its cart, cycle, map, wall cells, budget of 50 cycles and coverage bound) with the bump
    defined as the paper's robot senses it: the drive stage ends with the bumper's switch closed, and the bump's
    contact is where the bumper met the wall. Backing up after it can touch another wall with the cart's rear (a
    stall, unsensed); v0 and v1 credited that wall, one the bumper never touched, in 0.1-0.35% of bumps (issue
    29). Over seeds 0-199 the fix changed the rewards of 7 episodes in 200 with random turns, 8 with the paper's
    random bounce and 12 with ``fixed_turn``, and no score by more than 0.001: over seeds 0-49 (IQM and 95%
    stratified-bootstrap interval of ``coverage``) random 0.677 [0.660, 0.691], the random bounce 0.676 [0.663,
    0.690], ``fixed_turn`` 0.727 [0.711, 0.742]; on seeds 100-149 and 200-249 random 0.675 [0.657, 0.691] and
    0.688 [0.671, 0.705], ``fixed_turn`` 0.718 [0.695, 0.736] and 0.722 [0.701, 0.741].

    ## Action Space
    As BumperCartExplore-v0: ``Box(-1, 1, (1,), float32)``, the turn as a fraction of 180°.

    ## Observation Space
    As BumperCartExplore-v0: ``Box((7,), float32)``, the cycle's log (ticks of turn, drive and back-up, the bump
    bit). The fix changes no observation: the log never held the contact.

    ## Rewards
    As BumperCartExplore-v1: ``reward_touch``, 100 x the wall fraction newly touched by this cycle's bump (the cell
    of the bumper's contact point), over the bound; an episode's rewards sum to 100 x ``coverage``.

    ## Task score
    As BumperCartExplore-v1: ``coverage`` (max, ceiling 1), the paper's random bounce against ``fixed_turn``.

    ## Starting State
    As BumperCartExplore-v0 (reset option ``pose``).

    ## Episode End
    As BumperCartExplore-v1: never terminates; truncated after ``budget_cycles`` cycles (50), whatever time limit
    ``gym.make`` was given. The metrics (``env.unwrapped.episode_metrics()``; ``info["episode_metrics"]`` of the
    budget's last cycle): ``coverage``, ``wall_fraction_touched``, ``bumps``,
    ``odometry_error_cm``, ``large_slips``; ``info["contact_point"]`` is the last bump's contact on the bumper.

    ## Arguments
    | argument | default | meaning |
    |----------|---------|---------|
    | budget_cycles | 50 | the episode's cycles, which the coverage bound is for, in [1, 100000] |
    | map | "paper" | as BumperCartExplore-v0 |
    {layouts}
    | cell_cm | 5.0 | as BumperCartExplore-v0 |
    {arguments}
    | render_mode | None | "rgb_array" or "human" |
    | window_scale | 1.0 | with render_mode="human", the window shows each frame zoomed by this factor, in [0.25, 8]; rgb_array frames are unchanged |
    | num_rows | 1 | rows simulated at once, an integer in [1, 1e6]: the native vector env sets it (``gym.make_vec``) |

    ## Version History
    * v2 (2026-12-05, issue 29): a bump credits the bumper's own contact, not a later one of the back-up: the touch
      reward, ``coverage``, ``wall_fraction_touched``, ``touched_cells`` and ``contact_point`` change where backing up
      touched a wall after the bump; the cart's motion and observations are v1's. ``info`` made lean without changing an
      episode (2026-12-05): ``info["episode_metrics"]`` is only in the info of the step that ends the episode
      (terminated, or truncated by the env itself; on a native vector env's rows that end, time limit included),
      ``env.unwrapped.episode_metrics()`` returns them at any time, and
      :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics` adds them where Gymnasium's ``TimeLimit`` truncates.
    * v1: a budget of 50 cycles and ``coverage`` against its upper bound (the reward scaled by the bound).
    * v0: 200 cycles, the reward 100 x the wall fraction touched.
    """

    credits_latest_contact = False
