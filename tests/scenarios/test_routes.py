"""Walking routes around walls: the route graph, the routes the sampler draws, and walkers
that follow them through a door (crowd integrated with explicit Euler, no physics)."""

from __future__ import annotations

import itertools
import textwrap

import numpy as np

from srpb_gym.scenarios import parse_scenario, sample, validate
from srpb_gym.scenarios.routes import route_graph, segment_clearance
from srpb_gym.scenarios.schema import PLACEMENT_GAP
from srpb_gym.scenarios.space import crosses_walls
from srpb_gym.sim.crowd import STOPPED, Crowd

DOOR = (3.525, 4.475)  # the 0.95 m door in the wall from x = 5.95 to 6.05
TWO_ROOMS = textwrap.dedent("""\
    name: two_rooms
    time_limit: 60.0
    bounds: [0.0, 0.0, 12.0, 8.0]
    obstacles:
      - rectangle: [5.95, 0.0, 6.05, 3.525]
      - rectangle: [5.95, 4.475, 6.05, 8.0]
    robot:
      start: {position: [1.0, 3.0, 2.0, 5.0]}
      goal: {position: [10.0, 3.0, 11.0, 5.0]}
    people:
      - spawn: [7.5, 1.0, 11.5, 7.0]
        goal: [0.8, 1.0, 4.0, 7.0]
        count: [2, 4]
      - spawn: [0.8, 0.8, 4.0, 2.0]
        goal: [8.0, 6.0, 11.0, 7.0]
        loop: true
    """)


def two_rooms():
    return validate(parse_scenario(TWO_ROOMS, "two_rooms.yaml"), trials=0)


def door_crossing(path: np.ndarray) -> float | None:
    """The y at which the polyline first crosses the line x = 6 (None if it does not)."""
    for a, b in itertools.pairwise(path):
        if (a[0] - 6.0) * (b[0] - 6.0) < 0.0:
            return a[1] + (6.0 - a[0]) / (b[0] - a[0]) * (b[1] - a[1])
    return None


def walkable(path: np.ndarray, walls: np.ndarray, radius: float) -> bool:
    """Whether every leg keeps the body ``PLACEMENT_GAP`` clear of the walls."""
    return bool(np.all(segment_clearance(path[:-1], path[1:], walls) >= radius + PLACEMENT_GAP
                       - 1e-9))  # fmt: skip


def test_a_route_blocked_by_a_wall_goes_through_the_door():
    scenario = two_rooms()
    graph = route_graph(scenario.bounds, scenario.walls, scenario.obstacles, 0.3, PLACEMENT_GAP)
    start, goal = (10.0, 1.0), (2.0, 5.0)
    assert crosses_walls(start, goal, scenario.walls)  # the straight line hits the wall
    corners = graph.route(start, goal, 0.3)
    assert corners  # so the route turns
    path = np.array([start, *corners, goal])
    assert walkable(path, scenario.walls, 0.3)
    y = door_crossing(path)
    assert y is not None and DOOR[0] + 0.3 <= y <= DOOR[1] - 0.3  # through the door's middle
    assert graph.route(start, (9.0, 7.0), 0.3) == ()  # an open leg stays straight
    assert graph.route((10.0, 1.0), (9.0, 1.0), 0.3) == ()


def test_no_route_into_a_closed_room():
    walls = np.array([[2.0, 0.0, 2.0, 2.0], [2.0, 2.0, 0.0, 2.0]])  # a closed corner room
    graph = route_graph((0.0, 0.0, 6.0, 6.0), walls, (), 0.3, PLACEMENT_GAP)
    assert graph.route((4.0, 4.0), (1.0, 1.0), 0.3) is None
    assert graph.route((4.0, 4.0), (4.0, 1.0), 0.3) == ()


def test_sampled_walkers_go_through_the_door():
    scenario = two_rooms()
    for seed in range(10):
        layout = sample(scenario, np.random.default_rng(seed))
        assert layout.people
        for person in layout.people:
            path = np.array([person.position, *person.route])
            if person.loop:  # the way back closes the cycle
                path = np.vstack([path, person.route[0]])
            assert walkable(path, scenario.walls, person.radius)
            assert not any(crosses_walls(a, b, scenario.walls) for a, b in itertools.pairwise(path))
            y = door_crossing(path)
            assert y is not None and DOOR[0] < y < DOOR[1]


def test_sampling_routes_takes_nothing_from_the_generator():
    scenario = two_rooms()
    rng = np.random.default_rng(5)
    sample(scenario, rng)
    straight = parse_scenario(TWO_ROOMS.replace("5.95, 0.0, 6.05, 3.525", "5.95, 0.0, 6.05, 0.5")
                              .replace("5.95, 4.475, 6.05, 8.0", "5.95, 7.5, 6.05, 8.0"),
                              "open.yaml")  # fmt: skip
    other = np.random.default_rng(5)
    sample(validate(straight, trials=0), other)
    assert rng.bit_generator.state == other.bit_generator.state


def test_walkers_pass_the_door_and_reach_their_goals():
    scenario = two_rooms()
    layout = sample(scenario, np.random.default_rng(1))
    ahead = [p for p in layout.people if not p.loop]
    crowd = Crowd()
    rng = np.random.default_rng(0)
    walls = np.ascontiguousarray(scenario.walls)
    crowd.reset(ahead, (), walls, rng)
    none, dt = np.zeros((0, 2)), 0.1
    pos = crowd.position.copy()
    for k in range(400):
        v = crowd.desired_velocity(k * dt, dt, none, none, np.zeros(0)).copy()
        pos += v * dt
        crowd.sync(pos, v)
    assert np.all(crowd.state == STOPPED)
    goals = np.array([p.route[-1] for p in ahead])
    assert np.all(np.hypot(*(pos - goals).T) < 0.5)
    assert np.all(pos[:, 0] < 5.95)  # in the left room


def test_a_fixed_route_across_a_wall_is_walked_around_its_end():
    text = textwrap.dedent("""\
        name: around
        time_limit: 30.0
        bounds: [0.0, 0.0, 10.0, 6.0]
        walls:
          - [5.0, 0.0, 5.0, 2.0]
        robot:
          start: {position: [1.0, 4.5]}
          goal: {position: [9.0, 4.5]}
        people:
          - route: [[8.0, 1.0], [2.0, 1.0], [2.0, 2.5]]
            count: 2
            spacing: 2.0
        """)
    scenario = validate(parse_scenario(text, "around.yaml"), trials=0)
    for seed in range(5):
        for person in sample(scenario, np.random.default_rng(seed)).people:
            path = np.array([person.position, *person.route])
            assert walkable(path, scenario.walls, person.radius)
            assert tuple(person.route[-2:]) == ((2.0, 1.0), (2.0, 2.5))  # its own waypoints
            turn = [p for p in person.route if 4.0 < p[0] < 6.0]
            assert turn and all(p[1] > 2.0 + person.radius for p in turn)  # above the wall
