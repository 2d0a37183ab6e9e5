"""Several robots in one scenario: the ``robots`` entries, ``sample(..., n_robots)``, their
checks, and single-robot layouts unchanged by them."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.errors import InputError
from srpb_gym.scenarios import (
    DEFAULT_ROBOT_RADIUS,
    list_scenarios,
    load_scenario,
    parse_scenario,
    sample,
    validate,
)  # fmt: skip
from srpb_gym.scenarios.sampler import GAP, ROBOT_GAP, ROBOTS_GAP
from srpb_gym.scenarios.space import point_distance

HERE = Path(__file__).resolve().parent
# layouts drawn with one robot before the ``robots`` key existed ("name|radius|seed"; crowd
# and fformation re-drawn when their F-formations were moved onto the robot's way)
RECORDED = json.loads((HERE / "single_robot_layouts.json").read_text())
ROBOT_COUNTS = {"corridor": 3, "crossing": 4, "crowd": 8, "doorway": 4, "fformation": 3}
CASES = [(name, n) for name in sorted(ROBOT_COUNTS) for n in (1, 2, 3, 8)
         if n <= ROBOT_COUNTS[name]]  # fmt: skip
SEEDS = 40
BIG = 0.45  # m, a robot radius every packaged scenario holds with all its robots
# m, a radius each scenario holds with all its robots, and one it does not
LARGEST = {"corridor": (0.95, 1.0), "crossing": (0.8, 0.85), "crowd": (0.75, 0.8),
           "doorway": (0.45, 0.5), "fformation": (0.75, 0.8)}  # fmt: skip


def _plain(layout) -> dict:
    """A layout as the JSON of the recorded layouts."""
    data = {
        "robots": [dataclasses.asdict(r) for r in layout.robots],
        "people": [dataclasses.asdict(p) for p in layout.people],
        "formations": [dataclasses.asdict(f) for f in layout.formations],
        "time_limit": layout.time_limit,
        "goal_tolerance": layout.goal_tolerance,
        "bounds": layout.bounds,
    }
    return json.loads(json.dumps(data))


def _inside(place, x: float, y: float) -> bool:
    return place.xmin <= x <= place.xmax and place.ymin <= y <= place.ymax


def test_packaged_scenarios_have_robots_entries():
    assert sorted(ROBOT_COUNTS) == list_scenarios()
    for name, count in ROBOT_COUNTS.items():
        scenario = load_scenario(name)
        assert len(scenario.robots) == scenario.max_robots == count, name
        assert scenario.robot_specs(1) == (scenario.robot,)
        assert scenario.robot_specs(count) == scenario.robots
        assert scenario.robots[0] == scenario.robot, name  # robot 0 repeats the single robot


@pytest.mark.parametrize(("name", "n"), CASES)
@pytest.mark.parametrize("radius", [DEFAULT_ROBOT_RADIUS, BIG])
def test_robots_keep_clear_of_walls_and_each_other(name, n, radius):
    scenario = load_scenario(name, robot_radius=radius)
    space, specs = scenario.free_space, scenario.robot_specs(n)
    for seed in range(SEEDS if radius == DEFAULT_ROBOT_RADIUS else SEEDS // 4):
        layout = sample(scenario, np.random.default_rng(seed), n_robots=n)
        assert len(layout.robots) == n
        assert layout.goal_tolerance == specs[0].goal_tolerance
        points = []
        for i, (robot, spec) in enumerate(zip(layout.robots, specs)):
            assert _inside(spec.start.place, *robot.start[:2])  # robot i from entry i
            assert _inside(spec.goal.place, *robot.goal[:2])
            assert space.label_at(*robot.start[:2]) == space.label_at(*robot.goal[:2]) != 0
            assert math.dist(robot.start[:2], robot.goal[:2]) > spec.goal_tolerance
            for x, y, yaw in (robot.start, robot.goal):
                assert space.exact_clearance(x, y) >= radius + GAP
                assert point_distance(x, y, scenario.walls) >= radius + GAP
                assert -math.pi <= yaw <= math.pi
                points.append((i, (x, y)))
        for (i, a), (j, b) in itertools.combinations(points, 2):
            if i != j:
                assert math.dist(a, b) >= 2.0 * radius + ROBOTS_GAP - 1e-12, (seed, i, j)
        for robot in layout.robots:
            for person in layout.people:
                gap = math.dist(person.position, robot.start[:2]) - person.radius - radius
                assert gap >= ROBOT_GAP - 1e-12
            for formation in layout.formations:
                for point in (robot.start[:2], robot.goal[:2]):
                    for member in formation.members:
                        assert math.dist(member, point) >= radius + formation.radius


@pytest.mark.parametrize("name", sorted(ROBOT_COUNTS))
def test_same_seed_same_layouts(name):
    scenario = load_scenario(name)
    n = min(3, scenario.max_robots)
    a, b, c = (sample(scenario, np.random.default_rng(s), n_robots=n) for s in (5, 5, 6))
    assert _plain(a) == _plain(b)
    assert a.robots != c.robots


@pytest.mark.parametrize("key", sorted(RECORDED))
def test_single_robot_layouts_are_unchanged(key):
    name, radius, seed = key.split("|")
    scenario = load_scenario(name, robot_radius=float(radius))
    for layout in (
        sample(scenario, np.random.default_rng(int(seed))),
        sample(scenario, np.random.default_rng(int(seed)), n_robots=1),
    ):
        assert _plain(layout) == RECORDED[key]  # exactly: JSON keeps every bit of a float


def test_single_robot_ignores_the_robots_entries():
    scenario = load_scenario("crowd")
    alone = dataclasses.replace(scenario, robots=())
    for seed in range(5):
        a, b = (sample(s, np.random.default_rng(seed)) for s in (scenario, alone))
        assert _plain(a) == _plain(b)


def test_more_robots_than_places_names_the_limit():
    with pytest.raises(InputError) as info:
        sample(load_scenario("corridor"), np.random.default_rng(0), n_robots=4)
    assert info.value.message == "scenario 'corridor' has places for at most 3 robots, got 4"
    assert str(info.value) == f"n_robots: {info.value.message}" and info.value.key == "n_robots"
    alone = dataclasses.replace(load_scenario("crowd"), robots=())
    with pytest.raises(InputError, match="'crowd' has places for at most 1 robot, got 2"):
        sample(alone, np.random.default_rng(0), n_robots=2)
    with pytest.raises(InputError, match="at most 8 robots, got 9"):
        load_scenario("crowd").robot_specs(9)


@pytest.mark.parametrize("n", [0, -1, 1.0, 2.5, True, "2", None])
def test_robot_count_must_be_a_whole_number(n):
    with pytest.raises(InputError, match="expected a whole number >= 1") as info:
        sample(load_scenario("corridor"), np.random.default_rng(0), n_robots=n)
    assert info.value.key == "n_robots"


def test_numpy_integer_counts():
    scenario = load_scenario("crowd")
    a = sample(scenario, np.random.default_rng(1), n_robots=np.int64(3))
    b = sample(scenario, np.random.default_rng(1), n_robots=3)
    assert _plain(a) == _plain(b)


# --- located errors of robots entries ---------------------------------------------------

ROOM = """\
name: room
bounds: [0.0, 0.0, 10.0, 6.0]
obstacles:
  - rectangle: [4.9, 0.0, 5.1, 2.5]
robot:
  start: {position: [1.0, 1.0]}
  goal: {position: [9.0, 1.0]}
robots:
  - start: {position: [1.0, 1.0]}
    goal: {position: [9.0, 1.0]}
  - start: {position: [9.0, 4.5]}
    goal: {position: [1.0, 4.5]}
    goal_tolerance: 0.3
"""


def _load(tmp_path, text: str, edits: dict[str, str], radius: float = DEFAULT_ROBOT_RADIUS):
    for old, new in edits.items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / "room.yaml"
    path.write_text(text)
    return load_scenario(path, robot_radius=radius)


def _error(tmp_path, edits: dict[str, str], radius: float = DEFAULT_ROBOT_RADIUS) -> InputError:
    with pytest.raises(InputError) as info:
        _load(tmp_path, ROOM, edits, radius)
    return info.value


def test_room_loads(tmp_path):
    scenario = _load(tmp_path, ROOM, {})
    assert len(scenario.robots) == 2 and scenario.robots[1].goal_tolerance == 0.3
    layout = sample(scenario, np.random.default_rng(0), n_robots=2)
    assert [r.start[:2] for r in layout.robots] == [(1.0, 1.0), (9.0, 4.5)]
    assert layout.robots[1].start[2] == pytest.approx(math.pi)  # towards its goal
    assert layout.goal_tolerance == 0.2  # the first robot's


ROBOTS_ERRORS = {
    # case: (edits, line, key, message)
    "start in a wall": (
        {"start: {position: [9.0, 4.5]}": "start: {position: [9.0, 5.9]}"},
        11, "robots[1].start.position",
        "a robot of radius 0.275 m at the point (9, 5.9) overlaps a wall or obstacle",
    ),
    "goal in an obstacle": (
        {"goal: {position: [1.0, 4.5]}": "goal: {position: [5.0, 2.0]}"},
        12, "robots[1].goal.position", "a robot of radius 0.275 m at the point (5, 2)",
    ),
    "unreachable goal": (
        {"[4.9, 0.0, 5.1, 2.5]": "[4.9, 0.0, 5.1, 6.0]",
         "robot:\n  start: {position: [1.0, 1.0]}\n  goal: {position: [9.0, 1.0]}":
         "robot:\n  start: {position: [1.0, 1.0]}\n  goal: {position: [3.0, 1.0]}"},
        10, "robots[0].goal.position",
        "the goal is not reachable from the start for a robot of radius 0.275 m",
    ),
    "outside the bounds": (
        {"goal: {position: [1.0, 4.5]}": "goal: {position: [1.0, 6.5]}"},
        12, "robots[1].goal.position", "(1, 6.5) lies outside the bounds",
    ),
    "goal within tolerance": (
        {"goal: {position: [1.0, 4.5]}": "goal: {position: [8.8, 4.5]}"},
        12, "robots[1].goal.position", "the goal is within goal_tolerance of the start",
    ),
    "two robots on one start": (
        {"start: {position: [9.0, 4.5]}": "start: {position: [1.5, 1.2]}"},
        11, "robots[1].start.position",
        "could not draw a start for a robot of radius 0.275 m clear of walls, 0.3 m clear of "
        "the other robots' starts and goals and reachable (1 tries; all robots drawn 20 times)",
    ),
    "two robots on one goal region": (
        {"goal: {position: [1.0, 4.5]}": "goal: {position: [8.5, 0.5, 9.5, 1.5]}"},
        12, "robots[1].goal.position", "could not draw a goal for a robot of radius 0.275 m",
    ),
    "not a list": (
        {ROOM[ROOM.index("robots:") :]: "robots: {a: 1}\n"},
        8, "robots", "expected a list, got a mapping",
    ),
    "unknown key": (
        {"    goal_tolerance: 0.3": "    speed: 0.3"},
        13, "robots[1].speed", "unknown key; valid keys: start, goal, goal_tolerance",
    ),
    "missing goal": (
        {"    goal: {position: [1.0, 4.5]}\n": ""},
        11, "robots[1]", "missing required key 'goal'",
    ),
    "bad tolerance": (
        {"goal_tolerance: 0.3": "goal_tolerance: -0.3"},
        13, "robots[1].goal_tolerance", "must be > 0",
    ),
    "bad yaw": (
        {"start: {position: [9.0, 4.5]}": "start: {position: [9.0, 4.5], yaw: west}"},
        11, "robots[1].start.yaw", "expected a number, [low, high] or towards_goal",
    ),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(ROBOTS_ERRORS))
def test_bad_robots_entry_names_file_line_and_key(tmp_path, case):
    edits, line, key, message = ROBOTS_ERRORS[case]
    error = _error(tmp_path, edits)
    assert error.path.endswith("room.yaml")
    assert (error.line, error.key) == (line, key), str(error)
    assert str(error).startswith(f"{error.path}:{line}: {key}: "), str(error)
    assert message in str(error)


def test_robots_too_crowded_for_a_big_robot_name_the_radius(tmp_path):
    # every start of robot 1 is less than 2 * 0.6 + 0.3 m from robot 0's start at (1, 1)
    edits = {"start: {position: [9.0, 4.5]}": "start: {position: [1.5, 0.5, 2.0, 2.0]}"}
    _load(tmp_path, ROOM, edits)  # fits 0.275 m robots: 0.85 m apart
    error = _error(tmp_path, edits, radius=0.6)
    assert error.key == "robots[1].start.position" and error.line == 11
    assert "could not draw a start for a robot of radius 0.6 m" in str(error)


def test_single_robot_problems_are_reported_first(tmp_path):
    edits = {"goal: {position: [9.0, 1.0]}\nrobots": "goal: {position: [5.0, 1.0]}\nrobots"}
    assert _error(tmp_path, edits).key == "robot.goal.position"


def test_one_robots_entry_is_checked_but_not_drawn(tmp_path):
    text = ROOM[: ROOM.index("  - start: {position: [9.0, 4.5]}")]
    scenario = _load(tmp_path, text, {})
    assert len(scenario.robots) == 1 and scenario.max_robots == 1
    edits = {"  - start: {position: [1.0, 1.0]}": "  - start: {position: [0.1, 1.0]}"}
    with pytest.raises(InputError, match=r"robots\[0\]\.start\.position: a robot of radius"):
        _load(tmp_path, text, edits)


def test_at_most_64_entries(tmp_path):
    entry = "  - {start: {position: [1.0, 1.0]}, goal: {position: [9.0, 1.0]}}\n"
    head = ROOM[: ROOM.index("robots:")]
    path = tmp_path / "many.yaml"
    path.write_text(head + "robots:\n" + entry * 65)
    with pytest.raises(InputError, match="robots: at most 64 robots, got 65"):
        parse_scenario(path.read_text(), str(path))


def test_parsed_entries_keep_their_places():
    text = ROOM.replace(
        "start: {position: [9.0, 4.5]}", "start: {position: [8, 4, 9, 5], yaw_deg: 90}"
    )
    scenario = validate(parse_scenario(text, "room.yaml"))
    spec = scenario.robots[1]
    assert (spec.start.place.xmin, spec.start.place.ymax) == (8.0, 5.0)
    assert not spec.start.yaw.towards_goal and spec.start.yaw.range == (math.pi / 2, math.pi / 2)
    assert spec.goal.yaw.towards_goal
    layout = sample(scenario, np.random.default_rng(3), n_robots=2)
    assert layout.robots[1].start[2] == pytest.approx(math.pi / 2)


# --- the largest robot each packaged scenario holds with all its robots ---------------------


@pytest.mark.parametrize("name", sorted(LARGEST))
def test_largest_robot_radius(name):
    fits, too_big = LARGEST[name]
    scenario = load_scenario(name, robot_radius=fits)
    for seed in range(20):
        sample(scenario, np.random.default_rng(seed), n_robots=scenario.max_robots)
    with pytest.raises(InputError, match=f"radius {too_big:g} m") as info:
        load_scenario(name, robot_radius=too_big)
    assert info.value.key.startswith("robots[" if name != "doorway" else "robot.")


def test_readme_example_has_two_robots(tmp_path):
    readme = HERE.parents[1] / "envs" / "README.md"
    block = re.findall(r"```yaml\n(.*?)```", readme.read_text(), re.S)[-1]
    (tmp_path / "example.yaml").write_text(block)
    example = load_scenario(tmp_path / "example.yaml")
    assert example.max_robots == 2 and example.robots[0] == example.robot
    layout = sample(example, np.random.default_rng(0), n_robots=2)
    assert layout.robots[1].start[:2] == (12.0, 3.3) and layout.goal_tolerance == 0.25
