"""Distances between segments and walls (the kernels of walking routes and walkers)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from srpb_gym.sim.geometry import (
    leg_clearance,
    path_clearance,
    segment_distance,
    wall_between,
    wall_within,
)

coord = st.floats(-5.0, 5.0, allow_nan=False)


def sampled_distance(a, b, c, d, n=401) -> float:
    """Smallest distance between points sampled densely along the two segments."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    p = np.asarray(a) + t * (np.asarray(b) - np.asarray(a))
    q = np.asarray(c) + t * (np.asarray(d) - np.asarray(c))
    return float(np.min(np.hypot(*(p[:, None, :] - q[None, :, :]).transpose(2, 0, 1))))


@settings(max_examples=150, deadline=None)
@given(st.tuples(*[coord] * 8))
def test_segment_distance_matches_dense_sampling(v):
    a, b, c, d = v[0:2], v[2:4], v[4:6], v[6:8]
    exact = segment_distance(*a, *b, *c, *d)
    sampled = sampled_distance(a, b, c, d)
    length = max(np.hypot(*np.subtract(b, a)), np.hypot(*np.subtract(d, c)))
    assert exact <= sampled + 1e-9
    assert sampled - exact <= length / 400 + 1e-9  # the sampling step bounds the error


def test_crossing_and_touching_segments_are_at_distance_zero():
    assert segment_distance(0.0, 0.0, 2.0, 2.0, 0.0, 2.0, 2.0, 0.0) == 0.0  # crossing
    assert segment_distance(0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 2.0, 0.0) == 0.0  # touching ends
    assert segment_distance(0.0, 0.0, 2.0, 0.0, 1.0, 0.0, 3.0, 0.0) == 0.0  # overlapping
    assert segment_distance(0.0, 0.0, 2.0, 0.0, 3.0, 0.0, 4.0, 0.0) == 1.0  # collinear apart
    assert segment_distance(0.0, 0.0, 0.0, 0.0, 3.0, -1.0, 3.0, 1.0) == 3.0  # a point


def test_wall_queries_agree():
    walls = np.array([[2.0, -1.0, 2.0, 1.0], [5.0, 3.0, 6.0, 3.0]])
    ax = np.array([0.0, 0.0, 0.0])
    ay = np.array([0.0, 1.5, 3.0])
    bx = np.array([4.0, 4.0, 4.0])
    by = np.array([0.0, 1.5, 3.0])
    clear = path_clearance(ax, ay, bx, by, walls, np.empty(3))
    np.testing.assert_allclose(clear, [0.0, 0.5, 1.0])
    for k in range(3):
        assert wall_within(ax[k], ay[k], bx[k], by[k], 0.75, walls) == (clear[k] < 0.75)
    leg, ends = leg_clearance(0.0, 1.5, 4.0, 1.5, walls)
    assert np.isclose(leg, 0.5) and np.isclose(ends, np.hypot(1.0, 1.5))  # (4, 1.5) to (5, 3)
    assert path_clearance(ax, ay, bx, by, np.zeros((0, 4)), np.empty(3))[0] == np.inf


def test_wall_between_sees_through_openings_only():
    walls = np.array([[2.0, -1.0, 2.0, 1.0]])
    assert wall_between(0.0, 0.0, 4.0, 0.0, walls)
    assert wall_between(0.0, 1.0, 4.0, 1.0, walls)  # grazing the end blocks
    assert not wall_between(0.0, 1.5, 4.0, 1.5, walls)
    assert not wall_between(0.0, 0.0, 0.0, 0.0, walls)  # a point sees itself
    assert not wall_between(2.0, 1.0, 2.0, 3.0, walls)  # from the wall's end, away from it
