"""Collisions attributed: what a robot touched, how fast both moved, who closed the gap."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from srpb_gym.sim.contact import CAUSES, KINDS, Collision, caused_by
from srpb_gym.sim.robot import RobotConfig
from srpb_gym.sim.world import World

CFG = RobotConfig()
BOX = np.array(
    [[-3.0, -3.0, 3.0, -3.0], [3.0, -3.0, 3.0, 3.0], [3.0, 3.0, -3.0, 3.0], [-3.0, 3.0, -3.0, -3.0]]
)


def _drive(world: World, commands, people_velocity, steps: int) -> list[tuple[int, int, Collision]]:
    """Step ``world`` with fixed world-frame ``commands`` (R, 3) and people velocities
    (P, 2); (step, robot, collision) of every step on which a collision began."""
    commands = np.asarray(commands, dtype=float).reshape(world.n_robots, 3)
    people_velocity = np.asarray(people_velocity, dtype=float).reshape(-1, 2)
    out = []
    for k in range(steps):
        world.clear_contacts()
        world.step(commands, people_velocity)
        for r in range(world.n_robots):
            if world.new_collisions[r]:
                assert world.new_collisions[r] == 1
                out.append((k, r, Collision.from_row(world.collision[r])))
    return out


def _world(robots, people=(), radius=0.25) -> World:
    people = np.asarray(people, dtype=float).reshape(-1, 2)
    return World(BOX, [(CFG, pose) for pose in robots], people, np.full(len(people), radius),
                 0.025, 4)  # fmt: skip


def test_a_robot_driving_into_a_standing_person_causes_it():
    world = _world([(0.0, 0.0, 0.0)], [(1.0, 0.0)])
    found = _drive(world, [0.5, 0.0, 0.0], [0.0, 0.0], 40)
    # it goes on pushing the person: one contact that lasts, one collision
    assert len(found) == 1 and world.collisions[0, 1]
    _, robot, c = found[0]
    assert (robot, c.kind, c.by) == (0, "person", "robot")
    assert c.robot_speed == pytest.approx(0.5) and c.robot_closing == pytest.approx(0.5)
    assert c.other_speed == 0.0 and c.other_closing == 0.0
    assert math.copysign(1.0, c.other_closing) == 1.0  # never -0.0


def test_a_person_walking_into_a_parked_robot_causes_it():
    world = _world([(0.0, 0.0, 0.0)], [(1.5, 0.05)])
    [(_, _, c)] = _drive(world, [0.0, 0.0, 0.0], [-1.0, 0.0], 20)
    assert (c.kind, c.by) == ("person", "person")
    assert c.robot_speed == 0.0 and c.robot_closing == 0.0
    assert math.copysign(1.0, c.robot_closing) == 1.0
    assert c.other_speed == pytest.approx(1.0)
    # off-centre by 5 cm: the person closes along the line between the centres
    assert 0.99 < c.other_closing < 1.0


def test_a_wall_collision_is_the_robots():
    world = _world([(2.0, 0.0, 0.0)])
    [(_, _, c)] = _drive(world, [0.5, 0.0, 0.0], np.zeros((0, 2)), 20)
    assert (c.kind, c.by) == ("wall", "robot")
    assert c.robot_closing == pytest.approx(0.5) and (c.other_speed, c.other_closing) == (0, 0)


def test_each_robot_of_a_robot_collision_sees_it_its_own_way():
    world = _world([(0.0, 0.0, 0.0), (1.2, 0.0, math.pi)])
    found = _drive(world, [[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]], np.zeros((0, 2)), 20)
    assert [(r, c.kind, c.by) for _, r, c in found] == [(0, "robot", "robot"),
                                                        (1, "robot", "other_robot")]  # fmt: skip
    assert found[0][0] == found[1][0]  # the same step
    mover, parked = found[0][2], found[1][2]
    assert mover.robot_closing == pytest.approx(parked.other_closing)
    assert mover.other_closing == pytest.approx(parked.robot_closing)
    assert parked.robot_speed == 0.0 and parked.other_speed == pytest.approx(0.5)


def test_a_contact_after_a_step_without_it_is_a_new_collision():
    world = _world([(2.0, 0.0, 0.0)])
    first = _drive(world, [0.5, 0.0, 0.0], np.zeros((0, 2)), 20)
    away = _drive(world, [-0.5, 0.0, 0.0], np.zeros((0, 2)), 5)
    again = _drive(world, [0.5, 0.0, 0.0], np.zeros((0, 2)), 10)
    assert (len(first), len(away), len(again)) == (1, 0, 1)
    assert again[0][2].kind == "wall"


def test_the_rule_and_the_info_keys():
    assert [CAUSES[caused_by(0, -1.0, 5.0)], CAUSES[caused_by(1, 0.2, 0.2)],
            CAUSES[caused_by(1, 0.1, 0.3)], CAUSES[caused_by(2, 0.1, 0.3)],
            CAUSES[caused_by(2, 0.0, 0.0)]] == ["robot", "robot", "person", "other_robot",
                                                "robot"]  # fmt: skip
    assert KINDS == ("wall", "person", "robot")
    c = Collision("person", "person", 0.0, 1.0, 0.0, 0.9)
    info = c.info("collision_")
    assert list(info) == ["collision_kind", "collision_by", "collision_robot_speed",
                          "collision_other_speed", "collision_robot_closing",
                          "collision_other_closing"]  # fmt: skip
    assert Collision.from_info(info, "collision_") == c
    assert Collision.from_info({}, "collision_") is None


def test_the_env_reports_a_person_walking_into_a_parked_robot():
    # people ignore the robot, which stands still: corridor seed 0, a collision after 18 s
    env = gym.make("SRPB-Corridor-v0", crowd={"robot_reaction": 0.0})
    _, info = env.reset(seed=0)
    steps = 0
    while True:
        _, _, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        steps += 1
        if terminated or truncated:
            break
        assert not any(k.startswith(("collision_", "first_collision_")) for k in info)
    env.close()
    assert terminated and info["collision"] and steps == 180
    step, first = (Collision.from_info(info, p) for p in ("collision_", "first_collision_"))
    assert step == first and info["collision_count"] == 1
    assert (first.kind, first.by, first.robot_speed, first.robot_closing) == (
        "person", "person", 0.0, 0.0)  # fmt: skip
    assert first.other_closing > 0.5
