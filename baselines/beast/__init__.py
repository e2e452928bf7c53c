"""Hand baselines for the Platonic beasts: the paper's rolling gait, its sharp turn, a righting routine and the crawl.

Paper: Pai, Barman and Ralph, "Platonic Beasts: spherically symmetric multilimbed robots"
(``../shared/seeds/002_*.txt``). The environments are :mod:`polyenvs.beast`; these policies read only their
observations and import the family's kinematics, model parameters and sensor layout (nothing there imports them).

| module | what |
| --- | --- |
| ``policies`` | ``RollingGait``, ``SharpTurn``, ``Righting``, ``Crawl``: SB3-style ``predict`` policies |
| ``gait`` | the rolling gait (section 4): the closed-loop rolling and righting controllers |
| ``planner`` | the gait's planner: tumble geometry, joint-1 look-ahead bookkeeping, joint trajectories |
| ``zero_tip`` | the zero-tip tumble (section 3): the landing foot down before the tip, never fewer than three feet |
| ``crawl`` | the quadruped crawl of a 6-beast with a broken limb, and the reorientation onto it (section 5) |
| ``geometry`` | rotation vectors and the Kabsch fit the planners share |
| ``observation`` | an observation's sensor parts by name; the beast and its joint limits from the spaces |
"""

from baselines.beast.policies import Crawl, Righting, RollingGait, SharpTurn

__all__ = ["Crawl", "RollingGait", "SharpTurn", "Righting"]
