"""The classical planners: registry, goal reaching on empty scenarios, the global planner's
paths, the DWA's collision checking, determinism, actions and what they may read."""

from __future__ import annotations

import inspect
import math
import re

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401 - registers the environments
from srpb_gym.perception.groups import detect_groups
from srpb_gym.perception.tracker import Tracks
from srpb_gym.planners import (
    DWA,
    PLANNERS,
    GlobalPlanner,
    Knowledge,
    SocialDWA,
    SocialForcePlanner,
    command_to_action,
    dwa,
    global_planner,
    grid,
    make_planner,
    recovery,
    reference,
    rollout,
    social_dwa,
    social_force,
)

CLASSICAL = ["dwa", "social-dwa", "social-force"]
IDS = {
    "corridor": "SRPB-Corridor-v0",
    "fformation": "SRPB-FFormation-v0",
    "doorway": "SRPB-Doorway-v0",
    "crowd": "SRPB-Crowd-v0",
}


def run(env: gym.Env, planner, seed: int, steps: int = 1000, options=None):
    """Actions, poses and the last info of an episode (at most ``steps`` steps)."""
    obs, info = env.reset(seed=seed, options=options)
    planner.reset(env.unwrapped.knowledge())
    actions, poses = [], [env.unwrapped.knowledge().pose.copy()]
    for _ in range(steps):
        action = planner.act(obs, env.unwrapped.knowledge())
        actions.append(action)
        obs, _, terminated, truncated, info = env.step(action)
        poses.append(env.unwrapped.knowledge().pose.copy())
        if terminated or truncated:
            break
    return np.array(actions), np.array(poses), info


def test_registry() -> None:
    assert set(PLANNERS) >= {"go-to-goal", "dwa", "social-dwa", "social-force"}
    assert PLANNERS["dwa"] is DWA and PLANNERS["social-dwa"] is SocialDWA
    assert PLANNERS["social-force"] is SocialForcePlanner
    assert isinstance(make_planner("social-dwa", {"w_psi": 1.0}), SocialDWA)
    with pytest.raises(KeyError):
        make_planner("no-such-planner")


@pytest.mark.parametrize("scenario", ["corridor", "fformation", "doorway"])
@pytest.mark.parametrize("name", CLASSICAL)
def test_reaches_goal_without_people(name: str, scenario: str) -> None:
    env = gym.make(IDS[scenario])
    _, _, info = run(env, make_planner(name), seed=3, options={"people": False})
    assert info["is_success"] and not info["collision"]


def test_global_path_through_the_door_clear_of_walls() -> None:
    env = gym.make(IDS["doorway"])
    env.reset(seed=0, options={"people": False})
    knowledge = env.unwrapped.knowledge()
    planner = GlobalPlanner()
    planner.reset(knowledge)
    path = planner.plan(knowledge)
    assert np.allclose(path[0], knowledge.pose[:2]) and np.allclose(path[-1], knowledge.goal[:2])
    assert np.all(np.hypot(*np.diff(path, axis=0).T) <= planner.config.spacing + 1e-9)
    # exact distance of every path point to every wall segment
    walls = knowledge.walls
    a, b = walls[None, :, :2], walls[None, :, 2:]
    ab = b - a
    u = np.clip(((path[:, None, :] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
    clearance = np.hypot(*(path[:, None, :] - (a + u[..., None] * ab)).transpose(2, 0, 1))
    assert clearance.min() >= knowledge.robot.radius
    crossing = np.flatnonzero(np.diff(np.sign(path[:, 0] - 6.0)) != 0)
    assert crossing.size == 1 and 3.525 < path[crossing[0], 1] < 4.475  # through the door


@pytest.mark.parametrize("name", CLASSICAL)
def test_does_not_drive_into_a_wall_ahead(name: str) -> None:
    """Facing the dividing wall 0.5 m away with the goal behind it: no driving into the
    wall, no collision, the safety margin kept (the way round is through the door)."""
    env = gym.make(IDS["doorway"])
    start = (5.45, 2.0, 0.0)
    options = {"people": False, "start": start, "goal": (10.0, 2.0, 0.0)}
    actions, poses, info = run(env, make_planner(name), seed=0, steps=40, options=options)
    assert not info["collision"]
    robot = env.unwrapped.knowledge().robot
    assert (5.95 - poses[:, 0]).min() >= robot.radius + robot.bumper + 0.03  # wall at x 5.95
    assert poses[:10, 0].max() <= start[0] + 0.02  # turns first, does not drive at it
    assert actions[0][0] <= 0.2


def test_dwa_rejects_trajectories_into_walls() -> None:
    """Every sample the DWA can choose from in front of a wall keeps clear of it."""
    env = gym.make(IDS["corridor"])
    env.reset(seed=0, options={"people": False, "start": (17.5, 1.1, 0.0)})
    knowledge = env.unwrapped.knowledge()
    planner = DWA()
    planner.reset(knowledge)
    v, w = planner.decide(knowledge)
    traj = planner._traj[(planner._vt == v) & (planner._wt == w)][0]
    assert np.all(traj[:, 0] <= 18.0 - knowledge.robot.radius - knowledge.robot.bumper)


@pytest.mark.parametrize("name", CLASSICAL)
def test_deterministic_and_in_action_space(name: str) -> None:
    env = gym.make(IDS["crowd"])
    first, _, _ = run(env, make_planner(name), seed=5, steps=60)
    second, _, _ = run(env, make_planner(name), seed=5, steps=60)
    assert np.array_equal(first, second)
    assert first.dtype == np.float32
    assert all(env.action_space.contains(a) for a in first)


@pytest.mark.parametrize("name", CLASSICAL)
def test_acts_on_knowledge_only(name: str) -> None:
    """The action depends on the Knowledge snapshot only (not on the observation or any
    other state of the environment)."""
    env = gym.make(IDS["crowd"])
    obs, _ = env.reset(seed=2)
    for _ in range(30):
        env.step(np.array([0.5, 0.0], np.float32))
    knowledge = env.unwrapped.knowledge()
    assert isinstance(knowledge, Knowledge)
    a, b = make_planner(name), make_planner(name)
    a.reset(knowledge)
    b.reset(knowledge)
    assert np.array_equal(a.act(obs, knowledge), b.act(None, knowledge))


@pytest.mark.parametrize(
    "module", [dwa, global_planner, grid, recovery, reference, rollout, social_dwa, social_force]
)
def test_no_ground_truth_access(module) -> None:
    source = inspect.getsource(module)
    forbidden = r"\bunwrapped\b|gt_record|(?<!srpb_gym)\.sim\b|\.crowd\b|\.world\b|people_xy"
    assert re.search(forbidden, source) is None


def test_detect_groups() -> None:
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 5.0], [9.0, 9.0], [9.5, 9.0], [9.0, 10.0]])
    vel = np.zeros_like(xy)
    vel[1] = (1.0, 0.0)  # walking: not a group member
    n = xy.shape[0]
    tracks = Tracks(np.arange(n), xy, vel, np.zeros(n), np.tile(0.01 * np.eye(2), (n, 1, 1)),
                    np.ones(n), np.zeros(n), np.ones(n, bool), np.zeros(n, np.int64))  # fmt: skip
    members, start, size = detect_groups(tracks)
    assert members.tolist() == [3, 4, 5] and start.tolist() == [0] and size.tolist() == [3]


def test_social_costs_grow_towards_people() -> None:
    """The social DWA's cost of heading straight at a standing pair exceeds that of
    passing them wide."""
    env = gym.make(IDS["fformation"])
    env.reset(seed=0, options={"start": (5.6, 1.85, 0.0)})  # 2.3 m before the pair, facing it
    for _ in range(15):  # tracks settle
        env.step(np.zeros(2, np.float32))
    knowledge = env.unwrapped.knowledge()
    assert knowledge.tracks.xy.shape[0] >= 2
    planner = SocialDWA()
    planner.reset(knowledge)
    planner._perceive_groups(knowledge.tracks, knowledge.t)
    centre = knowledge.tracks.xy.mean(axis=0)
    x, y = knowledge.pose[:2]
    steps = np.linspace(0.1, 1.0, planner._steps)[None, :]
    heading = math.atan2(centre[1] - y, centre[0] - x)
    traj = np.zeros((2, planner._steps, 4))
    for i, offset in enumerate((0.0, 2.5)):  # towards the pair; towards a point beside it
        target = centre + np.array([0.0, offset])
        traj[i, :, 0] = x + steps * (target[0] - x)
        traj[i, :, 1] = y + steps * (target[1] - y)
        traj[i, :, 2], traj[i, :, 3] = heading, 0.5
    cost = planner._social_costs(knowledge, traj)
    assert cost[0] > cost[1] >= 0.0


def wall_clearance(points: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """Exact distance [m] of each point (N, 2) to the nearest wall segment."""
    a, b = walls[None, :, :2], walls[None, :, 2:]
    ab = b - a
    u = np.clip(((points[:, None, :] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
    return np.hypot(*(points[:, None, :] - (a + u[..., None] * ab)).transpose(2, 0, 1)).min(1)


@pytest.mark.parametrize("seed", [0, 1])
def test_dwa_drives_a_large_robot(seed: int) -> None:
    """The robot's size comes from its config: a 0.45 m robot reaches the goal without a
    collision, its global planner inflates the walls by 0.45 m plus bumper and margin,
    and path and trajectory keep at least 0.45 m from every wall."""
    env = gym.make(IDS["corridor"], robot={"radius": 0.45})
    env.reset(seed=seed, options={"people": False})
    knowledge = env.unwrapped.knowledge()
    robot = knowledge.robot
    assert robot.radius == 0.45
    planner = make_planner("dwa")
    planner.reset(knowledge)
    gp = planner.planner
    assert gp.robot_radius == robot.radius + robot.bumper
    lethal = robot.radius + robot.bumper + gp.config.margin
    cost, dist = gp.static_cost.ravel(), gp.dist.ravel()
    cells = np.arange(cost.shape[0]) != gp.cell(*knowledge.goal[:2])  # the goal: reachable
    assert np.all(cost[cells & (dist < lethal)] >= gp.config.lethal_cost)
    assert np.all(cost[cells & (dist > lethal)] < gp.config.lethal_cost)
    assert np.any((dist > 0.3) & (dist < 0.45))  # lethal for this robot, not a default one
    path = gp.plan(knowledge)
    assert wall_clearance(path, knowledge.walls).min() >= robot.radius

    _, poses, info = run(env, planner, seed=seed, options={"people": False})
    assert info["is_success"] and not info["collision"]
    assert wall_clearance(poses[:, :2], knowledge.walls).min() >= robot.radius


def test_command_to_action_of_a_base_that_cannot_reverse() -> None:
    from srpb_gym.sim.robot import RobotConfig

    robot = RobotConfig(v_min=0.0)
    assert command_to_action(-0.1, 0.0, 0.0, robot).tolist() == [0.0, 0.0]
    assert command_to_action(-0.05, 0.0, 0.0, RobotConfig()).tolist() == [-0.5, 0.0]
