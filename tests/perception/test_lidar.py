"""The planar lidar: beams, ranges against pymunk, noise, clipping and its config."""

from __future__ import annotations

import math

import numpy as np
import pymunk
import pytest

from srpb_gym.errors import InputError
from srpb_gym.perception import LIDAR_PRESETS, Lidar, LidarConfig

NO_SEGS = np.zeros((0, 4))
NO_CIRCLES = np.zeros((0, 3))
EXACT = {"noise_std": 0.0}


def corridor_scene(rng: np.random.Generator):
    """A 4 m wide corridor with doors and random clutter, 20 people, the robot last."""
    segs = np.array([
        [-2.0, -2.0, 30.0, -2.0], [-2.0, 2.0, 30.0, 2.0], [-2.0, -2.0, -2.0, 2.0],
        [6.0, -2.0, 6.0, -0.8], [12.0, 2.0, 12.0, 0.9], [18.0, -2.0, 18.5, -1.0],
    ])  # fmt: skip
    clutter = rng.uniform([-1.0, -1.8], [25.0, 1.8], (4, 2))
    heading = rng.uniform(-math.pi, math.pi, 4)
    ends = clutter + rng.uniform(0.2, 1.5, (4, 1)) * np.column_stack(
        [np.cos(heading), np.sin(heading)]
    )
    segs = np.vstack([segs, np.column_stack([clutter, ends])])
    people = np.column_stack([rng.uniform([0.5, -1.7], [26.0, 1.7], (20, 2)), np.full(20, 0.25)])
    robot = [rng.uniform(-1.5, 0.5), rng.uniform(-1.5, 1.5), 0.3]
    return segs, np.vstack([people, robot]), 20


def pymunk_scan(x, y, yaw, angles, range_max, segs, circles, skip):
    """One ``segment_query_first`` per beam, radius 0, static shapes."""
    space = pymunk.Space()
    for x0, y0, x1, y1 in segs:
        space.add(pymunk.Segment(space.static_body, (x0, y0), (x1, y1), 0.0))
    for j, (cx, cy, r) in enumerate(circles):
        if j != skip:
            body = pymunk.Body(body_type=pymunk.Body.STATIC)
            body.position = (cx, cy)
            space.add(body, pymunk.Circle(body, r))
    out = np.full(len(angles), range_max)
    query = pymunk.ShapeFilter()
    for b, a in enumerate(angles):
        end = (x + range_max * math.cos(yaw + a), y + range_max * math.sin(yaw + a))
        hit = space.segment_query_first((x, y), end, 0.0, query)
        if hit is not None:
            out[b] = hit.alpha * range_max
    return out


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("preset", ["default", "wide"])
def test_scan_agrees_with_pymunk(seed, preset):
    lidar = Lidar({"preset": preset, **EXACT, "range_min": 0.0})
    rng = np.random.default_rng(seed)
    segs, circles, skip = corridor_scene(rng)
    x, y = circles[skip, :2]
    yaw = rng.uniform(-math.pi, math.pi)
    ranges = lidar.scan(x, y, yaw, segs, circles, skip, rng)
    expected = pymunk_scan(x, y, yaw, lidar.angles, lidar.config.range_max, segs, circles, skip)
    np.testing.assert_allclose(ranges, expected, atol=1e-3, rtol=0)
    assert (ranges < lidar.config.range_max).sum() > lidar.n_beams // 4


def test_beam_angles():
    default = Lidar().angles
    assert default.shape == (181,)
    np.testing.assert_allclose(default, np.radians(np.arange(-90, 91)), atol=1e-12)
    wide = Lidar("wide").angles
    assert wide.shape == (360,)
    np.testing.assert_allclose(np.diff(wide), 2 * math.pi / 360)
    assert wide[180] == 0.0 and wide[0] == pytest.approx(-math.pi)  # -pi once, no +pi
    odd = Lidar({"fov": 2 * math.pi, "n_beams": 5}).angles
    np.testing.assert_allclose(odd, -odd[::-1], atol=1e-15)  # symmetric, no +-pi beam
    assert np.abs(odd).max() < math.pi
    # 2 pi written with few digits is still a full turn
    assert Lidar({"fov": 6.283185, "n_beams": 4}).angles.tolist() == pytest.approx(
        [-math.pi, -math.pi / 2, 0.0, math.pi / 2]
    )
    assert Lidar({"n_beams": 1}).angles.tolist() == [0.0]


def test_hand_made_ranges():
    lidar = Lidar(EXACT)
    wall = np.array([[4.0, -10.0, 4.0, 10.0]])
    body = np.array([[0.0, 0.0, 0.3], [0.0, 2.0, 0.5]])  # the robot, a person on its left
    ranges = lidar.scan(0.0, 0.0, 0.0, wall, body, 0, None)
    assert ranges[90] == pytest.approx(4.0)  # straight ahead
    assert ranges[180] == pytest.approx(1.5)  # 90 deg left: the person
    assert ranges[0] == 25.0  # 90 deg right: nothing, range_max
    assert ranges[135] == pytest.approx(4.0 * math.sqrt(2.0))
    empty = lidar.scan(3.0, -1.0, 2.0, NO_SEGS, NO_CIRCLES, -1, None)
    assert (empty == 25.0).all() and np.isfinite(empty).all()


def test_clipping_to_range_min():
    lidar = Lidar({"noise_std": 0.005, "range_min": 0.1})
    close = np.array([[0.02, -5.0, 0.02, 5.0]])  # 2 cm ahead
    ranges = lidar.scan(0.0, 0.0, 0.0, close, NO_CIRCLES, -1, np.random.default_rng(0))
    assert ranges.min() == 0.1
    assert ranges[90] == 0.1
    buried = np.array([[0.0, 0.0, 1.0]])  # the sensor inside another body
    ranges = lidar.scan(0.0, 0.0, 0.0, NO_SEGS, buried, -1, np.random.default_rng(0))
    assert (ranges == 0.1).all()


def test_noise_statistics_and_range_max():
    lidar = Lidar({"noise_std": 0.02})
    wall = np.array([[5.0, -100.0, 5.0, 100.0]])  # beams with |angle| < ~78 deg hit it
    rng = np.random.default_rng(42)
    scans = np.array([lidar.scan(0.0, 0.0, 0.0, wall, NO_CIRCLES, -1, rng).copy()
                      for _ in range(400)])  # fmt: skip
    error = scans - lidar.true_ranges
    hitting = np.abs(lidar.angles) < math.radians(70)
    assert abs(error[:, hitting].mean()) < 0.001
    assert error[:, hitting].std() == pytest.approx(0.02, rel=0.03)
    # beams that hit nothing read exactly range_max, without noise
    assert (scans[:, np.abs(lidar.angles) > math.radians(89)] == 25.0).all()
    assert (scans <= 25.0).all()


def test_same_seed_same_scan_and_out_buffer():
    lidar = Lidar()
    segs, circles, skip = corridor_scene(np.random.default_rng(3))
    a = lidar.scan(0.0, 0.0, 0.4, segs, circles, skip, np.random.default_rng(9)).copy()
    out = np.empty(181)
    b = lidar.scan(0.0, 0.0, 0.4, segs, circles, skip, np.random.default_rng(9), out=out)
    assert b is out
    np.testing.assert_array_equal(a, b)
    c = lidar.scan(0.0, 0.0, 0.4, segs, circles, skip, np.random.default_rng(10))
    assert not np.array_equal(a, c)
    with pytest.raises(ValueError, match="rng"):
        lidar.scan(0.0, 0.0, 0.0, segs, circles, skip, None)


def test_hit_points():
    lidar = Lidar(EXACT)
    wall = np.array([[4.0, -50.0, 4.0, 50.0]])
    x, y, yaw = 1.0, 2.0, 0.3
    ranges = lidar.scan(x, y, yaw, wall, NO_CIRCLES, -1, None)
    points = lidar.hit_points(x, y, yaw, ranges)
    assert points.shape == (181, 2)
    hit = ranges < 25.0
    np.testing.assert_allclose(points[hit, 0], 4.0, atol=1e-9)
    np.testing.assert_allclose(np.hypot(points[:, 0] - x, points[:, 1] - y), ranges)


def test_config_presets_and_validation():
    assert LidarConfig.from_spec(None) == LIDAR_PRESETS["default"] == LIDAR_PRESETS["paper"]
    assert LIDAR_PRESETS["default"] == LidarConfig(math.pi, 181, 0.05, 25.0, 0.01)
    wide = LidarConfig.from_spec("wide")
    assert (wide.fov, wide.n_beams, wide.range_min, wide.range_max) == (2 * math.pi, 360, 0.1, 10)
    custom = LidarConfig.from_spec({"preset": "wide", "n_beams": 90}, path="sensors.lidar")
    assert custom.n_beams == 90 and custom.range_max == 10.0
    with pytest.raises(InputError, match=r"sensors\.lidar\.beams"):
        LidarConfig.from_spec({"beams": 3}, path="sensors.lidar")
    with pytest.raises(InputError, match="unknown preset"):
        LidarConfig.from_spec("hokuyo")
    bad = [{"n_beams": 0}, {"range_min": -0.1}, {"range_min": 30.0}, {"fov": 0.0},
           {"fov": 7.0}, {"noise_std": -1.0}, {"range_max": math.inf}]  # fmt: skip
    for kwargs in bad:
        with pytest.raises(ValueError):
            LidarConfig(**kwargs)
        with pytest.raises(InputError):
            LidarConfig.from_spec(kwargs, path="lidar")
