"""What the environment adapters share besides their settings
(:class:`~srpb_gym.settings.EnvSettings`): drawing an episode's layout with the reset
options, the planner's computation time and the episode's time limit."""

from __future__ import annotations

import math
import numbers
import warnings
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.scenarios import Scenario, sample
from srpb_gym.scenarios.sampler import free_space_of
from srpb_gym.sim.layout import EpisodeLayout, RobotLayout
from srpb_gym.simulation import Simulation

RESET_OPTIONS = ("people", "start", "goal")


def check_render_mode(render_mode: str | None, modes: list[str]) -> None:
    """A render mode of the environment's metadata, or ``None``."""
    if render_mode is not None and render_mode not in modes:
        raise InputError(f"expected one of {modes}, got {render_mode!r}", key="render_mode")


def episode_layout(
    scenario: Scenario,
    rng: np.random.Generator,
    options: Mapping[str, Any] | None,
    n_robots: int = 1,
    *,
    strict: bool = True,
    route: int | None = None,
) -> EpisodeLayout:
    """The layout of one episode: drawn from ``scenario`` with ``rng`` (a single robot
    from ``scenario.robots[route]`` when ``route`` is given), changed by the reset options
    ``people`` (False: nobody) and, with one robot, ``start`` and ``goal`` ((x, y, yaw)
    [m, m, rad], checked to hold the robot and to be connected).

    An unknown option is an error, or with ``strict=False`` a warning (PettingZoo's API
    test passes options of its own)."""
    if options is not None and not isinstance(options, Mapping):
        raise InputError(f"expected a mapping of reset options (or None), got {options!r}",
                         key="options")  # fmt: skip
    options = dict(options or {})
    unknown = sorted(set(options) - set(RESET_OPTIONS))
    if unknown:
        message = f"unknown reset option; valid: {', '.join(RESET_OPTIONS)}"
        if strict:
            raise InputError(message, key=f"options.{unknown[0]}")
        warnings.warn(f"options.{unknown[0]}: {message}; ignored", stacklevel=3)
    people = options.get("people", True)
    if not isinstance(people, (bool, np.bool_)):
        raise InputError(f"expected true or false, got {people!r}", key="options.people")
    layout = sample(scenario, rng, n_robots=n_robots, route=route)
    if not people:
        layout = replace(layout, people=(), formations=())
    if "start" in options or "goal" in options:
        if n_robots != 1:
            raise InputError(
                "start and goal options need a single robot",
                key="options.start" if "start" in options else "options.goal",
            )
        robot = layout.robots[0]
        start = _pose_option(options.get("start", robot.start), "start")
        goal = _pose_option(options.get("goal", robot.goal), "goal")
        _check_poses(scenario, start, goal)
        layout = replace(layout, robots=(RobotLayout(start, goal),))
    return layout


def route_choice(scenario: Scenario, route: Any) -> int | str | tuple[int, ...] | None:
    """The ``route`` argument of a single-robot environment, checked: ``None`` (the
    scenario's ``robot`` entry), ``i`` (its ``robots[i]`` entry), ``"random"`` (one of
    its ``robots`` entries drawn for each episode) or a non-empty list of entries (one of
    them drawn for each episode, each item equally often: an entry listed twice is drawn
    twice as often), returned as a tuple. The entries must share the goal tolerance of
    ``robot`` (the task's metric parameters hold one)."""
    if route is None:
        return None
    if isinstance(route, str) and route == "random":
        if not scenario.robots:
            raise InputError(f"scenario {scenario.name!r} has no robots entries to draw a "
                             f"route from", key="route")  # fmt: skip
        entries = list(range(len(scenario.robots)))
    elif isinstance(route, str):
        raise InputError(f"expected a robots entry's index, a list of them or 'random', got "
                         f"{route!r}", key="route")  # fmt: skip
    elif isinstance(route, (list, tuple)):
        if not route:
            raise InputError("expected at least one robots entry in the list", key="route")
        for item in route:
            scenario.route_spec(item)
        route = entries = tuple(int(item) for item in route)
    else:
        scenario.route_spec(route)
        route = int(route)
        entries = [route]
    tolerance = scenario.robot.goal_tolerance
    for i in sorted(set(entries)):
        if scenario.robots[i].goal_tolerance != tolerance:
            raise scenario.error(
                f"robots[{i}].goal_tolerance",
                f"a route's goal tolerance must be the robot entry's ({tolerance:g} m) for "
                f"route={route!r}, got {scenario.robots[i].goal_tolerance:g} m",
            )
    return route


def planning_seconds(value: Any) -> float:
    """A planner computation time [s]: a finite real number >= 0 (numpy scalars too)."""
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real)
            or not math.isfinite(value) or value < 0):  # fmt: skip
        raise ValueError(f"planning time must be a finite number >= 0 [s], got {value!r}")
    return float(value)


def out_of_time(sim: Simulation, steps: int, step_limit: int | None) -> bool:
    """Whether the episode is over by the scenario's time limit or the step limit."""
    if step_limit is not None and steps >= step_limit:
        return True
    return sim.t >= sim.layout.time_limit - 1e-9


def _check_poses(scenario: Scenario, start: tuple[float, ...], goal: tuple[float, ...]) -> None:
    """A start and goal from reset options must hold the robot and be connected."""
    space = free_space_of(scenario)
    radius = scenario.robot_radius
    for name, (x, y, _) in (("start", start), ("goal", goal)):
        if not space.is_clear(x, y, radius):
            raise InputError(f"a robot of radius {radius:g} m at ({x:g}, {y:g}) overlaps a "
                             f"wall, an obstacle or the world's edge",
                             key=f"options.{name}")  # fmt: skip
    if space.label_at(*start[:2]) != space.label_at(*goal[:2]):
        raise InputError(f"the goal is not reachable from the start for a robot of radius "
                         f"{radius:g} m", key="options.goal")  # fmt: skip


def _pose_option(value: Any, name: str) -> tuple[float, float, float]:
    """An (x, y, yaw) reset option as floats; anything else is an error naming the key."""
    try:
        pose = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        pose = ()
    if len(pose) != 3 or not all(map(math.isfinite, pose)):
        raise InputError(f"expected (x, y, yaw), three finite numbers [m, m, rad], got "
                         f"{value!r}", key=f"options.{name}")  # fmt: skip
    return pose  # type: ignore[return-value]
