"""polyenvs: reinforcement-learning environments for unconventional, minimally-sensed robots.

``import polyenvs`` registers every environment under the ``polyenvs/`` namespace::

    import gymnasium as gym
    import polyenvs  # noqa: F401

    env = gym.make("polyenvs/BuckybotWallFollow-v0")
"""

from polyenvs.registry import ENV_IDS, register_all

__all__ = ["ENV_IDS", "__version__"]
__version__ = "0.1.0"

register_all()
