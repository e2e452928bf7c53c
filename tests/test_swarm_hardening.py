"""The swarm's rules for bad input and for what a user gets by default (issue 14): an internal cap ends a
single-robot episode as a truncation; step and render before a first reset raise ``ResetNeeded``; an AEC action is
checked when it is given; derived defaults fit their ranges over every accepted input; actions must be real numbers;
unknown reset options raise; the modules' defaults are what the commands evaluate; TorchRL's PettingZooWrapper
steps every swarm module. A refused call changes nothing: the same episode follows as if it had not been made."""

from __future__ import annotations

import importlib
import inspect

import gymnasium as gym
import numpy as np
import pytest

from polyenvs.evaluation.rollout import make_env
from polyenvs.registry import REGISTRY
from polyenvs.swarm import corridor_v0, formation_v0, obstacle_field_v0, single
from polyenvs.swarm.batched import SwarmVectorEnv

MODULES = [corridor_v0, obstacle_field_v0, formation_v0]
IDS = [m.__name__.rsplit(".", 1)[1] for m in MODULES]
SINGLE_IDS = [e.id for e in REGISTRY if e.kind == "gymnasium" and e.family == "swarm"]
SWARM_ROWS = [e for e in REGISTRY if e.kind == "pettingzoo" and e.family == "swarm"]
WRONG_DTYPES = [
    np.full(2, 0.2 + 5j),
    [0.2 + 5j, 0.1],
    np.zeros(2, dtype=bool),
    [True, False],
    np.zeros(2).astype(str),
    np.array([0.1, 0.2], dtype=object),
]
BAD_OPTIONS = [{"bogus": 1}, [1], "x", 3, {0: 1}, {"options": 1, "bogus": 2}]


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, tuple | list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return np.array_equal(a, b)


def _actions(env, step: int) -> dict:
    rng = np.random.default_rng(step)
    return {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents}


def _aec_cycle(env, twin, steps: int) -> None:
    """``steps`` AEC steps of the same actions on ``env`` and ``twin``; both must see the same thing throughout."""
    for k in range(steps):
        assert env.agent_selection == twin.agent_selection
        assert _same(env.last(), twin.last())
        agent = env.agent_selection
        if env.terminations[agent] or env.truncations[agent]:
            env.step(None)
            twin.step(None)
            continue
        action = np.random.default_rng(k).uniform(-1, 1, 2).astype(np.float32)
        env.step(action)
        twin.step(action)


# --- 2: the swarm's own cap inside a single-robot id ---------------------------------------------------------------
def test_single_robot_swarm_cap_ends_the_episode_as_a_truncation(monkeypatch):
    """The swarm inside a single-robot id caps its episode at 1e6 steps (``max_cycles`` must be a number). Reaching
    it is a truncation, then ResetNeeded; it was ``truncated=False``, then ``KeyError: 'robot_0'``. The cap made
    small here (it is read at construction) so as not to run 1e6 steps."""
    monkeypatch.setattr(single, "_NO_LIMIT", 5)
    for cls in (single.APLiteCorridorEnv, single.APLiteObstacleFieldEnv):
        env = cls()
        env.reset(seed=0)
        still = np.zeros(2, np.float32)  # standing still: no arrival
        for _ in range(4):
            assert env.step(still)[2:4] == (False, False)
        _, _, terminated, truncated, info = env.step(still)
        assert (terminated, truncated) == (False, True) and "episode_metrics" in info
        with pytest.raises(gym.error.ResetNeeded, match=r"truncated: call reset\(\)"):
            env.step(still)
        env.reset(seed=0)
        assert env.step(still)[2:4] == (False, False)
    # Under a time limit above the cap (as the registry's would be, were it above 1e6), the cap truncates first.
    limited = gym.make(SINGLE_IDS[0], max_episode_steps=50)
    limited.reset(seed=0)
    truncated = [limited.step(np.zeros(2, np.float32))[3] for _ in range(5)]
    assert truncated == [False] * 4 + [True]


# --- 4: step and render before the first reset -------------------------------------------------------------------
@pytest.mark.parametrize("env_id", SINGLE_IDS)
def test_single_robot_step_and_render_before_reset_raise_reset_needed(env_id):
    env = gym.make(env_id, render_mode="rgb_array").unwrapped
    with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before step\(\)"):
        env.step(np.zeros(2, np.float32))
    with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before render\(\)"):
        env.render()
    env.reset(seed=0)
    assert env.render().ndim == 3
    env.swarm.pose[0, :2] = env.swarm.goal  # at the light: the next step arrives
    assert env.step(np.zeros(2, np.float32))[2] is True
    with pytest.raises(gym.error.ResetNeeded, match=r"the robot has arrived: call reset\(\)"):
        env.step(np.zeros(2, np.float32))


@pytest.mark.parametrize("module", MODULES, ids=IDS)
def test_pettingzoo_step_and_render_before_reset_raise_reset_needed(module):
    """The parallel env stepped ``{}`` before a reset (it returned empty dicts) or rendered (it drew an empty
    frame); the AEC forms raised PettingZoo's AssertionError or AttributeError."""
    parallel = module.parallel_env(render_mode="rgb_array")
    with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before step\(\)"):
        parallel.step({})
    with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before step\(\)"):
        parallel.step({"robot_0": np.zeros(2, np.float32)})
    with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before render\(\)"):
        parallel.render()
    for aec in (module.env(render_mode="rgb_array"), module.raw_env(render_mode="rgb_array")):
        with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before step\(\)"):
            aec.step(np.zeros(2, np.float32))
        with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before render\(\)"):
            aec.render()
        aec.reset(seed=0)
        assert aec.render().ndim == 3
        aec.step(np.zeros(2, np.float32))


# --- 5: an AEC action is checked when it is given -----------------------------------------------------------------
@pytest.mark.parametrize("make", ["env", "raw_env"])
def test_aec_bad_action_is_refused_when_given_and_changes_nothing(make):
    """robot_0's NaN or "x" was stored, robot_6's turn then raised, and so did every later step until a reset."""
    env, twin = getattr(formation_v0, make)(), getattr(formation_v0, make)()
    env.reset(seed=0)
    twin.reset(seed=0)
    for bad in (np.full(2, np.nan), "x", None, np.zeros(3), np.full(2, 2.0), *WRONG_DTYPES):
        with pytest.raises(ValueError, match="robot_0"):
            env.step(bad)
        assert env.agent_selection == "robot_0"
    _aec_cycle(env, twin, 3 * len(env.possible_agents))
    # A bad action in the middle of a cycle too: the agents before it keep theirs.
    _aec_cycle(env, twin, 3)
    with pytest.raises(ValueError, match=env.agent_selection):
        env.step(np.full(2, 0.2 + 5j))
    _aec_cycle(env, twin, 2 * len(env.possible_agents))


# --- 6: derived defaults fit their ranges for every accepted input ------------------------------------------------
def test_formation_builds_over_its_whole_spacing_range_with_default_everything_else():
    """``goal_radius_m`` (2 R) was refused from R = 1.5 m up (``goal_radius_m must be in [0.1, 3], got 4.0``, a
    parameter the user did not pass), and ``comm_range_m`` (3 m) from R = 2 m up (the springs reach 1.5 R)."""
    for spacing_m in (0.5, 1.5, 1.75, 2.0, 3.0):  # the ends, the middle, and where each default used to break
        env = formation_v0.parallel_env(spacing_m=spacing_m)
        assert env.goal_radius_m == min(2 * spacing_m, 3.0)
        assert env.comm_range_m == max(3.0, 1.5 * spacing_m)
        env.reset(seed=0)
        for step in range(3):
            env.step(_actions(env, step))
        batch = SwarmVectorEnv("formation_v0", num_envs=2, spacing_m=spacing_m)
        batch.reset(seed=0)
        batch.step(np.zeros((batch.num_envs, 2)))
        for n_robots in (1, 1024):  # the lattice, hence the field, grows with both
            formation_v0.parallel_env(spacing_m=spacing_m, n_robots=n_robots).reset(seed=0)


def test_formation_given_values_are_still_checked_and_the_issue_example_builds():
    env = formation_v0.parallel_env(spacing_m=2.0, comm_range_m=3.0)
    assert env.goal_radius_m == 3.0 and env.comm_range_m == 3.0
    with pytest.raises(ValueError, match="goal_radius_m"):
        formation_v0.parallel_env(spacing_m=2.0, goal_radius_m=4.0)
    with pytest.raises(ValueError, match="comm_range_m"):
        formation_v0.parallel_env(spacing_m=3.0, comm_range_m=3.0)
    with pytest.raises(ValueError, match="spacing_m"):
        formation_v0.parallel_env(spacing_m=3.5)


# --- 7: actions must be real numbers ------------------------------------------------------------------------------
@pytest.mark.parametrize("module", MODULES, ids=IDS)
def test_wrong_dtype_actions_raise_and_change_nothing_in_the_parallel_env(module):
    """Complex actions lost their imaginary part (0.2+5j drove as 0.2), bools drove as 0/1, strings were parsed."""
    env, twin = module.parallel_env(n_robots=3), module.parallel_env(n_robots=3)
    env.reset(seed=0)
    twin.reset(seed=0)
    good = _actions(env, 0)
    for bad in WRONG_DTYPES:
        with pytest.raises(ValueError, match="robot_1.*real numbers"):
            env.step({**good, "robot_1": bad})
        with pytest.raises(ValueError, match="real numbers"):
            env.step({a: bad for a in env.agents})
    for step in range(5):
        actions = _actions(env, step)
        assert _same(env.step(actions), twin.step(actions))


def test_actions_of_wrong_shapes_or_mixed_dtypes_are_checked_one_by_one_in_the_parallel_env():
    """The step stacks a dict of arrays at once: (1, 2) actions, and a (3,) and a (1,) action (as many numbers as
    two (2,) ones), are refused naming the first, and mixed real dtypes drive as their float32 values, as one dtype
    does."""
    env, twin = obstacle_field_v0.parallel_env(n_robots=3), obstacle_field_v0.parallel_env(n_robots=3)
    env.reset(seed=0)
    twin.reset(seed=0)
    good = _actions(env, 0)
    with pytest.raises(ValueError, match="robot_0"):
        env.step({agent: action[None] for agent, action in good.items()})
    with pytest.raises(ValueError, match="robot_1"):
        env.step({**good, "robot_1": np.full(3, 0.1, np.float32), "robot_2": np.full(1, 0.1, np.float32)})
    mixed = {**good, "robot_0": good["robot_0"].astype(np.float64), "robot_2": np.array([1, -1])}
    same = {**good, "robot_2": np.array([1.0, -1.0], np.float32)}
    assert _same(env.step(mixed), twin.step(same))


@pytest.mark.parametrize("env_id", SINGLE_IDS)
def test_wrong_dtype_actions_raise_and_change_nothing_in_the_single_robot_ids(env_id):
    env, twin = gym.make(env_id), gym.make(env_id)
    env.reset(seed=0)
    twin.reset(seed=0)
    for bad in WRONG_DTYPES:
        with pytest.raises(ValueError, match="real numbers"):
            env.step(bad)
    for step in range(5):
        action = np.random.default_rng(step).uniform(-1, 1, 2).astype(np.float32)
        assert _same(env.step(action), twin.step(action))


def test_wrong_dtype_actions_raise_and_change_nothing_in_the_vector_env():
    batch, twin = SwarmVectorEnv("formation_v0", num_envs=2), SwarmVectorEnv("formation_v0", num_envs=2)
    with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before step\(\)"):
        batch.step(np.zeros((batch.num_envs, 2)))
    batch.reset(seed=0)
    twin.reset(seed=0)
    good = np.random.default_rng(0).uniform(-1, 1, (batch.num_envs, 2))
    for bad in (good + 5j, good.astype(bool), good.astype(str), good.astype(object), (good + 0j).tolist()):
        with pytest.raises(ValueError, match="actions must be real numbers"):
            batch.step(bad)
    for step in range(5):
        actions = np.random.default_rng(step).uniform(-1, 1, (batch.num_envs, 2))
        assert _same(batch.step(actions)[:4], twin.step(actions)[:4])


# --- 8: reset options ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("module", MODULES, ids=IDS)
def test_unknown_and_malformed_options_raise_and_change_nothing_in_the_pettingzoo_envs(module):
    env, twin = module.parallel_env(), module.parallel_env()
    env.reset(seed=0)
    twin.reset(seed=0)
    for options in BAD_OPTIONS:
        with pytest.raises(ValueError, match="option"):
            env.reset(seed=1, options=options)
        with pytest.raises(ValueError, match="option"):
            env.reset(options=options)
    for step in range(3):
        actions = _actions(env, step)
        assert _same(env.step(actions), twin.step(actions))
    assert _same(env.reset(), twin.reset())  # the generator went on as if the calls had not been made
    assert _same(env.reset(seed=2, options={}), twin.reset(seed=2))
    # PettingZoo's api_test and parallel_api_test probe reset(seed=0, options={"options": 1}): that key is ignored.
    assert _same(env.reset(seed=0, options={"options": 1}), twin.reset(seed=0))

    aec, aec_twin = module.env(), module.env()
    with pytest.raises(ValueError, match="option"):
        aec.reset(seed=0, options={"bogus": 1})
    with pytest.raises(gym.error.ResetNeeded):  # that reset did not count as one
        aec.step(np.zeros(2, np.float32))
    aec.reset(seed=0)
    aec_twin.reset(seed=0)
    _aec_cycle(aec, aec_twin, 2)
    for options in BAD_OPTIONS:
        with pytest.raises(ValueError, match="option"):
            aec.reset(seed=1, options=options)
    _aec_cycle(aec, aec_twin, 2 * len(aec.possible_agents))


@pytest.mark.parametrize("env_id", SINGLE_IDS)
def test_unknown_and_malformed_options_raise_and_change_nothing_in_the_single_robot_ids(env_id):
    env, twin = gym.make(env_id), gym.make(env_id)
    env.reset(seed=0)
    twin.reset(seed=0)
    for options in (*BAD_OPTIONS, {"options": 1}):  # the PettingZoo probe is no option of a Gymnasium env
        with pytest.raises(ValueError, match="option"):
            env.reset(seed=1, options=options)
    for step in range(3):
        action = np.random.default_rng(step).uniform(-1, 1, 2).astype(np.float32)
        assert _same(env.step(action), twin.step(action))
    assert _same(env.reset(), twin.reset())
    assert _same(env.reset(seed=3, options={}), twin.reset(seed=3))


def test_unknown_and_malformed_options_raise_and_change_nothing_in_the_vector_env():
    batch, twin = SwarmVectorEnv("corridor_v0", num_envs=2), SwarmVectorEnv("corridor_v0", num_envs=2)
    batch.reset(seed=0)
    twin.reset(seed=0)
    for options in (*BAD_OPTIONS, {"options": 1}):
        with pytest.raises(ValueError, match="option"):
            batch.reset(seed=1, options=options)
    for step in range(3):
        actions = np.random.default_rng(step).uniform(-1, 1, (batch.num_envs, 2))
        assert _same(batch.step(actions)[:4], twin.step(actions)[:4])
    assert _same(batch.reset(seed=4, options={}), twin.reset(seed=4))


# --- 11: one source of truth for the defaults ---------------------------------------------------------------------
@pytest.mark.parametrize("row", SWARM_ROWS, ids=lambda r: r.id)
def test_module_defaults_are_what_the_commands_evaluate(row):
    """``corridor_v0.parallel_env()`` built 1 robot while ``polyenvs evaluate polyenvs.swarm.corridor_v0`` built
    3 (the registry row's kwargs overrode the module's default)."""
    module = importlib.import_module(row.id)
    mine, evaluated = module.parallel_env(), make_env(row.id)
    assert (mine.n_robots, mine.max_cycles) == (evaluated.n_robots, evaluated.max_cycles)
    assert (mine.n_robots, mine.max_cycles) == (module.N_ROBOTS, module.MAX_CYCLES)
    assert row.max_cycles == evaluated.max_cycles  # the episode limit the pages and the leaderboard's pool read
    assert module.N_ROBOTS == {"corridor_v0": 3, "obstacle_field_v0": 3, "formation_v0": 7}[row.id.rsplit(".", 1)[1]]
    # The row carries no default of its own that differs from the module's.
    defaults = {
        name: p.default
        for cls in type(mine).__mro__
        if "__init__" in vars(cls)
        for name, p in reversed(inspect.signature(cls.__init__).parameters.items())
        if p.default is not inspect.Parameter.empty
    }
    assert all(defaults.get(k, object()) == v for k, v in row.kwargs.items()), row.kwargs


# --- TorchRL ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("module", MODULES, ids=IDS)
def test_torchrl_pettingzoo_wrapper_steps_every_swarm_module(module):
    """TorchRL's PettingZooWrapper failed with ``Could not infer dtype of dict`` (every robot's info carried a
    nested ``episode_metrics`` dict): with ``flat_info=True`` the metrics are flat keys of numbers in every info."""
    torch = pytest.importorskip("torch", reason="TorchRL needs torch")
    torchrl_envs = pytest.importorskip("torchrl.envs", reason="torchrl is not installed")
    # Parallel: robots that hit an obstacle leave (the mask), then the truncation and a reset. AEC: TorchRL steps a
    # robot that has left with an action, not PettingZoo's None (refused, as PettingZoo's own AECEnv refuses it),
    # so there no robot leaves before the truncation.
    cases = [
        (module.parallel_env(max_cycles=30, flat_info=True, terminate_on_collision=True), 70, True),
        (module.env(max_cycles=4, flat_info=True), 3 * len(module.env().possible_agents) * 4, False),
    ]
    for swarm, steps, robots_leave in cases:
        robots = list(swarm.possible_agents)
        env = torchrl_envs.PettingZooWrapper(swarm, group_map={"robot": robots}, use_mask=True, seed=0)
        shape = env.full_action_spec["robot", "action"].shape

        def forward(td, shape=shape):  # full speed ahead
            td["robot", "action"] = torch.ones(shape)
            return td

        rollout = env.rollout(steps, policy=forward, break_when_any_done=False)
        assert rollout.batch_size == torch.Size([steps])
        info = rollout["next", "robot", "info"]
        assert "episode_success_rate" in info.keys() and info["pose"].shape == (steps, len(robots), 3)
        assert torch.isfinite(info["episode_min_clearance_cm"]).all()
        assert rollout["next", "robot", "done"].any()  # an episode ended, and the next one began
        if robots_leave:  # (in AEC the mask marks the one robot that acts)
            assert (~rollout["next", "robot", "mask"]).any()


@pytest.mark.parametrize("module", MODULES, ids=IDS)
def test_flat_info_carries_the_nested_metrics_and_changes_nothing_else(module):
    nested, flat = module.parallel_env(max_cycles=20), module.parallel_env(max_cycles=20, flat_info=True)
    results = [nested.reset(seed=5)], [flat.reset(seed=5)]
    while nested.agents:
        actions = _actions(nested, len(results[0]))
        results[0].append(nested.step(actions))
        results[1].append(flat.step(actions))
    assert not flat.agents and len(results[0]) == 21
    for a, b in zip(*results, strict=True):
        assert _same(a[:-1], b[:-1])
        for agent, info in a[-1].items():
            metrics = info.pop("episode_metrics", None)  # nested: on the robot's last cycle only
            assert _same(info, {k: v for k, v in b[-1][agent].items() if not k.startswith("episode_")})
            flat_metrics = {k: v for k, v in b[-1][agent].items() if k.startswith("episode_")}
            assert set(flat_metrics) == {f"episode_{k}" for k in nested.metric_names}  # flat: every cycle
            if metrics is not None:
                assert {f"episode_{k}": v for k, v in metrics.items()} == flat_metrics
    assert nested.episode_metrics() == flat.episode_metrics()
    with pytest.raises(ValueError, match="flat_info"):
        module.parallel_env(flat_info=1)
