"""The numpy optimal assignment against scipy's ``linear_sum_assignment`` (the reference, a
test-only dependency) on random rectangular matrices, ties included."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.optimize import linear_sum_assignment as scipy_assignment

from percept.perception.assignment import linear_sum_assignment

SHAPES = st.tuples(st.integers(0, 12), st.integers(0, 12))


@settings(max_examples=300, deadline=None)
@given(SHAPES.flatmap(lambda s: arrays(float, s, elements=st.floats(-1e3, 1e3))))
def test_the_same_assignment_as_scipy(cost: np.ndarray) -> None:
    rows, cols = linear_sum_assignment(cost)
    theirs = scipy_assignment(cost)
    assert len(rows) == min(cost.shape)
    assert len(set(rows)) == len(rows) and len(set(cols)) == len(cols)
    assert cost[rows, cols].sum() == pytest.approx(cost[theirs].sum(), abs=1e-6)


@settings(max_examples=300, deadline=None)
@given(SHAPES.flatmap(lambda s: arrays(float, s, elements=st.sampled_from([0.0, 1.0, 2.0]))))
def test_ties_are_broken_as_scipy_breaks_them(cost: np.ndarray) -> None:
    """Costs from three values: many assignments cost the same; the one chosen is scipy's."""
    rows, cols = linear_sum_assignment(cost)
    theirs = scipy_assignment(cost)
    assert np.array_equal(rows, theirs[0]) and np.array_equal(cols, theirs[1])


def test_rows_ascend_when_there_are_more_rows_than_columns() -> None:
    cost = np.array([[5.0, 9.0], [1.0, 8.0], [7.0, 2.0]])
    rows, cols = linear_sum_assignment(cost)
    assert rows.tolist() == [1, 2] and cols.tolist() == [0, 1]


@pytest.mark.parametrize(
    "cost", [np.zeros(3), np.array([[1.0, np.nan]]), np.array([[np.inf, 1.0], [1.0, 2.0]])]
)
def test_what_is_no_cost_matrix_is_refused(cost: np.ndarray) -> None:
    with pytest.raises(ValueError, match="cost must"):
        linear_sum_assignment(cost)
