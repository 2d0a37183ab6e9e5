from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment as scipy_lsa

from srpb_gym.perception.assignment import INFEASIBLE, INVALID, linear_sum_assignment


def ours(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray] | int:
    nr, nc = cost.shape
    rows, cols = np.empty(min(nr, nc), np.int64), np.empty(min(nr, nc), np.int64)
    k = linear_sum_assignment(np.ascontiguousarray(cost).ravel(), nr, nc, rows, cols)
    return (rows[:k], cols[:k]) if k >= 0 else k


def matrices(seed: int, count: int):
    """Random cost matrices of every small shape: continuous, integer (many ties), constant,
    and tracker-like (a few admissible costs, the rest one large value)."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        nr, nc = rng.integers(1, 9, 2)
        kind = rng.integers(4)
        if kind == 0:
            yield rng.uniform(0.0, 10.0, (nr, nc))
        elif kind == 1:
            yield rng.integers(0, 4, (nr, nc)).astype(np.float64)
        elif kind == 2:
            yield np.full((nr, nc), float(rng.integers(3)))
        else:
            cost = rng.uniform(0.0, 9.21, (nr, nc))
            big = 9.21 * (min(nr, nc) + 1) + 1.0
            yield np.where(rng.random((nr, nc)) < 0.6, big, cost)


@pytest.mark.parametrize("seed", range(4))
def test_same_pairs_as_scipy_ties_included(seed):
    for cost in matrices(seed, 3000):
        expected = scipy_lsa(cost)
        got = ours(cost)
        np.testing.assert_array_equal(got[0], expected[0])
        np.testing.assert_array_equal(got[1], expected[1])


def test_empty_infeasible_and_invalid():
    assert [a.size for a in ours(np.zeros((0, 3)))] == [0, 0]
    assert ours(np.array([[math.inf, 1.0], [math.inf, 2.0]])) == INFEASIBLE
    assert ours(np.array([[math.nan, 1.0]])) == INVALID
    assert ours(np.array([[-math.inf, 1.0]])) == INVALID
    rows, cols = ours(np.array([[math.inf, 1.0], [2.0, math.inf]]))
    assert rows.tolist() == [0, 1] and cols.tolist() == [1, 0]
