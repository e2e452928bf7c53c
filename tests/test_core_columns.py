"""Named columns (:mod:`polyenvs.core.columns`): the layout the batched-rows kernels write, from names only."""

from __future__ import annotations

import numpy as np
import pytest

from polyenvs.core.columns import OutColumns, indices, spans


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
