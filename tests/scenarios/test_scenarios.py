"""Scenario files: packaged scenarios, sampling invariants, and located errors."""

from __future__ import annotations

import importlib.resources
import importlib.util
import math
import re
import textwrap
import time
from collections import deque
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.errors import InputError
from srpb_gym.resources import scenarios_dir
from srpb_gym.scenarios import (
    ROBOT_RADIUS,
    list_scenarios,
    load_scenario,
    parse_scenario,
    sample,
    validate,
)  # fmt: skip
from srpb_gym.scenarios.schema import PLACEMENT_GAP
from srpb_gym.scenarios.space import inside_polygon, point_distance

NAMES = ["corridor", "crossing", "crowd", "doorway", "fformation"]
README = Path(__file__).resolve().parents[2] / "envs" / "README.md"


def _clearance(scenario, x: float, y: float) -> float:
    """Independent exact clearance: distance to walls, 0 inside an obstacle or outside."""
    xmin, ymin, xmax, ymax = scenario.bounds
    if not (xmin <= x <= xmax and ymin <= y <= ymax):
        return 0.0
    if any(inside_polygon(x, y, poly) for poly in scenario.obstacles):
        return 0.0
    return point_distance(x, y, scenario.walls)


def _free_mask(scenario, res: float):
    """Cells whose centres keep more than the robot's radius from every wall (brute force)."""
    xmin, ymin, xmax, ymax = scenario.bounds
    cols, rows = math.ceil((xmax - xmin) / res), math.ceil((ymax - ymin) / res)
    X, Y = np.meshgrid(xmin + (np.arange(cols) + 0.5) * res, ymin + (np.arange(rows) + 0.5) * res)
    P = np.stack([X.ravel(), Y.ravel()], axis=1)[:, None, :]
    a, b = scenario.walls[None, :, :2], scenario.walls[None, :, 2:]
    t = np.clip(np.sum((P - a) * (b - a), -1) / np.maximum(np.sum((b - a) ** 2, -1), 1e-12), 0, 1)
    dist = np.linalg.norm(P - (a + t[..., None] * (b - a)), axis=-1).min(axis=1).reshape(X.shape)
    free = dist > scenario.robot_radius
    for poly in scenario.obstacles:
        free &= ~inside_polygon(X, Y, poly)
    return free & (xmin + scenario.robot_radius < X) & (xmax - scenario.robot_radius > X)


def _bfs_reachable(scenario, free, a, b, res: float = 0.05) -> bool:
    """Breadth-first search on the inflated grid (independent of the scenario's labels)."""
    xmin, ymin = scenario.bounds[:2]
    rows, cols = free.shape

    def nearest_free(p):
        i, j = int((p[1] - ymin) // res), int((p[0] - xmin) // res)
        cells = [(i + di, j + dj) for di in (-1, 0, 1) for dj in (-1, 0, 1)]
        return next(
            c for c in sorted(cells, key=lambda c: abs(c[0] - i) + abs(c[1] - j)) if free[c]
        )

    start, goal = nearest_free(a), nearest_free(b)
    seen, queue = {start}, deque([start])
    while queue:
        i, j = queue.popleft()
        if (i, j) == goal:
            return True
        for n in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
            if n not in seen and 0 <= n[0] < rows and 0 <= n[1] < cols and free[n]:
                seen.add(n)
                queue.append(n)
    return False


def _as_tuple(layout):
    return (
        layout.walls.tobytes(), layout.robots, layout.people, layout.formations,
        layout.time_limit, layout.goal_tolerance, layout.bounds, layout.metadata,
    )  # fmt: skip


# --- packaged scenarios --------------------------------------------------------------------


def test_list_scenarios_lists_the_five():
    assert set(NAMES) <= set(list_scenarios())
    assert list_scenarios() == sorted(list_scenarios())


def test_packaged_files_are_found():
    folder = scenarios_dir()
    assert all((folder / f"{name}.yaml").is_file() for name in NAMES)
    if importlib.util.find_spec("srpb_gym.envs_data") is not None:  # installed package data
        assert (importlib.resources.files("srpb_gym.envs_data") / "corridor.yaml").is_file()


@pytest.mark.parametrize(("name", "radius"), [(n, r) for n in NAMES for r in (ROBOT_RADIUS, 0.45)])
def test_scenario_samples_valid_layouts(name, radius):
    scenario = load_scenario(name, robot_radius=radius)
    assert scenario.name == name and scenario.description
    assert scenario.robot_radius == radius and scenario.free_space.robot_radius == radius
    free = _free_mask(scenario, 0.05)
    for seed in range(20):
        layout = sample(scenario, np.random.default_rng(seed))
        (robot,) = layout.robots
        for x, y, _ in (robot.start, robot.goal):
            assert _clearance(scenario, x, y) >= radius + PLACEMENT_GAP
        assert math.dist(robot.start[:2], robot.goal[:2]) > layout.goal_tolerance
        assert _bfs_reachable(scenario, free, robot.start, robot.goal)
        space = scenario.free_space
        assert space.label_at(*robot.start[:2]) == space.label_at(*robot.goal[:2]) != 0
        bodies = [(p.position, p.radius) for p in layout.people]
        for f in layout.formations:
            assert 2 <= len(f.members) <= 6
            bodies += [(m, f.radius) for m in f.members]
        for p, r in bodies:
            assert _clearance(scenario, *p) >= r + PLACEMENT_GAP
            assert math.dist(p, robot.start[:2]) >= r + radius
        for k, (p, r) in enumerate(bodies):
            for q, s in bodies[k + 1 :]:
                assert math.dist(p, q) >= r + s
        assert layout.time_limit == scenario.time_limit > 0


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_layout(name):
    scenario = load_scenario(name)
    for seed in (0, 5, 123):
        a = sample(scenario, np.random.default_rng(seed))
        b = sample(scenario, np.random.default_rng(seed))
        assert _as_tuple(a) == _as_tuple(b)
    layouts = {_as_tuple(sample(scenario, np.random.default_rng(s)))[1] for s in range(5)}
    assert len(layouts) > 1  # different seeds give different robot poses


def test_sampling_is_fast():
    scenario = load_scenario("crowd")
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    for _ in range(50):
        sample(scenario, rng)
    assert (time.perf_counter() - t0) / 50 < 0.01  # typically well under 1 ms


def test_paper_scenarios_match_the_description():
    corridor = sample(load_scenario("corridor"), np.random.default_rng(0))
    start, goal = corridor.robots[0].start, corridor.robots[0].goal
    assert 11.0 <= math.dist(start[:2], goal[:2]) <= 13.0
    assert 2.0 <= corridor.bounds[3] - corridor.bounds[1] <= 2.5
    first, second = corridor.people
    assert first.position[0] < second.position[0]  # both walk towards the robot, -x
    assert second.start_delay > first.start_delay
    fform = sample(load_scenario("fformation"), np.random.default_rng(0))
    (group,) = fform.formations
    assert len(group.members) == 2
    # the route bends round the cabinets (about 10 m driven, as in the paper's lab)
    assert 6.5 <= math.dist(fform.robots[0].start[:2], fform.robots[0].goal[:2]) <= 8.0
    assert math.dist(group.center, fform.robots[0].goal[:2]) < 3.0


def test_crowd_has_12_to_20_people():
    scenario = load_scenario("crowd")
    for seed in range(20):
        layout = sample(scenario, np.random.default_rng(seed))
        total = len(layout.people) + sum(len(f.members) for f in layout.formations)
        assert 12 <= total <= 20
        assert len(layout.formations) == 2
        assert any(p.group >= 0 for p in layout.people)


def test_load_by_path_and_readme_example(tmp_path):
    by_name = load_scenario("doorway")
    by_path = load_scenario(Path(by_name.source))
    assert load_scenario("doorway.yaml").source == by_name.source
    assert by_path.name == "doorway" and by_path.walls.shape == by_name.walls.shape
    block = re.findall(r"```yaml\n(.*?)```", README.read_text(), re.S)[-1]
    (tmp_path / "example.yaml").write_text(block)
    example = load_scenario(tmp_path / "example.yaml")
    assert example.name == "hallway" and len(example.obstacles) == 3
    assert example.robot.goal.yaw.range == pytest.approx((-math.pi / 9, math.pi / 9))


def test_defaults_and_degrees():
    scenario = parse_scenario(
        textwrap.dedent("""\
            bounds: [0, 0, 10, 10]
            robot:
              start: {position: [1, 1]}
              goal: {position: [9, 9], yaw_deg: 90}
            people:
              - spawn: [2, 2, 4, 4]
                goal: [6, 6]
            formations:
              - center: [5, 2]
                orientation_deg: [0, 90]
            """),
        "defaults.yaml",
    )
    assert scenario.name == "defaults"
    assert scenario.time_limit == 60.0 and scenario.robot.goal_tolerance == 0.2
    assert scenario.robot.start.yaw.towards_goal
    assert scenario.robot.goal.yaw.range == pytest.approx((math.pi / 2, math.pi / 2))
    (entry,) = scenario.people
    assert entry.params.preferred_speed == (0.89, 1.79) and entry.params.radius == (0.2, 0.3)
    assert entry.params.relaxation_time == (0.4, 0.6) and entry.params.robot_reaction == (1, 1)
    assert scenario.formations[0].orientation == pytest.approx((0.0, math.pi / 2))
    assert scenario.walls.shape == (4, 4)  # enclose: true adds the bounds edges
    layout = sample(validate(scenario), np.random.default_rng(1))
    assert layout.robots[0].start[2] == pytest.approx(math.pi / 4)
    assert layout.robots[0].goal[2] == pytest.approx(math.pi / 2)
    assert layout.people[0].route == ((6.0, 6.0),)


def test_route_queue_and_loop():
    scenario = validate(parse_scenario(textwrap.dedent("""\
        bounds: [0, 0, 20, 4]
        robot: {start: {position: [1, 2]}, goal: {position: [19, 2]}}
        people:
          - route: [[18, 1], [10, 1], [10, 3]]
            count: 3
            spacing: 2.0
            headway: 1.5
            loop: true
            start_delay: 0.5
        """)))  # fmt: skip
    people = sample(scenario, np.random.default_rng(0)).people
    assert [p.position for p in people] == [(14.0, 1.0), (16.0, 1.0), (18.0, 1.0)]
    assert [p.start_delay for p in people] == [0.5, 2.0, 3.5]
    assert people[2].route == ((10.0, 1.0), (10.0, 3.0), (18.0, 1.0))
    assert all(p.loop for p in people)
    assert people[0].yaw == pytest.approx(math.pi)


# --- errors --------------------------------------------------------------------------------

GOOD = """\
name: test
time_limit: 30.0
bounds: [0.0, 0.0, 10.0, 6.0]
walls:
  - [5.0, 0.0, 5.0, 2.0]
obstacles:
  - rectangle: [7.0, 4.0, 8.0, 5.0]
robot:
  start:
    position: [1.0, 3.0]
  goal:
    position: [9.0, 3.0]
people:
  - route: [[8.0, 2.5], [2.0, 2.5]]
    count: 1
formations:
  - center: [3.0, 4.5]
    members: 2
"""


def _write(tmp_path, text: str, edits: dict[str, str] | None = None) -> Path:
    for old, new in (edits or {}).items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    return path


def _error(tmp_path, edits, text: str = GOOD) -> InputError:
    path = _write(tmp_path, text, edits)
    with pytest.raises(InputError) as info:
        load_scenario(path)
    return info.value


def test_good_file_loads(tmp_path):
    scenario = load_scenario(_write(tmp_path, GOOD))
    assert scenario.name == "test" and len(scenario.people) == 1


BAD_CASES = {
    "unknown top key": (
        {"time_limit: 30.0": "time_limit: 30.0\ncolour: red"},
        3,
        "colour",
        "unknown key",
    ),
    "unknown nested key": (
        {"    count: 1": "    count: 1\n    speed: 1.0"},
        16,
        "people[0].speed",
        "unknown key",
    ),
    "unknown robot key": (
        {"  goal:\n": "  goal:\n    size: 1\n"},
        12,
        "robot.goal.size",
        "unknown key",
    ),
    "wrong type": ({"time_limit: 30.0": "time_limit: long"}, 2, "time_limit", "expected a number"),
    "wrong list size": (
        {"bounds: [0.0, 0.0, 10.0, 6.0]": "bounds: [0, 0, 10]"},
        3,
        "bounds",
        "4 numbers",
    ),
    "time limit zero": ({"time_limit: 30.0": "time_limit: 0"}, 2, "time_limit", "must be > 0"),
    "time limit negative": ({"time_limit: 30.0": "time_limit: -5"}, 2, "time_limit", "must be > 0"),
    "start in wall": (
        {"position: [1.0, 3.0]": "position: [4.9, 1.0]"},
        10,
        "robot.start.position",
        "overlaps a wall",
    ),
    "start region centre in wall": (
        {"position: [1.0, 3.0]": "position: [4.0, 0.5, 5.8, 1.5]"},
        10,
        "robot.start.position",
        "centre of the region",
    ),
    "goal in obstacle": (
        {"position: [9.0, 3.0]": "position: [7.5, 4.5]"},
        12,
        "robot.goal.position",
        "overlaps a wall or obstacle",
    ),
    "start outside bounds": (
        {"position: [1.0, 3.0]": "position: [-1.0, 3.0]"},
        10,
        "robot.start.position",
        "outside the bounds",
    ),
    "goal unreachable": (
        {"  - [5.0, 0.0, 5.0, 2.0]": "  - [5.0, 0.0, 5.0, 6.0]"},
        12,
        "robot.goal.position",
        "not reachable from the start for a robot of radius 0.275 m",
    ),
    "too few members": (
        {"    members: 2": "    members: 1"},
        18,
        "formations[0].members",
        "2 to 6 members",
    ),
    "too many members": (
        {"    members: 2": "    members: [3, 7]"},
        18,
        "formations[0].members",
        "2 to 6 members",
    ),
    "members do not fit": (
        {"    members: 2": "    members: 6\n    radius: 0.4"},
        19,
        "formations[0].radius",
        "cannot hold 6 members",
    ),
    "members in wall": (
        {"center: [3.0, 4.5]": "center: [3.0, 5.5]"},
        17,
        "formations[0].center",
        "inside a wall",
    ),
    "group too big": (
        {"    count: 1": "    count: 1\n    group_size: 5"},
        16,
        "people[0].group_size",
        "must be 1 to 4",
    ),
    "waypoint in wall": (
        {"[[8.0, 2.5], [2.0, 2.5]]": "[[8.0, 2.5], [5.1, 1.0], [2.0, 2.5]]"},
        14,
        "people[0].route[1]",
        "too close to a wall",
    ),
    "waypoint in obstacle": (
        {"[[8.0, 2.5], [2.0, 2.5]]": "[[7.5, 4.5], [2.0, 2.5]]"},
        14,
        "people[0].route[0]",
        "inside or too close",
    ),
    "leg with no way around walls": (
        {
            "  - [5.0, 0.0, 5.0, 2.0]": "  - [5.0, 0.0, 5.0, 2.0]\n  - [2.0, 0.0, 2.0, 2.0]\n"
            "  - [2.0, 2.0, 4.0, 2.0]\n  - [4.0, 2.0, 4.0, 0.0]",
            "[[8.0, 2.5], [2.0, 2.5]]": "[[8.0, 2.5], [3.0, 1.0], [2.0, 2.5]]",
        },
        17,
        "people[0].route[1]",
        "no way around the walls",
    ),
    "route too short": (
        {"    count: 1": "    count: 4\n    spacing: 3.0"},
        16,
        "people[0].spacing",
        "do not fit",
    ),
    "range reversed": (
        {"    count: 1": "    count: 1\n    preferred_speed: [1.4, 0.8]"},
        16,
        "people[0].preferred_speed",
        "low > high",
    ),
    "both yaw keys": (
        {"position: [9.0, 3.0]": "position: [9.0, 3.0]\n    yaw: 0.0\n    yaw_deg: 0.0"},
        14,
        "robot.goal.yaw_deg",
        "not both",
    ),
    "bad yaw word": (
        {"position: [9.0, 3.0]": "position: [9.0, 3.0]\n    yaw: sideways"},
        13,
        "robot.goal.yaw",
        "towards_goal",
    ),
    "route and spawn": (
        {"    count: 1": "    count: 1\n    spawn: [1, 1, 2, 2]"},
        14,
        "people[0]",
        "exactly one",
    ),
    "sensor type": (
        {"formations:": "sensors:\n  lidar: 3\nformations:"},
        17,
        "sensors.lidar",
        "preset name or a mapping",
    ),
    "duplicate key": (
        {"time_limit: 30.0": "time_limit: 30.0\ntime_limit: 20.0"},
        3,
        "time_limit",
        "duplicate key",
    ),
    "missing robot": ({"robot:\n  start:": "robot_:\n  start:"}, 8, "robot_", "unknown key"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_scenario_names_file_line_and_key(tmp_path, case):
    edits, line, key, words = BAD_CASES[case]
    error = _error(tmp_path, edits)
    text = str(error)
    assert text.startswith(f"{tmp_path / 'bad.yaml'}:{line}: {key}: "), text
    assert error.line == line and error.key == key
    if words is not None:
        assert words in text, text


def test_overcrowded_spawn_names_the_entry(tmp_path):
    crowded = GOOD + textwrap.dedent("""\
        people:
          - spawn: [1.5, 4.5, 2.5, 5.5]
            goal: [8.0, 1.0]
            count: 20
        """)
    crowded = crowded.replace("people:\n  - route: [[8.0, 2.5], [2.0, 2.5]]\n    count: 1\n", "")
    error = _error(tmp_path, {}, crowded)
    assert ": people[0]: could not place person" in str(error) and error.line is not None


def test_sampler_error_when_placement_fails_at_run_time(tmp_path):
    text = GOOD.replace("[[8.0, 2.5], [2.0, 2.5]]", "[[1.6, 3.0], [8.0, 3.0]]")
    path = _write(tmp_path, text)
    scenario = validate(parse_scenario(path.read_text(), str(path)), trials=0)
    with pytest.raises(InputError, match=r"bad\.yaml:14: people\[0\]: could not place"):
        sample(scenario, np.random.default_rng(0))
    with pytest.raises(InputError, match=r"people\[0\]: could not place the people"):
        load_scenario(path)  # the trial layouts catch it at load time


HAS_PERCEPTION = all(
    importlib.util.find_spec(f"srpb_gym.perception.{m}") is not None
    for m in ("lidar", "detector", "tracker")
)


@pytest.mark.skipif(not HAS_PERCEPTION, reason="perception configs not present")
def test_sensor_specs_are_checked_by_the_perception_configs(tmp_path):
    good = "sensors:\n  lidar: paper\n  detector: {preset: default}\n  tracker: {}\nformations:"
    scenario = load_scenario(_write(tmp_path, GOOD, {"formations:": good}))
    assert scenario.sensors.lidar == "paper" and scenario.sensors.tracker == {}
    error = _error(tmp_path, {"formations:": "sensors:\n  lidar: nowhere\nformations:"})
    assert error.line == 17 and error.key == "sensors.lidar" and "unknown preset" in str(error)
    bad_key = "sensors:\n  detector:\n    preset: default\n    colour: red\nformations:"
    error = _error(tmp_path, {"formations:": bad_key})
    assert str(error).startswith(f"{tmp_path / 'bad.yaml'}:19: sensors.detector.colour: ")


def test_yaml_syntax_error_has_line(tmp_path):
    error = _error(tmp_path, {"  start:\n": "  start: [\n"})
    assert error.line is not None and "invalid YAML" in str(error)
    assert str(error).startswith(str(tmp_path / "bad.yaml"))


def test_unknown_name_lists_packaged():
    with pytest.raises(InputError, match=r"unknown scenario 'nowhere'.*corridor"):
        load_scenario("nowhere")
    with pytest.raises(InputError, match="no such scenario file"):
        load_scenario("missing/file.yaml")
