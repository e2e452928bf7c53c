"""The installed wheel, outside the checkout: every id makes, resets and steps, and the command line works.

Run by .ci/run from an empty directory with the fresh virtual environment's interpreter; it fails if polyenvs is
imported from anywhere but that environment's site-packages.
"""

import subprocess
import sys
from pathlib import Path

import gymnasium as gym

import polyenvs
from polyenvs.registry import ENV_IDS, PARALLEL_ENV_IDS, REGISTRY

#: One id per family for `polyenvs evaluate` (each a short episode of the paper's policy).
EVALUATE = {
    "buckybot": ["polyenvs/BuckybotGoal-v0", "--env-kwargs", '{"max_episode_steps": 20}'],
    "beast": ["polyenvs/BeastRecover-v1", "--env-kwargs", '{"max_episode_steps": 50}'],
    "bumper": ["polyenvs/BumperCartExplore-v0", "--env-kwargs", '{"max_episode_steps": 10}'],
    "swarm": ["polyenvs.swarm.corridor_v0", "--env-kwargs", '{"max_cycles": 20}'],
}


def main() -> int:
    here = Path(polyenvs.__file__).resolve()
    if "site-packages" not in here.parts:
        raise SystemExit(f"polyenvs imported from {here}, not from the installed wheel")
    for env_id in ENV_IDS:
        env = gym.make(env_id)
        env.reset(seed=0)
        env.step(env.action_space.sample())
        env.close()
    for module in PARALLEL_ENV_IDS:
        env = __import__(module, fromlist=["parallel_env"]).parallel_env()
        env.reset(seed=0)
        env.step({agent: env.action_space(agent).sample() for agent in env.agents})
        env.close()
    print(f"made, reset and stepped {len(ENV_IDS)} ids and {len(PARALLEL_ENV_IDS)} swarm modules")
    command = [sys.executable, "-m", "polyenvs.cli"]
    version = subprocess.run([*command, "--version"], capture_output=True, text=True, check=True).stdout.strip()
    if version != f"polyenvs {polyenvs.__version__}":
        raise SystemExit(f"polyenvs --version printed {version!r}")
    families = {row.family for row in REGISTRY}
    if families != set(EVALUATE):
        raise SystemExit(f"families without a smoke evaluation: {sorted(families - set(EVALUATE))}")
    for arguments in EVALUATE.values():
        subprocess.run([*command, "evaluate", arguments[0], "--policy", "paper", "--episodes", "1", *arguments[1:]],
                       check=True)  # fmt: skip
    print(version, "- the wheel's smoke test passed")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
