"""People who see the robot: the time-to-collision repulsion and turn-taking at doors."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401  (registers the ids)
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.scenarios.routes import DOOR_WIDTH, route_graph
from srpb_gym.sim import social_force as sf
from srpb_gym.sim.crowd import Crowd, SocialForceConfig
from srpb_gym.sim.layout import PersonLayout

DT = 0.1
K, TAU0, FMAX = 1.5, 3.0, 10.0


# ------------------------------------------------------------------ the power law
def ttc_energy(x, v, rsum):
    """k tau^-2 exp(-tau / tau0) of a body at offset x, relative velocity v (0: no collision)."""
    a, b, c = v @ v, x @ v, x @ x - rsum * rsum
    disc = b * b - a * c
    if b >= 0 or disc <= 0:
        return 0.0
    tau = (-b - math.sqrt(disc)) / a
    return K * math.exp(-tau / TAU0) / tau**2


@pytest.mark.parametrize("x, v", [((2.0, 0.3), (-1.0, 0.0)), ((1.5, -0.2), (-0.6, 0.25)),
                                  ((-1.0, 1.2), (0.5, -1.1))])  # fmt: skip
def test_ttc_force_is_minus_the_gradient_of_the_energy(x, v):
    x, v = np.array(x), np.array(v)
    fx, fy = sf._ttc(*x, *v, 0.55, K, TAU0, 1e9)
    h = 1e-6
    grad = [(ttc_energy(x + h * e, v, 0.55) - ttc_energy(x - h * e, v, 0.55)) / (2 * h)
            for e in np.eye(2)]  # fmt: skip
    assert (fx, fy) == pytest.approx((-grad[0], -grad[1]), rel=1e-5)


def test_ttc_force_head_on_brakes_and_is_capped():
    fx, fy = sf._ttc(1.0, 0.0, -1.0, 0.0, 0.55, K, TAU0, FMAX)  # 0.45 m gap at 1 m/s
    assert fx == pytest.approx(FMAX) and fy == 0.0  # straight back, at the cap
    fx, fy = sf._ttc(4.0, 0.0, -1.0, 0.0, 0.55, K, TAU0, FMAX)
    assert 0.0 < fx < FMAX and fy == 0.0


@pytest.mark.parametrize("x, v", [((1.0, 0.0), (1.0, 0.0)), ((1.0, 0.0), (0.0, 0.0)),
                                  ((2.0, 1.0), (-1.0, 0.0))])  # fmt: skip
def test_no_ttc_force_moving_apart_standing_or_passing_clear(x, v):
    assert sf._ttc(*x, *v, 0.55, K, TAU0, FMAX) == (0.0, 0.0)


def test_ttc_force_pushes_overlapping_bodies_apart():
    fx, fy = sf._ttc(0.0, 0.3, 0.0, 0.0, 0.55, K, TAU0, FMAX)
    assert (fx, fy) == (0.0, FMAX)


# ------------------------------------------------------------------ walkers and a robot
def walk_at(robot_xy, robot_vel, config=None, steps=120, speed=1.2):
    """A walker from (0, 0) to (10, 0) meeting a robot (radius 0.3) at ``robot_xy`` moving
    at ``robot_vel``; returns the smallest gap between their bodies [m] and the crowd."""
    crowd = Crowd(config)
    walker = PersonLayout(position=(0.0, 0.0), yaw=0.0, route=((10.0, 0.0),),
                          preferred_speed=speed, radius=0.25)  # fmt: skip
    crowd.reset([walker], [], np.zeros((0, 4)))
    return run_with_robot(crowd, robot_xy, robot_vel, steps), crowd


def run_with_robot(crowd, robot_xy, robot_vel, steps, drive=None):
    """Step a crowd of one walker beside a robot (radius 0.3) from ``robot_xy`` at
    ``robot_vel``; ``drive(robot_xy, walker_xy, robot_vel)`` may set the robot's velocity
    before each step. Returns the smallest gap between their bodies [m]."""
    rxy = np.array([robot_xy], dtype=np.float64)
    rvel = np.array([robot_vel], dtype=np.float64)
    pos, gap = crowd.position.copy(), math.inf
    for k in range(steps):
        if drive is not None:
            drive(rxy[0], pos[0], rvel[0])
        v = crowd.desired_velocity(k * DT, DT, rxy, rvel, np.array([0.3])).copy()
        pos += v * DT
        rxy += rvel * DT
        crowd.sync(pos, v)
        gap = min(gap, float(np.hypot(*(pos[0] - rxy[0]))) - 0.55)
    return gap


@pytest.mark.parametrize("offset", [0.0, 0.05, -0.15, 0.3])
def test_a_walker_keeps_clear_of_a_parked_robot_on_its_line(offset):
    gap, crowd = walk_at((4.0, offset), (0.0, 0.0))
    assert gap > 0.05
    assert crowd.position[0, 0] > 8.0  # and walks on past it


def test_a_walker_keeps_clear_of_a_slow_robot_coming_at_it():
    gap, _ = walk_at((5.0, 0.02), (-0.15, 0.0))
    assert gap > 0.05


@pytest.mark.parametrize("robot", [((4.0, 0.0), (0.0, 0.0)), ((5.0, 0.02), (-0.15, 0.0))])
def test_stopping_instead_of_backing_away_still_keeps_clear(robot):
    close_only = SocialForceConfig(robot_backing_gap=0.3)
    gap, crowd = walk_at(*robot, close_only)
    assert gap > 0.05 and crowd.position[0, 0] > 8.0
    assert crowd.pushed_back[0] == 0.0


def test_without_the_ttc_term_a_walker_comes_closer():
    with_ttc, _ = walk_at((4.0, 0.05), (0.0, 0.0))
    without, _ = walk_at((4.0, 0.05), (0.0, 0.0), SocialForceConfig(robot_ttc_strength=0.0))
    assert without < with_ttc


@pytest.mark.parametrize("backing_gap", [math.inf, 0.3])
def test_an_invisible_robot_is_walked_into(backing_gap):
    config = SocialForceConfig(robot_reaction=0.0, robot_backing_gap=backing_gap)
    gap, _ = walk_at((4.0, 0.0), (0.0, 0.0), config)
    assert gap < 0.0


@pytest.mark.parametrize("env_id", SCENARIO_IDS)
def test_a_parked_robot_is_never_touched(env_id):
    """The full count (100 episodes each) is benchmarks/people.py; here 10 seeds each."""
    env = gym.make(env_id)
    action = np.zeros(env.action_space.shape, np.float32)
    for seed in range(3_000_000, 3_000_010):
        env.reset(seed=seed)
        done = False
        while not done:
            _, _, term, trunc, info = env.step(action)
            assert not info["collision"], f"{env_id} seed {seed} t={info['t']:.1f}"
            done = term or trunc
            assert ("people_pushed_back" in info) == done  # the last info only
        pushed = env.unwrapped.sim.crowd.pushed_back
        assert info["people_pushed_back"] == pushed.max(initial=0.0) >= 0.0
    env.close()


# ------------------------------------------------------------------ doors
WALLS = np.array([[6.0, 0.0, 6.0, 3.5], [6.0, 4.5, 6.0, 8.0]])  # a 1 m door at y 3.5-4.5


def test_the_route_graph_finds_the_door():
    graph = route_graph((0.0, 0.0, 12.0, 8.0), WALLS, (), 0.25, 0.05)
    assert graph.doors.shape == (1, 6)
    cx, cy, nx, ny, hw, hd = graph.doors[0]
    assert (cx, cy, abs(nx), ny, hw, hd) == pytest.approx((6.0, 4.0, 1.0, 0.0, 0.5, 0.0))
    wide = np.array([[6.0, 0.0, 6.0, 3.0], [6.0, 3.0 + DOOR_WIDTH, 6.0, 8.0]])
    assert route_graph((0.0, 0.0, 12.0, 8.0), wide, (), 0.25, 0.05).doors.shape == (0, 6)


def door_crowd(people, robot_xy=None, robot_vel=(0.0, 0.0), steps=100, config=None):
    """People (layouts) walking through the door of WALLS, a robot (radius 0.3) driving at
    a constant velocity; per step the people's positions and waiting flags."""
    graph = route_graph((0.0, 0.0, 12.0, 8.0), WALLS, (), 0.25, 0.05)
    crowd = Crowd(config)
    crowd.reset(people, [], WALLS, None, graph.doors)
    rxy = np.zeros((0, 2)) if robot_xy is None else np.array([robot_xy], dtype=np.float64)
    rvel = np.array([robot_vel], dtype=np.float64)[: len(rxy)]
    pos, traj, waits = crowd.position.copy(), [], []
    for k in range(steps):
        v = crowd.desired_velocity(k * DT, DT, rxy, rvel, np.full(len(rxy), 0.3)).copy()
        pos += v * DT
        rxy += rvel * DT
        crowd.sync(pos, v)
        traj.append(pos.copy())
        waits.append(crowd.waiting.copy())
    return np.array(traj), np.array(waits)


def through(start, end, delay=0.0):
    """A walker from ``start`` to ``end`` through the door, as the route graph leads it:
    to a point before the door's middle, one after it, then its goal."""
    side = math.copysign(0.45, end[0] - 6.0)
    route = ((6.0 - side, 4.0), (6.0 + side, 4.0), end)
    return PersonLayout(position=start, yaw=0.0, route=route, preferred_speed=1.2,
                        radius=0.25, start_delay=delay)  # fmt: skip


def test_who_is_in_the_door_first_goes_the_other_waits_beside_it():
    first = through((7.2, 4.0), (1.0, 4.0))  # right to left, nearer the door
    second = through((4.3, 4.0), (11.0, 4.0))  # left to right
    traj, waits = door_crowd([first, second])
    assert not waits[:, 0].any()  # the first never waits
    assert waits[:, 1].any()
    # while the second waited it stood aside: beside the opening, not on its line
    waited = traj[np.nonzero(waits[:, 1])[0], 1]
    assert np.abs(waited[-5:, 1] - 4.0).max() > 0.5
    gap = np.hypot(*(traj[:, 0] - traj[:, 1]).T).min() - 0.5
    assert gap > 0.0  # they never touch
    assert traj[-1, 0, 0] < 3.0 and traj[-1, 1, 0] > 9.0  # both got through


def test_a_walker_follows_someone_going_its_way():
    lead = through((8.0, 4.0), (1.0, 4.0))
    follow = through((9.5, 4.0), (1.0, 5.0), delay=0.3)
    _, waits = door_crowd([lead, follow])
    assert not waits.any()


def test_a_walker_waits_while_a_robot_is_in_the_door():
    walker = through((8.5, 4.0), (1.0, 4.0))
    traj, waits = door_crowd([walker], robot_xy=(5.2, 4.0), robot_vel=(0.3, 0.0), steps=40)
    assert waits[:15, 0].any()
    robot_x = 5.2 + 0.3 * DT * np.arange(1, 41)
    gap = np.hypot(traj[:, 0, 0] - robot_x, traj[:, 0, 1] - 4.0).min() - 0.55
    assert gap > 0.0


def test_door_turn_taking_can_be_switched_off():
    first = through((7.2, 4.0), (1.0, 4.0))
    second = through((4.3, 4.0), (11.0, 4.0))
    _, waits = door_crowd([first, second], config=SocialForceConfig(door_approach=0.0))
    assert not waits.any()


# ------------------------------------------------------------------ backing away
CORRIDOR = np.array([[-20.0, 1.1, 20.0, 1.1], [-20.0, -1.1, 20.0, -1.1]])  # 2.2 m wide


def herded(config=None, steps=200, keep=1.6):
    """A walker from (0, 0.6) to (-15, 0.6) along a corridor meets a robot (radius 0.3)
    that drives at it at 0.5 m/s from (-4, 0.27) on the side the walker gives way to and,
    like a robot that minds personal space, stops while their centres are within
    ``keep``. Returns the crowd and the smallest gap between their bodies [m]."""
    crowd = Crowd(config)
    walker = PersonLayout(position=(0.0, 0.6), yaw=math.pi, route=((-15.0, 0.6),),
                          preferred_speed=1.0, radius=0.25)  # fmt: skip
    crowd.reset([walker], [], CORRIDOR)

    def drive(robot, person, vel):
        vel[0] = 0.5 if np.hypot(*(robot - person)) > keep else 0.0

    return crowd, run_with_robot(crowd, (-4.0, 0.27), (0.0, 0.0), steps, drive)


def test_pushed_back_is_the_distance_moved_back_while_a_robot_makes_it_back_away():
    crowd = Crowd()
    walker = PersonLayout(position=(0.0, 0.0), yaw=0.0, route=((10.0, 0.0),),
                          preferred_speed=1.0, radius=0.25)  # fmt: skip
    crowd.reset([walker], [], np.zeros((0, 4)))
    # a robot 0.35 m ahead, coming at 0.5 m/s, makes it back away; without one, moving
    # back (as a walker does for a moment where its route turns) is not being pushed
    moves = (((-0.1, 0.0), True, 0.1), ((0.05, 0.0), True, 0.1), ((-0.25, 0.0), False, 0.1),
             ((-0.2, 0.0), True, 0.3), ((0.0, 0.2), True, 0.3))  # fmt: skip
    for step, robot, expected in moves:
        rxy = crowd.position + np.array([[0.9, 0.0]]) if robot else np.zeros((0, 2))
        rvel = np.array([[-0.5, 0.0]])[: len(rxy)]
        crowd.desired_velocity(0.0, DT, rxy, rvel, np.full(len(rxy), 0.3))
        crowd.sync(crowd.position + np.array([step]), np.zeros((1, 2)))
        assert crowd.pushed_back[0] == pytest.approx(expected)


def test_a_robot_that_keeps_its_distance_herds_a_walker_unless_it_only_backs_off_close():
    crowd, _ = herded()  # the default: a robot pushes a walker back from any distance
    assert crowd.pushed_back[0] > 2.0
    assert crowd.position[0, 0] > 1.0  # walked back up the corridor
    crowd, gap = herded(SocialForceConfig(robot_backing_gap=0.3))
    assert crowd.pushed_back[0] < 0.1  # it stops for the robot instead
    assert gap > 0.05
    assert SocialForceConfig(robot_backing_gap=math.inf).robot_backing_gap == math.inf
    with pytest.raises(ValueError, match=">= 0"):
        SocialForceConfig(robot_backing_gap=-1.0)


def test_a_robot_that_drives_on_makes_a_close_walker_back_off():
    crowd, _ = herded(SocialForceConfig(robot_backing_gap=0.3), keep=0.0, steps=60)
    assert crowd.pushed_back[0] > 0.3  # backed away rather than be run over


def test_people_who_stop_for_robots_never_walk_into_one():
    """With ``robot_backing_gap``, a person's own velocity never closes on a robot by more
    than the gap leaves (less the robot's own closing): a robot that drives straight at its
    goal through the crowd is never hit by a person. (Without the rule, a walker squeezed
    between another person and the robot hit it in seed 17.)"""
    from srpb_gym.planners import knowledge_for, make_planner

    env = gym.make("SRPB-Crowd-v0", crowd={"robot_backing_gap": 0.3})
    base = env.unwrapped
    crowd, planner = base.sim.crowd, make_planner("go-to-goal")
    desired, worst = crowd.desired_velocity, [-math.inf]

    def checked(t, dt, rxy, rvel, rrad, walls=None, rng=None):
        pos = crowd.position.copy()
        v = desired(t, dt, rxy, rvel, rrad, walls, rng)
        off = pos - rxy[0, :2]
        dist = np.hypot(off[:, 0], off[:, 1])
        n = off / dist[:, None]
        own = -(v * n).sum(axis=1)  # each person's own closing speed
        closing = np.maximum(n @ rvel[0, :2], 0.0) * dt
        room = np.maximum(dist - crowd.radius - rrad[0] - sf.KEEP_OFF - closing, 0.0)
        worst[0] = max(worst[0], float((own * dt - room).max()))
        return v

    crowd.desired_velocity = checked
    for seed in range(20):
        obs, _ = env.reset(seed=seed)
        planner.reset(knowledge_for(planner, base.knowledge))
        done = False
        while not done:
            base.set_planning_time(0.001)
            action = planner.act(obs, knowledge_for(planner, base.knowledge))
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        assert info.get("collision_by") != "person", f"seed {seed}"
    assert worst[0] <= 1e-9
