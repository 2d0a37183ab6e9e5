"""The people detector: field of view, range, occlusion, misses, noise and reproducibility."""

from __future__ import annotations

import math

import numpy as np
import pytest

from srpb_gym.errors import InputError
from srpb_gym.perception import DETECTOR_PRESETS, Detections, DetectorConfig, PeopleDetector

NO_SEGS = np.zeros((0, 4))
EXACT = {"miss_probability": 0.0, "noise_std": 0.0, "noise_per_meter": 0.0, "yaw_noise_std": 0.0}


def world(people_xy, radius=0.25, robot=(0.0, 0.0)):
    """people_xy, people_yaw, circles (people then the robot), skip, people_circle."""
    xy = np.asarray(people_xy, dtype=float).reshape(-1, 2)
    circles = np.vstack([np.column_stack([xy, np.full(len(xy), radius)]), [[*robot, 0.3]]])
    return xy, np.zeros(len(xy)), circles, len(xy), np.arange(len(xy))


def detect(detector, people_xy, segs=NO_SEGS, rng=None, yaw=0.0, robot=(0.0, 0.0)):
    xy, pyaw, circles, skip, own = world(people_xy, robot=robot)
    rng = np.random.default_rng(0) if rng is None else rng
    return detector.detect(robot[0], robot[1], yaw, xy, pyaw, circles, skip, own, segs, rng)


def test_field_of_view_and_range():
    # 60 deg, 0.6-8 m (people in a row would hide each other: occlusion is tested below)
    camera = PeopleDetector({"preset": "camera", **EXACT, "occlusion": False})
    people = [
        [3.0, 0.0],  # ahead
        [3.0, 3.0 * math.tan(math.radians(29))],  # just inside +30 deg
        [3.0, 3.0 * math.tan(math.radians(31))],  # just outside
        [-3.0, 0.0],  # behind
        [0.5, 0.0],  # too close
        [7.9, 0.0],
        [8.1, 0.0],  # too far
    ]
    found = detect(camera, people)
    assert found.index.tolist() == [0, 1, 5]
    np.testing.assert_array_equal(found.xy, np.asarray(people)[[0, 1, 5]])
    # turned around, only the person behind is in view
    assert detect(camera, people, yaw=math.pi).index.tolist() == [3]
    lidar = PeopleDetector({"preset": "lidar", **EXACT, "occlusion": False})  # 0.1-10 m
    assert detect(lidar, people).index.tolist() == [0, 1, 2, 3, 4, 5, 6]


def test_occlusion_by_walls_and_people():
    camera = PeopleDetector("camera")  # with its misses and noise
    wall = np.array([[2.0, -0.5, 2.0, 0.5]])
    behind_wall = [[4.0, 0.0]]
    behind_person = [[2.0, 0.0], [4.0, 0.05]]
    in_the_open = [[4.0, 2.0]]
    rng = np.random.default_rng(1)
    counts = np.zeros(3, dtype=int)
    for _ in range(200):
        assert len(detect(camera, behind_wall, wall, rng).index) == 0
        counts[0] += len(detect(camera, behind_wall, NO_SEGS, rng).index)
        found = detect(camera, behind_person, NO_SEGS, rng)
        assert 1 not in found.index
        counts[1] += len(found.index)
        counts[2] += len(detect(camera, in_the_open, wall, rng).index)
    assert (counts > 170).all()  # the same people in the open are seen (5 % misses)
    # without occlusion the wall and the person in front hide nobody
    through = PeopleDetector({"preset": "camera", **EXACT, "occlusion": False})
    assert detect(through, behind_wall, wall).index.tolist() == [0]
    assert detect(through, behind_person).index.tolist() == [0, 1]
    assert detect(PeopleDetector("perfect"), behind_wall, wall).index.tolist() == [0]


def test_visible_flags_before_misses():
    detector = PeopleDetector({"preset": "lidar", "miss_probability": 1.0})
    found = detect(detector, [[1.0, 0.0], [20.0, 0.0]])
    assert len(found.index) == 0
    assert detector.visible.tolist() == [True, False]


def test_miss_frequency():
    detector = PeopleDetector({"preset": "lidar", "miss_probability": 0.3})
    around = np.linspace(0.0, 2.0 * math.pi, 50, endpoint=False)
    people = 8.0 * np.column_stack([np.cos(around), np.sin(around)])  # 1 m apart, none hidden
    rng = np.random.default_rng(5)
    seen = sum(len(detect(detector, people, rng=rng).index) for _ in range(200))
    assert seen / (200 * 50) == pytest.approx(0.7, abs=0.02)


def test_noise_grows_with_range():
    detector = PeopleDetector({"preset": "lidar", "miss_probability": 0.0})  # 0.05 + 0.01/m
    people = [[1.0, 0.0], [0.0, 9.0]]
    rng = np.random.default_rng(8)
    runs = [detect(detector, people, rng=rng) for _ in range(3000)]
    errors = np.array([r.xy for r in runs]) - np.asarray(people)  # (runs, 2 people, 2)
    np.testing.assert_allclose(runs[0].std, [0.06, 0.14])
    np.testing.assert_allclose(errors.std(axis=0), [[0.06, 0.06], [0.14, 0.14]], rtol=0.05)
    assert np.abs(errors.mean(axis=0)).max() < 0.01
    yaw_errors = np.array([r.yaw for r in runs])
    assert yaw_errors.std(axis=0) == pytest.approx([0.5, 0.5], rel=0.05)
    assert np.abs(yaw_errors).max() <= math.pi


def test_same_seed_same_detections_and_fixed_draws():
    detector = PeopleDetector("camera")
    rng_people = np.random.default_rng(2)
    people = rng_people.uniform([0.0, -4.0], [8.0, 4.0], (20, 2))
    wall = np.array([[3.0, -1.0, 3.0, 1.0]])
    a = detect(detector, people, wall, np.random.default_rng(4))
    b = detect(detector, people, wall, np.random.default_rng(4))
    assert isinstance(a, Detections) and 0 < len(a.index) < 20
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    assert a.index.dtype == np.int64 and a.xy.shape == (len(a.index), 2)
    # the number of draws does not depend on who is visible
    rng_front, rng_back = np.random.default_rng(6), np.random.default_rng(6)
    detect(detector, people, wall, rng_front, yaw=0.0)
    detect(detector, people, wall, rng_back, yaw=math.pi)
    assert rng_front.random() == rng_back.random()
    # results are fresh arrays, not views of reused buffers
    c = detect(detector, people, NO_SEGS, np.random.default_rng(5))
    np.testing.assert_array_equal(a.xy, b.xy)
    assert not np.shares_memory(a.xy, c.xy)


def test_no_people():
    found = detect(PeopleDetector(), np.zeros((0, 2)))
    assert found.index.shape == (0,) and found.xy.shape == (0, 2)


def test_config_presets_and_validation():
    assert DetectorConfig.from_spec(None) == DETECTOR_PRESETS["camera"]
    camera = DETECTOR_PRESETS["camera"]
    assert camera.fov == pytest.approx(math.radians(60))
    assert (camera.range_min, camera.range_max, camera.miss_probability) == (0.6, 8.0, 0.05)
    perfect = DETECTOR_PRESETS["perfect"]
    assert perfect.range_max == math.inf and not perfect.occlusion
    lidar = DetectorConfig.from_spec({"preset": "lidar", "range_max": 6.0}, path="detector")
    assert lidar.range_max == 6.0 and lidar.fov == pytest.approx(2 * math.pi)
    with pytest.raises(InputError, match=r"sensors\.people\.noise"):
        DetectorConfig.from_spec({"noise": 0.1}, path="sensors.people")
    bad = [
        {"fov": 0.0}, {"range_min": 9.0}, {"miss_probability": 1.5},
        {"noise_std": -0.1}, {"noise_per_meter": math.nan}, {"yaw_noise_std": math.inf},
    ]  # fmt: skip
    for kwargs in bad:
        with pytest.raises(ValueError):
            DetectorConfig(**kwargs)
        with pytest.raises(InputError):
            DetectorConfig.from_spec(kwargs)
