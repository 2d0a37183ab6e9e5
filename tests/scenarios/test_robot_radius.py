"""Scenarios for robots of other sizes, the default's unchanged layouts, the module graph."""

from __future__ import annotations

import ast
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.errors import InputError
from srpb_gym.scenarios import (
    DEFAULT_ROBOT_RADIUS,
    ROBOT_RADIUS,
    list_scenarios,
    load_scenario,
    parse_scenario,
    sample,
    validate,
)  # fmt: skip
from srpb_gym.scenarios.sampler import GAP, ROBOT_GAP
from srpb_gym.scenarios.space import point_distance
from srpb_gym.sim.robot import RobotConfig

BIG = 0.45  # m
PACKAGE = Path(__file__).resolve().parents[2] / "srpb_gym" / "scenarios"


def test_default_radius_is_the_robot_config_radius():
    assert DEFAULT_ROBOT_RADIUS == ROBOT_RADIUS == RobotConfig().radius == 0.275
    scenario = load_scenario("corridor")
    assert scenario.robot_radius == DEFAULT_ROBOT_RADIUS
    assert scenario.free_space.robot_radius == DEFAULT_ROBOT_RADIUS


@pytest.mark.parametrize("name", list_scenarios())
def test_big_robot_starts_and_ends_clear_of_walls(name):
    scenario = load_scenario(name, robot_radius=BIG)
    assert scenario.robot_radius == BIG
    space = scenario.free_space
    for seed in range(30):
        layout = sample(scenario, np.random.default_rng(seed))
        (robot,) = layout.robots
        for x, y, _ in (robot.start, robot.goal):
            assert space.exact_clearance(x, y) >= BIG + GAP
            assert point_distance(x, y, scenario.walls) >= BIG + GAP  # walls incl. obstacles
        for person in layout.people:
            gap = math.dist(person.position, robot.start[:2]) - person.radius - BIG
            assert gap >= ROBOT_GAP - 1e-12
        for formation in layout.formations:
            for member in formation.members:
                assert math.dist(member, robot.goal[:2]) >= BIG + formation.radius


def test_doorway_goal_unreachable_for_a_robot_wider_than_the_door():
    # the door is 0.95 m wide: grid cells in it keep at most 0.45 m from its jambs
    fits = load_scenario("doorway", robot_radius=0.45)
    with pytest.raises(InputError) as info:
        load_scenario("doorway", robot_radius=0.6)
    error = info.value
    assert "the goal is not reachable from the start for a robot of radius 0.6 m" in str(error)
    assert error.path.endswith("doorway.yaml") and error.key == "robot.goal.position"
    assert error.line == fits.lines["robot.goal.position"]
    for name in list_scenarios():  # the others still fit a 0.6 m robot
        if name != "doorway":
            load_scenario(name, robot_radius=0.6)


def test_robot_start_in_wall_names_the_radius():
    with pytest.raises(InputError, match=r"robot\.start\.position: a robot of radius 1 m at"):
        load_scenario("fformation", robot_radius=1.0)


def test_parse_and_validate_take_the_radius():
    path = Path(load_scenario("doorway").source)
    parsed = parse_scenario(path.read_text(), str(path), robot_radius=0.6)
    assert parsed.robot_radius == 0.6 and parsed.free_space is None
    with pytest.raises(InputError, match=r"radius 0\.6 m"):
        validate(parsed)
    small = validate(parsed, robot_radius=0.3)  # an explicit radius overrides the parsed one
    assert small.robot_radius == small.free_space.robot_radius == 0.3
    big = validate(small, trials=0, robot_radius=BIG)
    loaded = load_scenario("doorway", robot_radius=BIG)
    for seed in range(5):
        a, b = (sample(s, np.random.default_rng(seed)) for s in (big, loaded))
        assert (a.robots, a.people, a.formations) == (b.robots, b.people, b.formations)


def test_sample_uses_the_scenario_radius_even_without_validation():
    scenario = load_scenario("crowd")
    bigger = replace(scenario, robot_radius=0.8)  # free space still for 0.275 m: recomputed
    for seed in range(5):
        (robot,) = sample(bigger, np.random.default_rng(seed)).robots
        for x, y, _ in (robot.start, robot.goal):
            assert scenario.free_space.exact_clearance(x, y) >= 0.8 + GAP


@pytest.mark.parametrize("radius", [0.0, -0.3, math.nan, math.inf, "big", True, None])
def test_bad_radius_is_an_input_error(radius):
    with pytest.raises(InputError, match="must be a number > 0") as info:
        load_scenario("corridor", robot_radius=radius)
    assert info.value.key == "robot_radius"


# (name, seed): robot start, robot goal, first person's position, first formation's centre
# and the number of walking people, as sampled before the robot radius became a parameter
# (crowd and fformation: as sampled since their F-formations were moved onto the robot's
# way).
# Yaws are compared to 1e-15 rad: the yaw drawn from a range was wrapped by adding and
# subtracting pi before, which changed the last bit; it is now returned as drawn.
DEFAULT_LAYOUTS = {
    ("corridor", 4): (
        (1.677222442228947, 1.1045310211257446, 0.03747425479062283),
        (13.690497482283082, 0.9323344095582409, 0.0),
        (15.094306454394449, 1.2552694995258347), None, 2,
    ),
    ("crossing", 3): (
        (1.2513895002861746, 4.7368105065960995, 0.03020694289287679),
        (12.680764679123838, 5.082162036064368, 0.03020694289287679),
        (5.176679543492919, 0.7277911317096628), None, 2,
    ),
    ("crowd", 0): (
        (1.2095693498571634, 0.9158293710110962, 0.6837546613075758),
        (10.532778819148955, 8.513222108422823, 0.6837546613075758),
        (9.922332361378775, 5.364858738192007), (4.673981071760082, 3.993826673183316), 12,
    ),
    ("doorway", 1): (
        (1.5118216247002567, 4.90092739265187, -0.0004203378237413462),
        (10.144159612719633, 4.8972988942744875, -0.0004203378237413462),
        (10.810810375281767, 3.4551948182149674), None, 2,
    ),
    ("fformation", 2): (
        (4.404644853699726, 6.419396457365649, -1.5358546515733218),
        (10.094267722178284, 1.7683831884270194, 0.0),
        None, (7.945712105362359, 1.7875802146733206), 0,
    ),
}  # fmt: skip


@pytest.mark.parametrize(("name", "seed"), sorted(DEFAULT_LAYOUTS))
def test_default_radius_layouts_are_unchanged(name, seed):
    start, goal, person, center, people = DEFAULT_LAYOUTS[name, seed]
    layout = sample(load_scenario(name), np.random.default_rng(seed))
    (robot,) = layout.robots
    assert robot.start[:2] == start[:2] and robot.goal[:2] == goal[:2]
    assert robot.start[2] == pytest.approx(start[2], abs=1e-15, rel=0)
    assert robot.goal[2] == pytest.approx(goal[2], abs=1e-15, rel=0)
    assert len(layout.people) == people
    assert (layout.people[0].position if layout.people else None) == person
    assert (layout.formations[0].center if layout.formations else None) == center


def test_yaw_ranges_are_wrapped():
    scenario = validate(parse_scenario(
        "bounds: [0, 0, 10, 4]\n"
        "robot: {start: {position: [1, 2], yaw_deg: 270}, goal: {position: [9, 2], yaw: 7.0}}\n"
    ))  # fmt: skip
    (robot,) = sample(scenario, np.random.default_rng(0)).robots
    assert robot.start[2] == pytest.approx(-math.pi / 2)
    assert robot.goal[2] == pytest.approx(7.0 - 2.0 * math.pi)


# --- the module graph ----------------------------------------------------------------------

MODULES = ("space", "routes", "schema", "reader", "sampler", "validate", "loader")


@pytest.mark.parametrize("module", MODULES)
def test_each_module_imports_first(module):
    code = f"import srpb_gym.scenarios.{module}; import srpb_gym.scenarios"
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, timeout=120)


def _package_imports(module: str) -> set[str]:
    """The ``srpb_gym.scenarios`` modules ``module`` imports anywhere (functions and
    ``TYPE_CHECKING`` blocks included)."""
    tree = ast.parse((PACKAGE / f"{module}.py").read_text())
    found = set()
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        for name in names:
            if name.startswith("srpb_gym.scenarios.") and name.count(".") == 2:
                found.add(name.rsplit(".", 1)[1])
    return found & set(MODULES)


def test_modules_form_a_dag():
    # each module imports only modules before it in MODULES
    for k, module in enumerate(MODULES):
        assert _package_imports(module) <= set(MODULES[:k]), module
