"""Hand baselines for the Platonic beasts: the paper's rolling gait, its sharp turn, a righting routine and the crawl.

Paper: Pai, Barman and Ralph, "Platonic Beasts: spherically symmetric multilimbed robots" (``../shared/seeds/002_*.txt``).
The environments are :mod:`polyenvs.beast`; these policies read only its observations and import its kinematics.

| module | what |
| --- | --- |
| ``policies`` | ``RollingGait``, ``SharpTurn``, ``Righting``, ``Crawl``: the SB3-style policies the registry names |
| ``gait`` | the rolling gait (section 4): tumble planner and the closed-loop rolling and righting controllers |
| ``crawl`` | the quadruped crawl of a 6-beast with a broken limb, and the reorientation onto it (section 5) |
"""

from baselines.beast.policies import Crawl, Righting, RollingGait, SharpTurn

__all__ = ["Crawl", "RollingGait", "SharpTurn", "Righting"]
