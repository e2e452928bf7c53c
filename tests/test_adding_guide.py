"""The adding guide (docs/guides/adding.md), followed as a newcomer would, in every family: its toy task is written
as one task file in the family's package (here a module of that name loaded from a temporary folder), given its
registry row and its baselines row under a temporary id, and handed to the registry-wide contract suites, which run
on it unchanged (``GymnasiumRowChecks`` of tests/test_envs_shared.py, ``ParallelRowChecks`` of
tests/test_parallel_shared.py); its paper policy is evaluated through the commands' own path. Where the guide's
steps stop being enough (a step dropped from the guide, a base that starts needing something the guide does not
say), a toy task here fails.

Each toy writes only what the guide asks for, so that nothing else can carry it: a task file of the family's
declarations and hooks, a registry row (``EnvEntry`` or ``ParallelEnvEntry``) and a row of ``baselines.table``.
The episodes are short (the rows' limits are small), so each family's suite runs in seconds once its kernels are
compiled; the beast's is skipped without MuJoCo.
"""

from __future__ import annotations

import importlib.util
import sys
import textwrap

import gymnasium as gym
import pytest

import polyenvs.registry as registry
import tests.test_envs_shared as gymnasium_suite
import tests.test_parallel_shared as parallel_suite
from baselines.table import BASELINES, Baseline, HandBaselines
from polyenvs.core.rows import RowsEnv
from polyenvs.evaluation.episodes import evaluate
from polyenvs.registry import EnvEntry, ParallelEnvEntry, Score, import_attribute

# --------------------------------------------------------------------------------------------- the toy tasks

#: Buckybot (step 1's model is polyenvs/buckybot/goal.py): walk away from the start.
BUCKYBOT_TASK = '''
"""Toy: tip as far from the start as possible."""

import math

import numpy as np

from polyenvs.buckybot import simulator as S
from polyenvs.buckybot.env import BuckybotEnv, reset_task, step_task
from polyenvs.buckybot.floor_plans import LAYOUT_SPLIT
from polyenvs.buckybot.geometry import STEP_LENGTH_CM
from polyenvs.core.jit import njit
from polyenvs.core.layouts import documents_layouts

REWARD_TERMS = ("away",)
METRICS = ("distance_cm",)
OUT = BuckybotEnv.task_columns(REWARD_TERMS, METRICS)
(_R_AWAY,) = OUT.term_columns("away")
(_M_DISTANCE,) = OUT.metric_columns("distance_cm")
OBSERVATION_PARTS = {"away": 1}
(_AWAY,) = range(*BuckybotEnv.observation_parts(OBSERVATION_PARTS)["away"])
_START_X, _START_Y, _DISTANCE = range(3)


@njit(cache=True)
def _score_row(b, sim, task_arrays, out):
    state, (task,) = sim[S.A_STATE], task_arrays
    d = math.hypot(state[b, S.X] - task[b, _START_X], state[b, S.Y] - task[b, _START_Y])
    out[b, _R_AWAY] = (d - task[b, _DISTANCE]) / STEP_LENGTH_CM
    out[b, _M_DISTANCE] = task[b, _DISTANCE] = d
    sim[S.A_OBS][b, _AWAY] = math.tanh(d / 100.0)
    return False


@njit(cache=True)
def _start_row(b, sim, task_arrays, out):
    state, (task,) = sim[S.A_STATE], task_arrays
    task[b, _START_X], task[b, _START_Y], task[b, _DISTANCE] = state[b, S.X], state[b, S.Y], 0.0
    return _score_row(b, sim, task_arrays, out)


@njit(cache=True)
def _reset_kernel(rows, kernel):
    reset_task(rows, kernel, _start_row, REWARD_TERMS)


@njit(cache=True)
def _step_kernel(actions, kernel):
    step_task(actions, kernel, _score_row, REWARD_TERMS)


@documents_layouts(LAYOUT_SPLIT)
class ToyWanderEnv(BuckybotEnv):
    """Tip as far from the start as possible.

    ## Description
    A toy task of the adding guide.

    ## Action Space
    As BuckybotWallFollow-v0.

    ## Observation Space
    The sensors, then ``away``: tanh(distance from the start / 100 cm).

    ## Rewards
    ``reward_away``: the distance gained, in steps.

    ## Starting State
    As BuckybotWallFollow-v0.

    ## Episode End
    Truncated by the time limit.

    ## Arguments
    {layouts}

    ## Version History
    {version_history}
    """

    out_columns = OUT
    task_observation_sizes = OBSERVATION_PARTS
    task_observation_low = (0.0,)
    task_observation_high = (1.0,)

    def _task_init(self):
        self._task_state = np.zeros((self._batch_size, 3))

    def _task_arrays(self):
        return (self._task_state,)

    _step_kernel = staticmethod(_step_kernel)
    _reset_kernel = staticmethod(_reset_kernel)
'''

#: The beasts (step 1's model is polyenvs/beast/tasks.py): keep the body still (the guide's own check, stand.py).
BEAST_TASK = '''
"""Toy: stand still."""

from polyenvs.beast.env import BeastEnv
from polyenvs.beast.layouts import LAYOUT_SPLIT
from polyenvs.core.layouts import documents_layouts


@documents_layouts(LAYOUT_SPLIT)
class ToyStandEnv(BeastEnv):
    """Stand still.

    ## Description
    A toy task of the adding guide.

    ## Action Space
    As BeastRoll-v0.

    ## Observation Space
    As BeastRoll-v0.

    ## Rewards
    ``reward_still``: minus the squared body spin / 100.

    ## Starting State
    As BeastRoll-v0.

    ## Episode End
    Truncated by the time limit.

    ## Arguments
    As BeastRoll-v0, and:

    {layouts}

    ## Version History
    - v0: a toy.
    """

    reward_names = ("still",)
    metric_names = ("spin_sq",)

    def _task_reset(self, feet_mask):
        self._metrics = {"spin_sq": 0.0}

    def _task_step(self, summary):
        self._metrics["spin_sq"] = summary.spin_sq
        return (-0.01 * summary.spin_sq,), False
'''

#: The swarms (step 1's model is polyenvs/swarm/formation_v0.py): drive across an empty box to the light.
SWARM_TASK = '''
"""Toy: cross an empty box to the light."""

import numpy as np

from polyenvs.core.layouts import LayoutSplit, SplitParameter, documents_layouts
from polyenvs.swarm.env import Episode, Layout, SwarmEnv, module_constructors
from polyenvs.swarm.layouts import box_walls

N_ROBOTS = 2
MAX_CYCLES = 40
LAYOUT_SPLIT = LayoutSplit(
    (SplitParameter("light x", "m", train=(0.4, 0.9), test=(1.1, 1.6)),), varies="the light along the far wall"
)


@documents_layouts(LAYOUT_SPLIT)
class ToyBoxEnv(SwarmEnv):
    """Cross an empty box to the light.

    ## Description
    A toy task of the adding guide.

    ## Action Space
    As corridor_v0.

    ## Observation Space
    As corridor_v0.

    ## Rewards
    As corridor_v0.

    ## Arguments
    {layouts}
    """

    metadata = {**SwarmEnv.metadata, "name": "toy_box_v0"}

    def __init__(self, *, n_robots=N_ROBOTS, max_cycles=MAX_CYCLES, **kwargs):
        super().__init__(n_robots=n_robots, max_cycles=max_cycles, **kwargs)

    def _fixed_layout(self):
        return Layout(walls=box_walls(0.0, 0.0, 2.0, 3.0), bounds=(0.0, 0.0, 2.0, 3.0))

    def _episode(self, rng, light_x):
        x = 0.5 + np.arange(self.n_robots) * 0.8 / max(self.n_robots - 1, 1) + 0.05 * rng.random(self.n_robots)
        starts = np.column_stack([x, np.full(self.n_robots, 0.4), np.full(self.n_robots, np.pi / 2)])
        return Episode(circles=np.zeros((0, 3)), starts=starts, goal=np.array([light_x, 2.7]))

    def sample_episode(self, rng):
        return self._episode(rng, 1.0)

    def sample_layout_episode(self, rng, layouts):
        return self._episode(rng, float(LAYOUT_SPLIT.parameters[0].draw(rng, layouts, 1)[0]))


parallel_env, raw_env, env = module_constructors(ToyBoxEnv)
'''

#: The cart (step 1's model is polyenvs/bumper/localize.py): bump as often as possible.
CART_TASK = '''
"""Toy: bump as often as possible."""

from polyenvs.bumper.env import A_OBS, OBSERVATION_STRUCTURE, BumperCartEnv, step_task
from polyenvs.bumper.maps import LAYOUT_SPLIT
from polyenvs.core.columns import OutColumns
from polyenvs.core.jit import njit
from polyenvs.core.layouts import documents_layouts

REWARD_TERMS = ("bump",)
METRICS = ("bumps",)  # the base counts the bumps and writes them, as it does wherever a task names "bumps"
OUT = OutColumns(REWARD_TERMS, METRICS)
(_R_BUMP,) = OUT.term_columns("bump")
_BUMP_OBS = OBSERVATION_STRUCTURE["bump"][0]


@njit(cache=True)
def _score_row(b, sim, task, out):
    out[b, _R_BUMP] = sim[A_OBS][b, _BUMP_OBS]
    return False


@njit(cache=True)
def _step_kernel(actions, kernel):
    step_task(actions, kernel, _score_row, REWARD_TERMS)


@documents_layouts(LAYOUT_SPLIT)
class ToyBumpEnv(BumperCartEnv):
    """Bump as often as possible.

    ## Description
    A toy task of the adding guide.

    ## Action Space
    As BumperCartExplore-v0.

    ## Observation Space
    As BumperCartExplore-v0.

    ## Rewards
    ``reward_bump``: 1 a bump.

    ## Starting State
    As BumperCartExplore-v0.

    ## Episode End
    Truncated by the time limit.

    ## Arguments
    {layouts}

    ## Version History
    - v0: a toy.
    """

    out_columns = OUT
    _step_kernel = staticmethod(_step_kernel)
'''

#: Each family's toy: (the task file's module, its source, its registry row, its baselines row).
TOYS = {
    "buckybot": (
        "polyenvs.buckybot.toy_wander",
        BUCKYBOT_TASK,
        EnvEntry(
            id="polyenvs/ToyWander-v0",
            entry_point="polyenvs.buckybot.toy_wander:ToyWanderEnv",
            native_vector=True,
            max_episode_steps=40,
            description="Toy: Buckybot tips as far from its start as it can",
            score=Score("distance_cm", "max"),
        ),
        HandBaselines((Baseline("wall_follower", "baselines.buckybot:WallFollower"),), paper="wall_follower"),
    ),
    "beast": (
        "polyenvs.beast.toy_stand",
        BEAST_TASK,
        EnvEntry(
            id="polyenvs/ToyStand-v0",
            entry_point="polyenvs.beast.toy_stand:ToyStandEnv",
            max_episode_steps=30,
            extra="mujoco",
            description="Toy: a beast keeps its body still",
            score=Score("spin_sq", "min", ceiling=0.0),
        ),
        HandBaselines(
            (Baseline("rolling_gait", "baselines.beast:RollingGait", {"max_tumbles": 1}),), paper="rolling_gait"
        ),
    ),
    "swarm": (
        "polyenvs.swarm.toy_box_v0",
        SWARM_TASK,
        ParallelEnvEntry(
            id="polyenvs.swarm.toy_box_v0",
            description="Toy: robots cross an empty box to the light",
            score=Score("success_rate", "max", ceiling=1.0, aggregate="mean"),
        ),
        HandBaselines((Baseline("aplite", "baselines.swarm:APLite"),), paper="aplite"),
    ),
    "bumper": (
        "polyenvs.bumper.toy_bump",
        CART_TASK,
        EnvEntry(
            id="polyenvs/ToyBump-v0",
            entry_point="polyenvs.bumper.toy_bump:ToyBumpEnv",
            native_vector=True,
            max_episode_steps=20,
            description="Toy: the bump cart bumps as often as it can",
            score=Score("bumps", "max"),
        ),
        HandBaselines((Baseline("random_bounce", "baselines.bumper:RandomBounce"),), paper="random_bounce"),
    ),
}


def _write_task_file(module: str, source: str, folder) -> None:
    """The task file: ``source`` written to ``folder`` and imported as ``module``, a module of the family's package
    (what the guide's entry point names), as if the file lay there."""
    path = folder / f"{module.rpartition('.')[2]}.py"
    path.write_text(textwrap.dedent(source).lstrip())
    spec = importlib.util.spec_from_file_location(module, path)
    task = importlib.util.module_from_spec(spec)
    sys.modules[module] = task
    spec.loader.exec_module(task)


@pytest.fixture(scope="module")
def toy_rows(tmp_path_factory):
    """Every family's toy added as the guide says (task file, registry row, baselines row), and taken out after."""
    added = []
    with pytest.MonkeyPatch.context() as patch:
        for family, (module, source, row, baselines) in TOYS.items():
            if family == "beast" and importlib.util.find_spec("mujoco") is None:
                continue
            _write_task_file(module, source, tmp_path_factory.mktemp(family))
            patch.setattr(registry, "REGISTRY", (*registry.REGISTRY, row))
            patch.setitem(BASELINES, row.id, baselines)
            added.append((module, row))
        registry.register_all()  # as importing polyenvs registers the table's Gymnasium rows
        yield {row.family: row for _, row in added}
    for module, row in added:
        gym.registry.pop(row.id, None)
        sys.modules.pop(module, None)


def _toy(toy_rows, family: str):
    if family not in toy_rows:
        pytest.skip(f"the {family} toy needs an optional package (its row's extra) that is not installed")
    return toy_rows[family]


class _ToyGymnasiumRow(gymnasium_suite.GymnasiumRowChecks):
    """The Gymnasium suite's checks on the toy row of ``family``."""

    family = ""
    #: The toy's task file is imported only in this process (it lies in a temporary folder, not in the package), so
    #: the async vector env's workers must be forked from it: a spawned worker could not import the entry point.
    async_context = "fork"

    @pytest.fixture
    def entry(self, toy_rows) -> EnvEntry:
        return _toy(toy_rows, self.family)

    @pytest.fixture
    def env_id(self, entry) -> str:
        return entry.id

    @pytest.fixture
    def vector_id(self, entry) -> str:
        if not entry.vector_entry_point:
            pytest.skip("the family has no native vector env")
        return entry.id

    @pytest.fixture
    def rows_id(self, entry) -> str:
        if not issubclass(import_attribute(entry.entry_point), RowsEnv):
            pytest.skip("the family's base is not a RowsEnv")
        return entry.id


class TestToyBuckybot(_ToyGymnasiumRow):
    family = "buckybot"


class TestToyBeast(_ToyGymnasiumRow):
    family = "beast"


class TestToyCart(_ToyGymnasiumRow):
    family = "bumper"


class TestToySwarm(parallel_suite.ParallelRowChecks):
    """The parallel suite's checks on the toy swarm's row."""

    @pytest.fixture
    def entry(self, toy_rows) -> ParallelEnvEntry:
        return _toy(toy_rows, "swarm")


@pytest.mark.parametrize("family", list(TOYS))
def test_the_toys_paper_policy_runs_through_evaluate(toy_rows, family):
    """Steps 2 and 4 as the commands use them: ``polyenvs evaluate`` resolves the toy's row and builds its paper
    policy from its baselines row, and the episode reports the task's metrics."""
    row = _toy(toy_rows, family)
    doc = evaluate(row.id, "paper", episodes=1, seed=0)
    assert row.score.metric in doc["summary"]
