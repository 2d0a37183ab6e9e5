"""Tests of the constant-velocity Kalman multi-person tracker."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from srpb_gym.errors import InputError
from srpb_gym.perception.tracker import PRESETS, KalmanTracker, TrackerConfig, Tracks

DT = 0.1
STD = 0.1


def one(xy, yaw=0.0, std=STD):
    """Detection arrays for a single detection."""
    return np.array([xy], dtype=float), np.array([yaw]), np.array([std])


def none():
    return np.zeros((0, 2)), np.zeros(0), np.zeros(0)


def walk(tracker, start, velocity, steps, rng, std=STD, t0=0):
    """Feed noisy detections of one person walking at constant velocity; returns the true
    positions and the tracker's (ids, xy, velocity) after every step."""
    start, velocity = np.asarray(start, float), np.asarray(velocity, float)
    out = []
    for k in range(t0, t0 + steps):
        true = start + velocity * (k * DT)
        tracker.step(DT, *one(true + rng.normal(0.0, std, 2), np.arctan2(*velocity[::-1]), std))
        out.append((true, tracker.ids.copy(), tracker.xy.copy(), tracker.velocity.copy()))
    return out


def pos_var(tracker):
    return np.trace(tracker.covariance[0])


def test_straight_walk_keeps_id_converges_and_filters_noise():
    rng = np.random.default_rng(0)
    tr = KalmanTracker()
    out = walk(tr, (0.0, 0.0), (1.2, 0.4), 150, rng)
    assert all(ids.tolist() == [0] for _, ids, _, _ in out)
    assert tr.next_id == 1
    vel = np.array([v[0] for _, _, _, v in out])
    assert np.linalg.norm(vel[0] - (1.2, 0.4)) > 1.0  # starts at rest
    assert np.mean(np.linalg.norm(vel[50:] - (1.2, 0.4), axis=1)) < 0.25
    assert np.linalg.norm(vel[50:].mean(axis=0) - (1.2, 0.4)) < 0.05
    track_err = np.mean([np.linalg.norm(xy[0] - true) ** 2 for true, _, xy, _ in out[20:]])
    raw_err = 2 * STD**2  # mean squared 2-D error of a raw detection
    assert track_err < 0.6 * raw_err
    assert abs(tr.yaw[0] - np.arctan2(0.4, 1.2)) < 1e-9  # noiseless yaw measurements


def test_occlusion_grows_then_shrinks_covariance_and_keeps_id():
    rng = np.random.default_rng(1)
    tr = KalmanTracker()
    walk(tr, (0.0, 0.0), (1.0, 0.0), 30, rng)
    covs = [tr.covariance[0].copy()]
    for _ in range(8):  # 0.8 s < timeout
        assert tr.step(DT, *none()) == 1
        assert not tr.matched[0] and tr.detection[0] == -1
        covs.append(tr.covariance[0].copy())
    for a, b in itertools.pairwise(covs):
        assert np.linalg.eigvalsh(b - a).min() > 0.0  # strictly grows (Loewner order)
    assert tr.time_since_update[0] == pytest.approx(0.8)
    before = tr.covariance[0].copy()
    walk(tr, (0.0, 0.0), (1.0, 0.0), 1, rng, t0=38)
    assert tr.ids.tolist() == [0] and tr.matched[0] and tr.detection[0] == 0
    assert np.linalg.eigvalsh(before - tr.covariance[0]).min() > 0.0
    assert tr.time_since_update[0] == 0.0
    assert tr.age[0] == pytest.approx(3.8)


def test_timeout_deletes_and_reappearing_person_gets_new_id():
    rng = np.random.default_rng(2)
    tr = KalmanTracker(TrackerConfig(timeout=0.5))
    walk(tr, (0.0, 0.0), (1.0, 0.0), 20, rng)
    for _ in range(5):  # time since update reaches the timeout: kept
        tr.step(DT, *none())
    assert len(tr) == 1
    tr.step(DT, *none())  # exceeds it: deleted
    assert len(tr) == 0 and tr.ids.shape == (0,) and tr.covariance.shape == (0, 2, 2)
    walk(tr, (0.0, 0.0), (1.0, 0.0), 3, rng, t0=26)
    assert tr.ids.tolist() == [1]


def crossing(tracker, rng, steps=120):
    """A walks +x along y=0 and B walks +y along x=0; A passes the crossing point 1.5 s
    before B. Returns the ids of the tracks nearest to A and B at every step."""
    seen = []
    for k in range(steps):
        t = k * DT
        a = np.array([-4.0 + 1.0 * t, 0.0])
        b = np.array([0.0, -5.5 + 1.0 * t])
        order = [1, 0] if k % 2 else [0, 1]  # detection order must not matter
        truth = np.array([a, b])[order]
        xy = truth + rng.normal(0.0, STD, (2, 2))
        tracker.step(DT, xy, np.array([0.0, np.pi / 2])[order], np.full(2, STD))
        d = np.linalg.norm(tracker.xy[:, None] - np.array([a, b])[None], axis=-1)
        seen.append(tracker.ids[d.argmin(axis=0)].tolist())
    return seen


def test_two_people_crossing_keep_ids():
    tr = KalmanTracker()
    seen = crossing(tr, np.random.default_rng(3))
    assert all(s == [0, 1] for s in seen)
    assert tr.next_id == 2


def test_head_on_passing_keeps_ids():
    rng = np.random.default_rng(4)
    tr = KalmanTracker()
    for k in range(80):  # pass at 0.8 m lateral distance at t = 4 s
        a = np.array([-4.0 + 1.0 * k * DT, 0.4])
        b = np.array([4.0 - 1.0 * k * DT, -0.4])
        tr.step(DT, np.array([a, b]) + rng.normal(0.0, STD, (2, 2)), [0.0, np.pi], [STD, STD])
        assert tr.ids.tolist() == [0, 1]
        assert np.linalg.norm(tr.xy - [a, b], axis=1).max() < 0.4


def test_far_detection_is_not_associated():
    tr = KalmanTracker(TrackerConfig(reacquire_gate=0.0))
    tr.step(DT, *one((0.0, 0.0)))
    tr.step(DT, *one((2.0, 0.0)))  # beyond max_distance
    assert tr.ids.tolist() == [0, 1] and tr.matched.tolist() == [False, True]
    tr = KalmanTracker(TrackerConfig(reacquire_gate=0.0))
    tr.step(DT, *one((0.0, 0.0)))
    tr.step(0.0, *one((0.6, 0.0)))  # within max_distance, d2 = 0.36 / 0.02 = 18 > gate
    assert tr.ids.tolist() == [0, 1]
    np.testing.assert_array_equal(tr.xy, [[0.0, 0.0], [0.6, 0.0]])


def test_reacquire_gate_catches_leftovers_only():
    tr = KalmanTracker()  # reacquire_gate 25 > 18
    tr.step(DT, *one((0.0, 0.0)))
    tr.step(0.0, *one((0.6, 0.0)))
    assert tr.ids.tolist() == [0] and tr.detection.tolist() == [0]
    tr = KalmanTracker()
    tr.step(DT, *one((0.0, 0.0)))
    tr.step(0.0, np.array([[0.1, 0.0], [0.6, 0.0]]), np.zeros(2), np.full(2, STD))
    assert tr.ids.tolist() == [0, 1] and tr.detection.tolist() == [0, 1]


def test_assignment_is_global_not_greedy():
    tr = KalmanTracker(TrackerConfig(reacquire_gate=0.0))
    std = np.full(2, 0.2)
    tr.step(DT, np.array([[0.0, 0.0], [0.6, 0.0]]), np.zeros(2), std)
    # Detection 0 is nearest to track 1, but only A<-0, B<-1 pairs both.
    tr.step(0.0, np.array([[0.35, 0.0], [0.95, 0.0]]), np.zeros(2), std)
    assert tr.ids.tolist() == [0, 1] and tr.detection.tolist() == [0, 1]
    assert tr.matched.all() and tr.next_id == 2


def test_empty_inputs():
    tr = KalmanTracker()
    assert tr.step(DT, *none()) == 0
    assert tr.step(DT, [], [], []) == 0
    assert tr.step(0.0, np.zeros((0, 2)), [], 0.1) == 0
    t = tr.tracks()
    assert isinstance(t, Tracks) and all(len(a) == 0 for a in t)
    assert t.xy.shape == (0, 2) and t.covariance.shape == (0, 2, 2) and t.ids.dtype == np.int64
    tr.step(DT, *one((1.0, 2.0)))
    assert tr.step(DT, *none()) == 1 and tr.ids.tolist() == [0]


def test_capacity_refuses_new_tracks():
    tr = KalmanTracker(TrackerConfig(max_tracks=3, timeout=0.25))
    xy = np.array([[0.0, 0.0], [3.0, 0.0], [6.0, 0.0], [9.0, 0.0], [12.0, 0.0]])
    assert tr.step(DT, xy, np.zeros(5), np.full(5, STD)) == 3
    assert tr.ids.tolist() == [0, 1, 2] and tr.refused == 2 and tr.last_refused == 2
    assert tr.detection.tolist() == [0, 1, 2]
    tr.step(DT, xy, np.zeros(5), np.full(5, STD))
    assert tr.ids.tolist() == [0, 1, 2] and tr.refused == 4
    for _ in range(3):
        tr.step(DT, xy[3:], np.zeros(2), np.full(2, STD))
    assert tr.ids.tolist() == [3, 4] and tr.detection.tolist() == [0, 1]


def test_many_detections_grow_the_workspace():
    tr = KalmanTracker(TrackerConfig(max_tracks=4))
    xy = np.stack([np.arange(10) * 3.0, np.zeros(10)], axis=1)
    assert tr.step(DT, xy, np.zeros(10), np.full(10, STD)) == 4
    assert tr.step(DT, xy, np.zeros(10), np.full(10, STD)) == 4
    assert tr.ids.tolist() == [0, 1, 2, 3] and tr.refused == 12


def random_run(tracker, seed, steps=200, people=12):
    """People walking in a 6 m room with noisy detections, misses and varying dt."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(0, 6, (people, 2))
    v = rng.normal(0, 0.8, (people, 2))
    snaps = []
    for _ in range(steps):
        dt = float(rng.choice([0.0, 0.05, 0.1, 0.2]))
        p += v * dt
        v[(p < 0) | (p > 6)] *= -1
        keep = rng.random(people) > 0.1
        std = rng.uniform(0.0, 0.2, keep.sum())
        xy = p[keep] + rng.normal(0, 1, (keep.sum(), 2)) * std[:, None]
        tracker.step(dt, xy, rng.uniform(-4, 4, keep.sum()), std)
        snaps.append(tuple(a.copy() for a in tracker.tracks()))
    return snaps


def test_covariance_symmetric_positive_definite():
    tr = KalmanTracker()
    for snap in random_run(tr, 5):
        t = Tracks(*snap)
        np.testing.assert_array_equal(t.covariance, t.covariance.transpose(0, 2, 1))
        if len(t.ids):
            assert np.linalg.eigvalsh(t.covariance).min() > 0.0
    full = tr.state_covariance
    np.testing.assert_array_equal(full, full.transpose(0, 2, 1))
    assert np.linalg.eigvalsh(full).min() > 0.0


def test_deterministic():
    a = random_run(KalmanTracker(), 6)
    b = random_run(KalmanTracker(), 6)
    for sa, sb in zip(a, b):
        for xa, xb in zip(sa, sb):
            np.testing.assert_array_equal(xa, xb)
            assert xa.dtype == xb.dtype


def test_reset_restarts_ids():
    tr = KalmanTracker()
    random_run(tr, 7, steps=20)
    tr.reset()
    assert len(tr) == 0 and tr.next_id == 0 and tr.refused == 0
    tr.step(DT, *one((0.0, 0.0)))
    assert tr.ids.tolist() == [0]


def test_zero_dt_does_not_predict():
    rng = np.random.default_rng(8)
    tr = KalmanTracker()
    walk(tr, (0.0, 0.0), (1.0, 1.0), 10, rng)
    state = [a.copy() for a in (tr.xy, tr.velocity, tr.covariance, tr.age)]
    tr.step(0.0, *none())
    for a, b in zip(state, (tr.xy, tr.velocity, tr.covariance, tr.age)):
        np.testing.assert_array_equal(a, b)
    assert tr.time_since_update[0] == 0.0


def test_new_track_initial_state():
    tr = KalmanTracker(TrackerConfig(init_velocity_std=0.7))
    tr.step(DT, *one((1.0, 2.0), yaw=4.0, std=0.3))
    np.testing.assert_array_equal(tr.xy, [[1.0, 2.0]])
    np.testing.assert_array_equal(tr.velocity, [[0.0, 0.0]])
    np.testing.assert_allclose(tr.state_covariance[0], np.diag([0.09, 0.09, 0.49, 0.49]))
    assert tr.yaw[0] == pytest.approx(4.0 - 2 * np.pi)
    assert tr.age[0] == 0.0 and tr.matched[0] and tr.detection[0] == 0


def test_zero_std_detection_is_accepted():
    tr = KalmanTracker()
    tr.step(DT, *one((1.0, 2.0), std=0.0))
    tr.step(0.0, *one((1.0, 2.0), std=0.0))
    assert tr.ids.tolist() == [0] and np.linalg.eigvalsh(tr.covariance[0]).min() > 0.0


def test_yaw_blends_circularly():
    tr = KalmanTracker(TrackerConfig(yaw_smoothing=0.5))
    tr.step(DT, *one((0.0, 0.0), yaw=3.1))
    tr.step(0.0, *one((0.0, 0.0), yaw=-3.1))
    assert abs(abs(tr.yaw[0]) - np.pi) < 1e-9  # halfway across pi, not through 0
    tr = KalmanTracker(TrackerConfig(yaw_smoothing=1.0))
    tr.step(DT, *one((0.0, 0.0), yaw=0.3))
    tr.step(DT, *one((0.0, 0.0), yaw=-2.0))
    assert tr.yaw[0] == pytest.approx(-2.0)


def test_heading_from_velocity():
    rng = np.random.default_rng(9)
    tr = KalmanTracker(TrackerConfig(min_speed_for_heading=0.5))
    out = walk(tr, (0.0, 0.0), (0.0, -1.0), 40, rng)  # detections report yaw -pi/2 ...
    tr.step(DT, *one(out[-1][0] + (0.0, -0.1), yaw=1.0))  # ... then a wrong one
    assert tr.yaw[0] == pytest.approx(np.arctan2(tr.velocity[0, 1], tr.velocity[0, 0]))
    assert abs(tr.yaw[0] + np.pi / 2) < 0.2


def test_min_hits_delays_reporting():
    tr = KalmanTracker(TrackerConfig(min_hits=3))
    far = np.array([[10.0, 0.0]])
    assert tr.step(DT, *one((0.0, 0.0))) == 0
    assert tr.num_live == 1 and tr.ids.shape == (0,)
    assert tr.step(0.0, *one((0.0, 0.0))) == 0
    tr.step(0.0, np.array([[0.0, 0.0], [10.0, 0.0]]), np.zeros(2), np.full(2, STD))
    assert tr.ids.tolist() == [0] and tr.num_live == 2
    assert tr.detection.tolist() == [0]
    tr.step(0.0, far, [0.0], [STD])
    tr.step(0.0, far, [0.0], [STD])
    assert tr.ids.tolist() == [0, 1]


def test_views_are_read_only():
    tr = KalmanTracker()
    tr.step(DT, *one((0.0, 0.0)))
    for arr in tr.tracks():
        with pytest.raises(ValueError):
            arr[...] = 0


def test_bad_inputs_raise_and_leave_state_unchanged():
    tr = KalmanTracker()
    tr.step(DT, *one((0.0, 0.0)))
    before = [a.copy() for a in tr.tracks()]
    bad = [
        (DT, np.array([[np.nan, 0.0]]), [0.0], [STD]),
        (DT, np.array([[0.0, 0.0]]), [np.inf], [STD]),
        (DT, np.array([[0.0, 0.0]]), [0.0], [-1.0]),
        (-0.1, np.array([[0.0, 0.0]]), [0.0], [STD]),
        (np.nan, np.array([[0.0, 0.0]]), [0.0], [STD]),
        (DT, np.zeros((2, 3)), np.zeros(2), np.zeros(2)),
        (DT, np.zeros((2, 2)), np.zeros(3), np.zeros(2)),
    ]
    for args in bad:
        with pytest.raises(ValueError):
            tr.step(*args)
    for a, b in zip(before, tr.tracks()):
        np.testing.assert_array_equal(a, b)


def test_config_validation_and_specs():
    assert TrackerConfig.from_spec(None) == PRESETS["default"] == TrackerConfig()
    assert TrackerConfig.from_spec("default") == TrackerConfig()
    cfg = TrackerConfig.from_spec({"preset": "default", "gate": 13.8, "max_tracks": 8})
    assert cfg.gate == 13.8 and cfg.max_tracks == 8
    assert KalmanTracker({"timeout": 2.0}).config.timeout == 2.0
    with pytest.raises(InputError, match=r"tracker\.gait"):
        TrackerConfig.from_spec({"gait": 1.0}, path="tracker")
    with pytest.raises(InputError):
        TrackerConfig.from_spec("nope")
    for bad in [
        {"accel_noise_std": -1.0}, {"init_velocity_std": 0.0}, {"gate": 0.0},
        {"gate": float("inf")}, {"max_distance": 0.0}, {"timeout": float("nan")},
        {"max_tracks": 0}, {"max_tracks": 2.5}, {"max_tracks": True}, {"yaw_smoothing": 0.0},
        {"yaw_smoothing": 1.5}, {"min_speed_for_heading": -0.1}, {"min_hits": 0},
        {"reacquire_gate": -1.0},
    ]:  # fmt: skip
        with pytest.raises(ValueError):
            dataclasses.replace(TrackerConfig(), **bad)
    assert TrackerConfig(max_distance=float("inf")).max_distance == float("inf")


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 8), st.integers(0, 6))
def test_invariants_on_random_scenes(seed, cap, people):
    rng = np.random.default_rng(seed)
    tr = KalmanTracker(TrackerConfig(max_tracks=cap, timeout=0.3))
    seen = -1
    for _ in range(30):
        D = int(rng.integers(0, people + 1))
        xy = rng.uniform(-3, 3, (D, 2))
        tr.step(float(rng.choice([0.0, 0.1, 0.3])), xy, rng.uniform(-9, 9, D),
                rng.uniform(0.0, 0.3, D))  # fmt: skip
        ids, det = tr.ids, tr.detection
        assert len(ids) <= cap and len(np.unique(ids)) == len(ids)
        assert np.all(np.diff(ids) > 0) and (len(ids) == 0 or ids.max() < tr.next_id)
        assert seen <= tr.next_id - 1
        seen = tr.next_id - 1
        assert np.all((det >= -1) & (det < D)) and np.array_equal(det >= 0, tr.matched)
        used = det[det >= 0]
        assert len(np.unique(used)) == len(used)
        assert np.all(np.abs(tr.yaw) <= np.pi) and np.all(tr.time_since_update <= 0.3)
        assert len(used) + tr.last_refused <= D
