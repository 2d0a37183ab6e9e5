"""Ray casts, obstacle distances and lines of sight of srpb_gym.sim.geometry."""

from __future__ import annotations

import math

import numpy as np
import pymunk
import pytest

from srpb_gym.sim.geometry import (
    line_of_sight,
    point_obstacle_distance,
    point_segment_distance,
    raycast,
)

NO_SEGS = np.zeros((0, 4))
NO_CIRCLES = np.zeros((0, 3))


def random_scene(rng: np.random.Generator, n_segs: int = 12, n_circles: int = 20):
    """Walls of random length and direction and bodies of radius 0.2-0.4 m in a 16 m box,
    the sensing robot's own circle last (at the origin)."""
    a = rng.uniform(-8.0, 8.0, (n_segs, 2))
    lengths = rng.uniform(0.0, 6.0, n_segs)
    lengths[0] = 0.0  # a zero-length segment
    heading = rng.uniform(-math.pi, math.pi, n_segs)
    b = a + lengths[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
    segs = np.column_stack([a, b])
    circles = np.column_stack(
        [rng.uniform(-8.0, 8.0, (n_circles, 2)), rng.uniform(0.2, 0.4, n_circles)]
    )
    circles = np.vstack([circles, [[0.0, 0.0, 0.3]]])
    return segs, circles, n_circles


def pymunk_ranges(ox, oy, yaw, angles, range_max, segs, circles, skip):
    """Per-beam ``Space.segment_query_first`` distances in the same scene."""
    space = pymunk.Space()
    body = space.static_body
    for x0, y0, x1, y1 in segs:
        space.add(pymunk.Segment(body, (x0, y0), (x1, y1), 0.0))
    for j, (x, y, r) in enumerate(circles):
        if j != skip:
            space.add(pymunk.Circle(body, r, (x, y)))
    out = np.full(angles.shape[0], range_max)
    for b, a in enumerate(angles):
        end = (ox + range_max * math.cos(yaw + a), oy + range_max * math.sin(yaw + a))
        hit = space.segment_query_first((ox, oy), end, 0.0, pymunk.ShapeFilter())
        if hit is not None:
            out[b] = hit.alpha * range_max
    return out


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("fov", [math.pi, 2.0 * math.pi])
def test_raycast_matches_pymunk(seed, fov):
    rng = np.random.default_rng(seed)
    segs, circles, skip = random_scene(rng)
    ox, oy = rng.uniform(-0.5, 0.5, 2)
    circles[skip, :2] = (ox, oy)
    yaw = rng.uniform(-math.pi, math.pi)
    angles = np.linspace(-fov / 2, fov / 2, 181)
    ours = raycast(ox, oy, yaw, angles, 12.0, segs, circles, skip, np.empty(181))
    ref = pymunk_ranges(ox, oy, yaw, angles, 12.0, segs, circles, skip)
    np.testing.assert_allclose(ours, ref, atol=1e-3, rtol=0)
    assert (ours < 12.0).sum() > 20  # the scene is not empty


@pytest.mark.parametrize("seed", range(3))
def test_raycast_any_beam_order_same_ranges(seed):
    rng = np.random.default_rng(100 + seed)
    segs, circles, skip = random_scene(rng, n_segs=20, n_circles=30)
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    order = rng.permutation(360)
    sorted_ranges = raycast(0.0, 0.0, 1.0, angles, 10.0, segs, circles, skip, np.empty(360))
    shuffled = raycast(0.0, 0.0, 1.0, angles[order], 10.0, segs, circles, skip, np.empty(360))
    np.testing.assert_allclose(shuffled, sorted_ranges[order], atol=1e-12)
    # the same directions written outside [-pi, pi] (no angular windows) agree too
    shifted = raycast(0.0, 0.0, 1.0, angles + 4 * math.pi, 10.0, segs, circles, skip,
                      np.empty(360))  # fmt: skip
    np.testing.assert_allclose(shifted, sorted_ranges, atol=1e-9)


def test_raycast_hand_made_cases():
    out = np.empty(3)
    angles = np.array([-math.pi / 2, 0.0, math.pi / 2])
    wall = np.array([[3.0, -10.0, 3.0, 10.0]])  # x = 3
    ranges = raycast(0.0, 0.0, 0.0, angles, 20.0, wall, NO_CIRCLES, -1, out)
    np.testing.assert_allclose(ranges, [20.0, 3.0, 20.0])
    body = np.array([[5.0, 0.0, 0.5], [0.0, 0.0, 0.3]])  # ahead, and the robot itself
    ranges = raycast(0.0, 0.0, 0.0, angles, 20.0, NO_SEGS, body, 1, out)
    np.testing.assert_allclose(ranges, [20.0, 4.5, 20.0])
    # facing +y: the wall is now on the right-hand beam
    ranges = raycast(1.0, 0.0, math.pi / 2, angles, 20.0, wall, NO_CIRCLES, -1, out)
    np.testing.assert_allclose(ranges, [2.0, 20.0, 20.0])
    # nothing at all
    assert (raycast(0.0, 0.0, 0.3, angles, 7.0, NO_SEGS, NO_CIRCLES, -1, out) == 7.0).all()
    # hits beyond range_max are not reported
    assert (raycast(0.0, 0.0, 0.0, angles, 2.5, wall, NO_CIRCLES, -1, out) == 2.5).all()


def test_raycast_degenerate_geometry():
    out = np.empty(2)
    angles = np.array([0.0, math.pi / 2])
    # a wall parallel to the beam beside it, and one along the beam's own line
    beside = np.array([[0.0, 1.0, 10.0, 1.0]])
    np.testing.assert_allclose(raycast(0.0, 0.0, 0.0, angles, 20, beside, NO_CIRCLES, -1, out),
                               [20.0, 1.0])  # fmt: skip
    along = np.array([[4.0, 0.0, 9.0, 0.0]])
    np.testing.assert_allclose(raycast(0.0, 0.0, 0.0, angles, 20, along, NO_CIRCLES, -1, out),
                               [4.0, 20.0])  # fmt: skip
    reversed_along = along[:, [2, 3, 0, 1]]
    assert raycast(0.0, 0.0, 0.0, angles, 20, reversed_along, NO_CIRCLES, -1, out)[0] == 4.0
    # a point obstacle (zero-length segment) on a beam and one off it
    points = np.array([[6.0, 0.0, 6.0, 0.0], [3.0, 0.5, 3.0, 0.5]])
    np.testing.assert_allclose(raycast(0.0, 0.0, 0.0, angles, 20, points, NO_CIRCLES, -1, out),
                               [6.0, 20.0])  # fmt: skip
    # the origin on a wall reads 0 on every beam
    through = np.array([[-1.0, 0.0, 1.0, 0.0]])
    assert (raycast(0.0, 0.0, 0.0, angles, 20, through, NO_CIRCLES, -1, out) == 0.0).all()


def test_raycast_origin_inside_a_circle_is_blocked():
    angles = np.linspace(-math.pi, math.pi, 8, endpoint=False)
    circles = np.array([[0.2, 0.0, 1.0], [4.0, 0.0, 0.5]])  # around the origin, and ahead
    ranges = raycast(0.0, 0.0, 0.0, angles, 10.0, NO_SEGS, circles, -1, np.empty(8))
    assert (ranges == 0.0).all()
    ranges = raycast(0.0, 0.0, 0.0, angles, 10.0, NO_SEGS, circles, 0, np.empty(8))
    expected = np.full(8, 10.0)
    expected[4] = 3.5  # angle 0 is beam 4
    np.testing.assert_allclose(ranges, expected)
    on_boundary = np.array([[1.0, 0.0, 1.0]])
    assert (raycast(0.0, 0.0, 0.0, angles, 10.0, NO_SEGS, on_boundary, -1, ranges) == 0).all()


def test_point_obstacle_distance_matches_brute_force():
    rng = np.random.default_rng(7)
    segs, circles, skip = random_scene(rng)
    s = np.linspace(0.0, 1.0, 2001)[:, None]
    for px, py in rng.uniform(-9.0, 9.0, (50, 2)):
        wall_points = segs[:, None, :2] + s[None] * (segs[:, None, 2:] - segs[:, None, :2])
        walls = np.hypot(wall_points[..., 0] - px, wall_points[..., 1] - py).min()
        others = np.delete(circles, skip, axis=0)
        bodies = np.maximum(np.hypot(others[:, 0] - px, others[:, 1] - py) - others[:, 2], 0.0)
        expected = min(walls, bodies.min())
        got = point_obstacle_distance(px, py, segs, circles, skip)
        assert got <= expected + 1e-12
        assert got == pytest.approx(expected, abs=4e-3)  # the sampled walls are 3 mm apart


def test_point_obstacle_distance_edge_cases():
    assert point_obstacle_distance(1.0, 2.0, NO_SEGS, NO_CIRCLES, -1) == math.inf
    only_self = np.array([[1.0, 2.0, 0.3]])
    assert point_obstacle_distance(1.0, 2.0, NO_SEGS, only_self, 0) == math.inf
    assert point_obstacle_distance(1.0, 2.0, NO_SEGS, only_self, -1) == 0.0  # inside: 0
    assert point_segment_distance(3.0, 4.0, 0.0, 0.0, 0.0, 0.0) == 5.0  # zero length
    assert point_segment_distance(-3.0, 1.0, 0.0, 0.0, 5.0, 0.0) == pytest.approx(math.hypot(3, 1))


def test_line_of_sight_walls_and_people():
    circles = np.array([
        [0.0, 0.0, 0.3], [5.0, 0.0, 0.25], [10.0, 0.0, 0.25], [5.0, 4.0, 0.25], [8.0, -2.0, 0.25],
    ])  # fmt: skip
    wall = np.array([[2.0, 1.0, 2.0, 6.0]])  # blocks the way to (5, 4) only
    tx = np.array([5.0, 10.0, 5.0, 8.0])
    ty = np.array([0.0, 0.0, 4.0, -2.1])
    own = np.array([1, 2, 3, -1])
    out = line_of_sight(0.0, 0.0, tx, ty, wall, circles, 0, own, np.empty(4, dtype=np.bool_))
    # person 1 in the open; person 2 behind person 1; person 3 behind the wall; the point
    # (8, -2.1) lies inside body 4, which blocks it (it is not that target's own)
    assert out.tolist() == [True, False, False, False]
    out = line_of_sight(0.0, 0.0, tx, ty, NO_SEGS, circles[:1], 0, np.full(4, -1),
                        np.empty(4, dtype=np.bool_))  # fmt: skip
    assert out.all()


def test_line_of_sight_special_cases():
    out = np.empty(1, dtype=np.bool_)
    no_own = np.array([-1])
    # the target on the origin is visible
    wall = np.array([[-1.0, 1.0, 1.0, 1.0]])
    assert line_of_sight(0.0, 0.0, np.array([0.0]), np.array([0.0]), wall, NO_CIRCLES, -1, no_own,
                         out)[0]  # fmt: skip
    # a collinear wall between origin and target blocks; one beyond it does not
    for seg, seen in (([2.0, 0.0, 3.0, 0.0], False), ([6.0, 0.0, 8.0, 0.0], True)):
        got = line_of_sight(0.0, 0.0, np.array([5.0]), np.array([0.0]), np.array([seg]),
                            NO_CIRCLES, -1, no_own, out)[0]  # fmt: skip
        assert got == seen
    # a circle around the origin blocks (as for the ray cast), unless it is the target's own
    around = np.array([[0.1, 0.0, 0.5]])
    assert not line_of_sight(0.0, 0.0, np.array([5.0]), np.array([0.0]), NO_SEGS, around, -1,
                             no_own, out)[0]  # fmt: skip
    assert line_of_sight(0.0, 0.0, np.array([5.0]), np.array([0.0]), NO_SEGS, around, -1,
                         np.array([0]), out)[0]  # fmt: skip
    # a body that the sight line only grazes does not block
    grazed = np.array([[2.0, 1.0, 1.0]])
    assert line_of_sight(0.0, 0.0, np.array([5.0]), np.array([0.0]), NO_SEGS, grazed, -1, no_own,
                         out)[0]  # fmt: skip


@pytest.mark.parametrize("seed", range(3))
def test_line_of_sight_agrees_with_raycast(seed):
    """Visible exactly when a ray toward the target reaches it first (off the boundaries)."""
    rng = np.random.default_rng(200 + seed)
    segs, circles, skip = random_scene(rng)
    targets = rng.uniform(-8.0, 8.0, (200, 2))
    seen = line_of_sight(0.0, 0.0, targets[:, 0], targets[:, 1], segs, circles, skip,
                         np.full(200, -1), np.empty(200, dtype=np.bool_))  # fmt: skip
    dist = np.hypot(targets[:, 0], targets[:, 1])
    angles = np.arctan2(targets[:, 1], targets[:, 0])
    first = raycast(0.0, 0.0, 0.0, angles, 20.0, segs, circles, skip, np.empty(200))
    clear = np.abs(first - dist) > 1e-9
    assert clear.sum() > 150
    np.testing.assert_array_equal(seen[clear], (first >= dist)[clear])
    assert 0 < seen.sum() < 200


def test_origin_inside_a_body_like_pymunk():
    rng = np.random.default_rng(11)
    segs, circles, _ = random_scene(rng)
    circles[-1] = (0.3, -0.2, 0.8)  # another body around the origin, not skipped
    angles = np.linspace(-math.pi, math.pi, 181)
    ours = raycast(0.0, 0.0, 0.0, angles, 12.0, segs, circles, -1, np.empty(181))
    ref = pymunk_ranges(0.0, 0.0, 0.0, angles, 12.0, segs, circles, -1)
    np.testing.assert_allclose(ours, ref, atol=1e-3, rtol=0)
