"""Named columns (:mod:`polyenvs.core.columns`): the layout the batched-rows kernels write, from names only, and
every batched-rows task's kernels and ``info`` agreeing on it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401
from polyenvs.core.columns import OutColumns, indices, spans
from polyenvs.core.rows import RowsEnv

ROWS_IDS = [
    "polyenvs/BuckybotWallFollow-v0",
    "polyenvs/BuckybotExplore-v0",
    "polyenvs/BuckybotGoal-v0",
    "polyenvs/BumperCartExplore-v0",
]


def test_out_columns_lay_out_terms_metrics_reward_and_terminated_by_name():
    out = OutColumns(("progress", "blocked"), ("coverage", "steps", "progress"))
    assert out.term_columns("progress", "blocked") == (0, 1)
    assert out.metric_columns("coverage", "steps", "progress") == (2, 3, 4)
    assert (out.reward, out.terminated, out.width) == (5, 6, 7)
    assert out.term_columns("blocked", "progress") == (1, 0)  # asked by name: the order asked, not the layout's
    assert out.term_column("progress") != out.metric_column("progress")  # a term and a metric may share a name
    table = np.arange(out.width)
    assert list(table[out.term_slice]) == [0, 1] and list(table[out.metric_slice]) == [2, 3, 4]
    # Adding a metric adds a column after the others and moves only the reward and terminated flag.
    grown = OutColumns(out.terms, (*out.metrics, "new"))
    assert grown.metric_columns(*out.metrics) == out.metric_columns(*out.metrics)
    assert (grown.metric_column("new"), grown.reward) == (5, 6)


def test_out_columns_refuse_repeated_unknown_and_non_string_names():
    with pytest.raises(ValueError, match="repeat"):
        OutColumns(("a", "a"), ())
    with pytest.raises(ValueError, match="repeat"):
        OutColumns((), ("m", "n", "m"))
    with pytest.raises(TypeError):
        OutColumns(("",), ())
    with pytest.raises(TypeError):
        OutColumns((1,), ())
    out = OutColumns(("a",), ("m",))
    with pytest.raises(KeyError, match="no reward term 'm'"):
        out.term_column("m")
    with pytest.raises(KeyError, match="no metric 'a'"):
        out.metric_column("a")
    assert out == OutColumns(("a",), ("m",)) and out != OutColumns(("a",), ("n",))


def test_spans_and_indices():
    assert spans({"range": 6, "flag": 1}, start=2) == {"range": (2, 8), "flag": (8, 9)}
    assert indices(("state", "walls")) == {"state": 0, "walls": 1}
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError):
            spans({"part": bad})
    with pytest.raises(ValueError, match="repeat"):
        indices(("a", "b", "a"))


@pytest.mark.parametrize("env_id", ROWS_IDS)
def test_kernels_columns_are_the_info_keys(env_id):
    """The columns a task's kernels write are the ones ``info`` and ``episode_metrics()`` read: every reward term
    in ``info`` and every metric is the value in its named column, and the reward and terminated flag are theirs."""
    env = gym.make(env_id)
    core = env.unwrapped
    assert isinstance(core, RowsEnv)
    out = core.out_columns
    assert out.terms == tuple(core.reward_names) and out.metrics == tuple(core.all_metric_names)
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(20):
        _, reward, terminated, _, info = env.step(env.action_space.sample())
        row = core._out[0]
        for name in out.terms:
            assert info[f"reward_{name}"] == row[out.term_column(name)]
        metrics = core.episode_metrics()
        assert list(metrics) == list(out.metrics)
        for name in out.metrics:
            assert metrics[name] == row[out.metric_column(name)]
        assert reward == row[out.reward] and terminated == bool(row[out.terminated])
        if terminated:
            env.reset()


def test_the_names_are_read_from_the_declaration():
    """A task declares its names once, in ``out_columns``: the reward terms and the metrics (a Buckybot task's own,
    after the family's) are read from it, so the kernels' columns and ``info`` cannot drift apart."""
    from polyenvs.buckybot.goal import METRICS, REWARD_TERMS, BuckybotGoalEnv

    env = BuckybotGoalEnv()
    assert env.reward_names == REWARD_TERMS and env.metric_names == METRICS
    assert env.all_metric_names == (*BuckybotGoalEnv.base_metric_names, *METRICS) == env.out_columns.metrics
