"""Upper limits of the numbers a user gives (command-line flags, training configs, environment keywords).

One table for every layer: evaluation checks ``max_episode_steps``, training configs ``n_envs`` and ``timesteps``,
the command line each flag.
"""

__all__ = [
    "MAX_BC_EPOCHS",
    "MAX_BUMPS",
    "MAX_EPISODES",
    "MAX_EPISODE_STEPS",
    "MAX_FRAMES",
    "MAX_JOBS",
    "MAX_N_ENVS",
    "MAX_PARTICLES",
    "MAX_RUNS",
    "MAX_SEED",
    "MAX_STEPS",
    "MAX_TIMESTEPS",
    "MAX_TRIALS",
]

#: Upper limits of the command line's numbers: far above any real use, low enough that a slip of the keyboard
#: (``--episodes 99999999999``) is refused at once instead of running for ever or filling the memory.
MAX_SEED = 2**32 - 1  # numpy's legacy seeding, which Stable-Baselines3 uses, takes no more
MAX_EPISODES = 100_000
MAX_TIMESTEPS = 10**10
MAX_N_ENVS = 1024
MAX_JOBS = 1024
MAX_STEPS = 100_000  # steps of one recorded episode (the longest registered episode is 8000 steps)
MAX_FRAMES = 3_000  # frames a recording holds in memory (up to 2 MB each)
MAX_RUNS = 10_000
MAX_BUMPS = 1_000
MAX_PARTICLES = 1_000_000
MAX_BC_EPOCHS = 100_000  # passes over a demonstration dataset (``polyenvs train --bc-epochs``)
MAX_EPISODE_STEPS = 1_000_000  # an ``--env-kwargs`` max_episode_steps (what gym.make's TimeLimit takes)
MAX_TRIALS = 100_000  # trials of one study (``polyenvs tune --trials``)
