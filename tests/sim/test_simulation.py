"""The step pipeline: determinism, records, groups, several robots, options."""

from __future__ import annotations

import math

import numpy as np
import pytest

from srpb_gym.metrics import evaluate
from srpb_gym.perception.detector import DetectorConfig
from srpb_gym.sim.layout import EpisodeLayout, FormationLayout, PersonLayout, RobotLayout
from srpb_gym.simulation import SimConfig, Simulation

WALLS = np.array([[0, -2.0, 14, -2.0], [0, 2.0, 14, 2.0], [0, -2.0, 0, 2.0], [14, -2.0, 14, 2.0]])


def layout(robots=((1.0, 0.0, 0.0),), formation=True) -> EpisodeLayout:
    people = (
        PersonLayout((12.0, 0.8), math.pi, ((2.0, 0.8),)),
        PersonLayout((13.0, -0.8), math.pi, ((2.0, -0.8),), start_delay=2.0),
    )
    forms = (FormationLayout((8.0, 1.0), ((8.0, 0.4), (8.0, 1.6))),) if formation else ()
    goals = [(13.0, 0.0, 0.0)] * len(robots)
    return EpisodeLayout(
        WALLS, tuple(RobotLayout(s, g) for s, g in zip(robots, goals)), people, forms
    )


def run(sim: Simulation, seed: int, steps: int = 60, lay: EpisodeLayout | None = None):
    sim.reset(lay or layout(), np.random.default_rng(seed))
    for k in range(steps):
        sim.step(np.tile([0.4, 0.0, 0.2 * math.sin(k / 7)], (sim.n_robots, 1)), 0.002)
    return sim


def test_same_seed_same_episode_bit_for_bit():
    a, b = run(Simulation(), 3), run(Simulation(), 3)
    ra, rb = a.robots[0].record, b.robots[0].record
    assert ra.n_samples == 61
    for name in ("robot", "people", "people_id", "people_sample", "group_members"):
        assert np.array_equal(getattr(ra, name), getattr(rb, name), equal_nan=True), name
    assert np.array_equal(a.robots[0].scan, b.robots[0].scan)
    c = run(Simulation(), 4)
    assert not np.array_equal(ra.people, c.robots[0].record.people)


def test_reset_rebuilds_the_world():
    sim = Simulation()
    first = run(sim, 5).robots[0].record.robot.copy()
    again = run(sim, 5).robots[0].record.robot
    assert np.array_equal(first, again, equal_nan=True)


def test_records_hold_the_episode():
    sim = run(Simulation(), 0, steps=30)
    rec, gt = sim.robots[0].record, sim.robots[0].gt_record
    t = rec.robot_col("t")
    assert t == pytest.approx(np.arange(31) * 0.1)
    pt = rec.robot_col("planning_time")
    assert np.all(pt[:-1] == 0.002) and math.isnan(pt[-1])  # no decision at the last sample
    assert np.array_equal(rec.robot, gt.robot, equal_nan=True)
    # ground truth: every person at every sample, exact, with zero covariance
    assert gt.people.shape[0] == 31 * 4
    assert np.all(gt.people[:, 3:7] == 0.0)
    # the first sample's speed is zero, later ones follow the command's ramp
    assert rec.robot_col("vx")[0] == 0.0 and rec.robot_col("vx")[5] > 0.3
    values = evaluate(rec)
    assert values["m_mef"] == pytest.approx(3.0) and values["m_cef"] == pytest.approx(2.0)


def test_groups_seen_only_with_two_tracked_members():
    sim = Simulation(detector=DetectorConfig.from_spec("camera"))
    run(sim, 1, steps=40)
    rec, gt = sim.robots[0].record, sim.robots[0].gt_record
    assert np.all(gt.group_size == 2) and gt.group_sample.shape[0] == 41
    ids = rec.people_id[rec.group_members]
    assert np.all(rec.group_size >= 2)
    # each tracked member is a distinct track of the group's own sample
    assert np.all(
        rec.people_sample[rec.group_members] == np.repeat(rec.group_sample, rec.group_size)
    )
    assert len(np.unique(ids)) >= 2


def test_two_robots_see_each_other():
    lay = layout(robots=((3.0, 0.0, 0.0), (4.5, 0.0, math.pi)), formation=False)
    sim = Simulation()
    sim.reset(lay, np.random.default_rng(0))
    ahead = sim.robots[0].lidar.n_beams // 2  # the beam straight ahead
    gap = 1.5 - 0.275  # to the other robot's footprint, nearer than any wall (2 m)
    assert sim.robots[0].scan[ahead] == pytest.approx(gap, abs=0.05)
    assert sim.robots[1].scan[ahead] == pytest.approx(gap, abs=0.05)
    assert sim.obstacle_dist == pytest.approx([gap, gap], abs=1e-9)
    for _ in range(40):
        sim.step([[0.5, 0, 0], [0.5, 0, 0]])
    assert sim.collisions[:, 2].all()  # driving into each other
    assert sim.robots[0].record.n_samples == sim.robots[1].record.n_samples == 41
    gap = np.hypot(*np.subtract(*sim.world.robot_pose[:, :2]))
    assert gap >= 2 * 0.275 - 0.01


def test_crowd_every_substep_and_lidar_obstacle_distance():
    sim = Simulation(SimConfig(crowd_every_substep=True, obstacle_distance="lidar"))
    run(sim, 2, steps=20)
    rec = sim.robots[0].record
    od = rec.robot_col("obstacle_dist")
    assert np.all(od <= 25.0) and np.all(od > 0)
    assert od[-1] == pytest.approx(sim.robots[0].scan.min())


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"control_dt": 0.1, "physics_dt": 0.03}, "whole multiple"),
        ({"control_dt": 0.1, "physics_dt": 0.2}, "whole multiple"),
        ({"physics_dt": 0.0}, "> 0"),
        ({"obstacle_distance": "sonar"}, "obstacle_distance"),
    ],
)
def test_contradictory_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SimConfig(**kwargs)


def test_people_walk_their_routes_in_the_simulation():
    sim = run(Simulation(), 0, steps=150, lay=layout(robots=((1.0, -1.5, 0.0),), formation=False))
    xy = sim.world.people_xy
    assert xy[0] == pytest.approx([2.0, 0.8], abs=0.5)  # reached the end of its route


def test_simulation_from_scenario_uses_its_sensors():
    from srpb_gym.scenarios import load_scenario, sample

    scenario = load_scenario("crowd")
    sim = Simulation.from_scenario(scenario)
    assert sim.detector_config == DetectorConfig.from_spec("lidar")
    assert Simulation.from_scenario(load_scenario("corridor")).detector_config.fov < 1.1
    sim.reset(sample(scenario, np.random.default_rng(0)), np.random.default_rng(0))
    sim.step([[0.3, 0.0, 0.0]], 0.0)
    assert sim.robots[0].record.n_samples == 2


def test_holonomic_base_moves_sideways():
    from srpb_gym.sim.robot import RobotConfig

    sim = Simulation(robot=RobotConfig(kinematics="holonomic"))
    sim.reset(layout(robots=((4.0, 0.0, 0.0),), formation=False), np.random.default_rng(0))
    for _ in range(15):
        sim.step([[0.2, 0.2, 0.0]], 0.0)
    assert sim.velocity[0] == pytest.approx([0.2, 0.2, 0.0], abs=0.01)
    assert sim.world.robot_pose[0, 1] > 0.2
    diff = Simulation()
    diff.reset(layout(robots=((4.0, 0.0, 0.0),), formation=False), np.random.default_rng(0))
    for _ in range(15):
        diff.step([[0.2, 0.2, 0.0]], 0.0)
    assert abs(diff.velocity[0, 1]) < 1e-3  # a differential drive ignores vy


def expected_groups(persons, formation_of):
    """Formation ids, sizes and member rows of the formations with two or more rows."""
    forms = [formation_of[p] if p >= 0 else -1 for p in persons]
    gids = [f for f in sorted(set(forms) - {-1}) if forms.count(f) >= 2]
    members = [i for f in gids for i, g in enumerate(forms) if g == f]
    return gids, [forms.count(f) for f in gids], members


def test_each_sample_is_what_the_tracker_and_the_world_report(monkeypatch):
    # small tables and track memory, so that every way of growing them is taken
    monkeypatch.setattr(Simulation, "_reserve_records", lambda self: None)
    sim = Simulation(detector=DetectorConfig.from_spec("lidar"))
    lay = layout()
    sim.reset(lay, np.random.default_rng(7))
    state = sim.robots[0]
    state.track_person = np.full(1, -1, dtype=np.int64)
    followed: dict[int, int] = {}
    for k in range(120):
        sim.step([[0.3, 0.0, 0.3 * math.sin(k / 9)]], 0.001 * k)
        tracks, det_index = state.tracker.tracks(), state.detector.arrays[5]
        pose, v = sim.world.robot_pose[0], sim.velocity[0]
        robot_row = [sim.t, pose[0], pose[1], math.remainder(pose[2], 2 * math.pi), *v,
                     *state.goal, sim.obstacle_dist[0]]  # fmt: skip
        for tid, d in zip(tracks.ids, tracks.detection):
            if d >= 0:
                followed[int(tid)] = int(det_index[d])
        persons = [followed.get(int(tid), -1) for tid in tracks.ids]
        gids, sizes, members = expected_groups(persons, sim.crowd.formation_of)
        robot, people, ids, got_sizes, got_members = state.record.latest()
        assert robot[0, :11] == pytest.approx(robot_row, abs=1e-12) and math.isnan(robot[0, 11])
        assert state.record.robot[-2, 11] == 0.001 * k  # the decision's planning time
        rows = np.column_stack([tracks.xy, tracks.yaw, tracks.covariance.reshape(-1, 4),
                                tracks.velocity])  # fmt: skip
        np.testing.assert_array_equal(people, rows)
        np.testing.assert_array_equal(ids, tracks.ids)
        assert got_sizes.tolist() == sizes and got_members.tolist() == members
        assert state.record.group_id[len(state.record.group_id) - len(gids) :].tolist() == gids
        robot, people, ids, got_sizes, got_members = state.gt_record.latest()
        rows = np.zeros((sim.n_people, 9))
        rows[:, :2], rows[:, 2], rows[:, 7:] = (
            sim.world.people_xy,
            sim.crowd.yaw,
            sim.world.people_velocity,
        )
        np.testing.assert_array_equal(people, rows)
        np.testing.assert_array_equal(ids, np.arange(sim.n_people))
        assert got_sizes.tolist() == [2] and got_members.tolist() == [2, 3]
    assert state.record.n_samples == state.gt_record.n_samples == 121
    assert state.track_person.shape[0] > 1 and state.record.people.shape[0] > 256
    state.record.validate()
    state.gt_record.validate()
