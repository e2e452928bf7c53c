"""The Buckybot paper's dead-reckoning experiments from the command line: Figure 8's maps (the paper's explorer
driving BuckybotExplore-v0) and the 100-tip Monte Carlo (:mod:`polyenvs.buckybot.analysis` computes both)::

    python -m benchmarks.buckybot_analysis figure8 --seed 2 --output docs/buckybot_figure8.png
    python -m benchmarks.buckybot_analysis monte-carlo --runs 2000
"""

from __future__ import annotations

import argparse
import sys

import gymnasium as gym

from baselines import make_policy
from polyenvs.buckybot.analysis import (
    EXPLORE_ENV_ID,
    PAPER_MONTE_CARLO,
    dead_reckoning_monte_carlo,
    figure8_maps,
    figure8_summary,
    render_figure8,
    write_png,
)
from polyenvs.buckybot.simulator import BuckybotParams


def paper_explorer():
    """The paper's explorer, the policy Figure 8 was drawn with."""
    env = gym.make(EXPLORE_ENV_ID)
    try:
        return make_policy("paper", EXPLORE_ENV_ID, env.observation_space, env.action_space)
    finally:
        env.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.buckybot_analysis", description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    fig = commands.add_parser("figure8", help="the paper's Figure 8: true-pose and dead-reckoned maps side by side")
    fig.add_argument("--output", default="docs/buckybot_figure8.png", help="PNG to write")
    fig.add_argument("--seed", type=int, default=0)
    fig.add_argument("--floor-plan", default="office")
    fig.add_argument("--steps", type=int, default=1000, help="most tips to run")
    fig.add_argument("--cell-cm", type=float, default=10.0)
    mc = commands.add_parser("monte-carlo", help="the paper's 100-tip dead-reckoning Monte Carlo")
    mc.add_argument("--runs", type=int, default=2000)
    mc.add_argument("--tips", type=int, default=100)
    mc.add_argument("--heading-sd-deg", type=float, default=BuckybotParams.heading_sd_deg)
    args = parser.parse_args(argv)
    if args.command == "figure8":
        run = figure8_maps(
            paper_explorer(), seed=args.seed, floor_plan=args.floor_plan, max_steps=args.steps, cell_cm=args.cell_cm
        )
        write_png(args.output, render_figure8(run))
        print(f"wrote {args.output}")
        print(figure8_summary(run))
    else:
        result = dead_reckoning_monte_carlo(
            args.runs, args.tips, robot=BuckybotParams(heading_sd_deg=args.heading_sd_deg)
        )
        print(result)
        print(f"paper: position sd {PAPER_MONTE_CARLO[0]} cm, heading sd {PAPER_MONTE_CARLO[1]} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
