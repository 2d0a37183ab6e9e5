"""Physics of the pymunk world: robots stop at walls, respect their limits, push people
but never through walls, and report their contacts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from srpb_gym.sim import geometry
from srpb_gym.sim.robot import (
    RobotConfig,
    body_to_world,
    limit_commands,
    measure_velocity,
)
from srpb_gym.sim.world import World

CFG = RobotConfig()
BOX = np.array(
    [[-2.0, -2.0, 2.0, -2.0], [2.0, -2.0, 2.0, 2.0], [2.0, 2.0, -2.0, 2.0], [-2.0, 2.0, -2.0, -2.0]]
)
NO_PEOPLE = np.zeros((0, 2))


class Driver:
    """Drives one robot of a world the way the simulation does."""

    def __init__(self, world: World, cfg: RobotConfig = CFG, dt: float = 0.1) -> None:
        self.world, self.cfg, self.dt = world, cfg, dt
        self.low, self.high = cfg.velocity_bounds
        self.acc = np.array([cfg.acc_lin, cfg.acc_lin, cfg.acc_ang])
        self.cmd = np.zeros((1, 3))
        self.world_cmd = np.zeros((1, 3))
        self.measured = np.zeros((1, 3))

    def step(self, target, people_velocity=NO_PEOPLE) -> None:
        target = np.asarray(target, dtype=float).reshape(1, 3)
        lateral = self.cfg.kinematics == "holonomic"
        limit_commands(target, self.cmd, self.low, self.high, self.acc, self.dt, lateral,
                       self.cmd)  # fmt: skip
        before = self.world.robot_pose.copy()
        body_to_world(self.cmd, before, self.dt, self.world_cmd)
        self.world.collisions[:] = False
        self.world.step(self.world_cmd, people_velocity)
        measure_velocity(before, self.world.robot_pose, self.dt, self.measured)


def wall_clearance(world: World, walls=BOX) -> float:
    x, y = world.robot_pose[0, :2]
    return geometry.point_obstacle_distance(x, y, walls, np.zeros((0, 3)), -1) - CFG.radius


def box_world(pose=(0.0, 0.0, 0.0), people=NO_PEOPLE, radius=None) -> World:
    radius = np.full(len(people), 0.25) if radius is None else radius
    return World(BOX, [(CFG, pose)], people, radius, 0.025, 4)


@pytest.mark.parametrize("seed", range(6))
def test_robot_never_penetrates_walls(seed):
    rng = np.random.default_rng(seed)
    world = box_world((rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-np.pi, np.pi)))
    drive = Driver(world)
    worst = np.inf
    for k in range(600):
        if k % 25 == 0:  # hold random (often saturated) commands for 2.5 s
            target = rng.uniform([-1, 0, -3], [2, 0, 3])
        drive.step(target)
        worst = min(worst, wall_clearance(world))
    assert worst > -0.01  # never more than 1 cm into a wall


def test_robot_stops_at_wall_and_reports_contact():
    world = box_world((0.0, 0.0, 0.0))
    drive = Driver(world)
    contacts = 0
    for _ in range(80):
        drive.step([0.5, 0.0, 0.0])
        contacts += world.collisions[0, 0]
    assert world.robot_pose[0, 0] == pytest.approx(2.0 - CFG.radius - CFG.bumper, abs=0.01)
    assert abs(drive.measured[0, 0]) < 1e-3  # blocked: it measures standing still
    assert contacts > 30
    assert not world.collisions[0, 1:].any()


def test_free_motion_follows_limits():
    world = box_world((0.0, -1.5, 0.0))
    drive = Driver(world)
    history = []
    for target in [[2.0, 0, 3.0]] * 15 + [[-2.0, 0, -3.0]] * 25:
        drive.step(target)
        history.append(drive.measured[0].copy())
    v = np.array(history)
    low, high = CFG.velocity_bounds
    assert np.all(v[:, 0] <= high[0] + 1e-3) and np.all(v[:, 0] >= low[0] - 1e-3)
    assert np.all(np.abs(v[:, 2]) <= CFG.w_max + 1e-3)
    assert np.all(np.abs(v[:, 1]) < 0.02)  # a differential drive does not slide sideways
    # the command ramps at the acceleration limits (measurement lags one substep)
    assert np.all(np.abs(np.diff(v[:, 0])) <= CFG.acc_lin * 0.1 + 0.02)
    assert np.all(np.abs(np.diff(v[:, 2])) <= CFG.acc_ang * 0.1 + 0.03)
    assert v[14, [0, 2]] == pytest.approx([0.5, 1.05], abs=0.01)
    assert v[-1, [0, 2]] == pytest.approx([-0.1, -1.05], abs=0.01)


def test_arc_measured_without_lateral_velocity():
    world = box_world((0.0, -1.0, 0.0))
    drive = Driver(world)
    for _ in range(20):
        drive.step([0.4, 0.0, 0.8])
    assert drive.measured[0] == pytest.approx([0.4, 0.0, 0.8], abs=0.02)


def test_limit_commands_clip_and_ramp():
    low, high = CFG.velocity_bounds
    acc = np.array([1.0, 1.0, 1.05])
    out = np.zeros((2, 3))
    limit_commands(
        np.array([[9.0, 1.0, -9.0], [-9.0, 0.0, 0.5]]),
        np.array([[0.45, 0.0, -1.0], [0.0, 0.0, 0.5]]),
        low,
        high,
        acc,
        0.1,
        False,
        out,
    )
    assert out[0] == pytest.approx([0.5, 0.0, -1.05])
    assert out[1] == pytest.approx([-0.1, 0.0, 0.5])


def test_robot_pushes_person_but_not_through_wall():
    # a person standing between the robot and the wall
    person = np.array([[1.4, 0.0]])
    world = box_world((0.0, 0.0, 0.0), person)
    drive = Driver(world)
    touched = False
    for _ in range(100):
        drive.step([0.5, 0.0, 0.0], np.zeros((1, 2)))
        touched |= bool(world.collisions[0, 1])
        px = world.people_xy[0, 0]
        assert px + 0.25 <= 2.0 + 0.01  # the person's body stays inside the room
    assert touched
    x = world.robot_pose[0, 0]
    assert x + CFG.radius <= world.people_xy[0, 0] - 0.25 + 0.015  # bodies do not overlap


def test_two_robots_collide():
    robots = [(CFG, (-1.0, 0.0, 0.0)), (CFG, (1.0, 0.0, math.pi))]
    world = World(BOX, robots, NO_PEOPLE, np.zeros(0), 0.025, 4)
    cmd = np.zeros((2, 3))
    seen = False
    for _ in range(60):
        pose = world.robot_pose
        body_to_world(np.array([[0.5, 0, 0], [0.5, 0, 0]]), pose, 0.1, cmd)
        world.collisions[:] = False
        world.step(cmd, NO_PEOPLE)
        seen |= bool(world.collisions[:, 2].all())
        gap = np.hypot(*(world.robot_pose[0, :2] - world.robot_pose[1, :2]))
        assert gap > 2 * CFG.radius - 0.01
    assert seen


def test_people_follow_their_velocity():
    world = box_world((0.0, -1.5, 0.0), np.array([[-1.0, 1.0]]))
    for _ in range(10):
        world.step(np.zeros((1, 3)), np.array([[0.8, 0.0]]))
    assert world.people_xy[0] == pytest.approx([-0.2, 1.0], abs=1e-6)


def test_robot_config_validation():
    with pytest.raises(ValueError, match="kinematics"):
        RobotConfig(kinematics="legs")
    with pytest.raises(ValueError, match="v_min"):
        RobotConfig(v_min=0.2)
    assert RobotConfig(kinematics="holonomic").action_dims == 3


def test_direct_calls_match_the_public_pymunk_functions():
    people = np.array([[1.0, 0.5], [-1.0, -0.5]])
    fast, public = (box_world((0.0, 0.0, 0.3), people) for _ in range(2))
    public._calls.direct = False  # pymunk.batch's get/set functions and Space.step
    cmd, walk = np.array([[0.4, 0.0, 0.5]]), np.array([[0.3, -0.2], [-0.5, 0.1]])
    for _ in range(20):
        fast.step(cmd, walk)
        public.step(cmd, walk)
        np.testing.assert_array_equal(fast.state, public.state)
