"""Geometric checks of a scenario for a robot of a given radius.

:func:`validate` checks a parsed :class:`~srpb_gym.scenarios.schema.Scenario` for the
robot's radius and returns it with its :class:`~srpb_gym.scenarios.space.FreeSpace`
attached (a clearance field and the connected components of the space the robot fits in,
on a 5 cm grid), so that sampling needs no geometry set-up. What is checked, each failure
raising a located :class:`~srpb_gym.errors.InputError`:

* every place (robot start and goal, those of each ``robots`` entry, spawn and goal
  regions, F-formation centres) lies inside ``bounds`` (all corners of a region);
* for ``robot`` and then each ``robots`` entry: the robot's circle (``robot_radius``,
  default 0.275 m) at the centre of its start and goal places keeps ``PLACEMENT_GAP``
  (5 cm) from walls and obstacles, and the goal is reachable from the start: some grid
  cell of the start place and some grid cell of the goal place are connected
  (4-neighbour) through cells whose centres are more than the robot radius away from
  every wall;
* an F-formation's members fit on its circle without overlapping at the smallest radius
  and the most members, and its whole circle plus a body radius around the centre of its
  place is clear of walls;
* every route waypoint and ``via`` point, and the centres of spawn and goal regions, are at
  least the largest body radius plus 5 cm (plus the waypoint jitter) away from walls (the
  F-formation circle, likewise, keeps 5 cm), and every leg of a route (taken between
  region centres for spawn entries) can be walked by the largest body, in a straight line
  or around the walls (the scenario's :class:`~srpb_gym.scenarios.routes.RouteGraph`,
  attached to the returned scenario);
* a route is long enough for its people to queue along it;
* sensor specs are accepted by the perception configs (when those modules are present);
* a few trial layouts can be drawn, for one robot and for all the ``robots`` entries (so
  crowded recipes fail at load time, not mid-run).
"""

from __future__ import annotations

import importlib
import inspect
import itertools
import math
from dataclasses import replace

import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.scenarios.routes import RouteGraph
from srpb_gym.scenarios.sampler import free_space_of, routes_of, sample
from srpb_gym.scenarios.schema import (
    PLACEMENT_GAP,
    FormationSpec,
    RobotSpec,
    Scenario,
    WalkerEntry,
    checked_robot_radius,
)
from srpb_gym.scenarios.space import FreeSpace, Place, Point

TRIAL_SEEDS = 8  # layouts drawn at load time
SENSOR_CONFIGS = (
    ("lidar", "srpb_gym.perception.lidar", "LidarConfig"),
    ("detector", "srpb_gym.perception.detector", "DetectorConfig"),
    ("tracker", "srpb_gym.perception.tracker", "TrackerConfig"),
)


# --- checks --------------------------------------------------------------------------------


def validate(
    scenario: Scenario, trials: int = TRIAL_SEEDS, *, robot_radius: float | None = None
) -> Scenario:
    """Check a scenario (see the module docstring) for a robot of ``robot_radius`` [m]
    (default: ``scenario.robot_radius``) and return it with that radius and its free space.

    ``trials`` layouts (seeds 0, 1, ...) are drawn as a last check.
    """
    radius = scenario.robot_radius if robot_radius is None else robot_radius
    radius = checked_robot_radius(radius, scenario.source)
    scenario = replace(scenario, robot_radius=radius, free_space=None, routes=None)
    if not scenario.time_limit > 0:
        raise scenario.error("time_limit", f"must be > 0, got {scenario.time_limit}")
    _check_places(scenario)
    space = free_space_of(scenario)
    _check_robot(scenario, space, "robot", scenario.robot, space.robot_labels)
    for i, spec in enumerate(scenario.robots):
        labels = space.labels_between(spec.start.place, spec.goal.place)
        _check_robot(scenario, space, f"robots[{i}]", spec, labels)
    for formation in scenario.formations:
        _check_formation(scenario, space, formation)
    routes = routes_of(scenario) if scenario.people else None
    if routes is not None:
        for entry in scenario.people:
            _check_walkers(scenario, space, routes, entry)
    _check_sensors(scenario)
    prepared = replace(scenario, free_space=space, routes=routes)
    for seed in range(trials):
        sample(prepared, np.random.default_rng(seed))
        if len(scenario.robots) > 1:
            sample(prepared, np.random.default_rng(seed), n_robots=len(scenario.robots))
    return prepared


def _places(scenario: Scenario) -> list[tuple[str, Place]]:
    found = []
    keyed = [("robot", scenario.robot)]
    keyed += [(f"robots[{i}]", spec) for i, spec in enumerate(scenario.robots)]
    for key, spec in keyed:
        found += [(f"{key}.start.position", spec.start.place),
                  (f"{key}.goal.position", spec.goal.place)]  # fmt: skip
    for entry in scenario.people:
        if entry.spawn is not None and entry.goal is not None:
            found += [(f"{entry.key}.spawn", entry.spawn), (f"{entry.key}.goal", entry.goal)]
    found += [(f"{f.key}.center", f.center) for f in scenario.formations]
    return found


def _check_places(scenario: Scenario) -> None:
    xmin, ymin, xmax, ymax = scenario.bounds
    for key, place in _places(scenario):
        for x, y in place.corners():
            if not (xmin <= x <= xmax and ymin <= y <= ymax):
                raise scenario.error(
                    key, f"({x:g}, {y:g}) lies outside the bounds {list(scenario.bounds)}"
                )


def _check_robot(
    scenario: Scenario, space: FreeSpace, key: str, robot: RobotSpec, labels: frozenset[int]
) -> None:
    """The ``robot`` entry or a ``robots`` entry (``key``) whose start and goal places meet
    the free-space components ``labels``."""
    radius = scenario.robot_radius
    for name, pose in (("start", robot.start), ("goal", robot.goal)):
        x, y = pose.place.center
        if not space.is_clear(x, y, radius + PLACEMENT_GAP):
            what = "the point" if pose.place.is_point else "the centre of the region"
            raise scenario.error(
                f"{key}.{name}.position",
                f"a robot of radius {radius:g} m at {what} ({x:g}, {y:g}) overlaps a wall or "
                f"obstacle or comes within {PLACEMENT_GAP} m of one "
                f"(clearance {space.exact_clearance(x, y):.3f} m)",
            )
    if not labels:
        raise scenario.error(
            f"{key}.goal.position",
            f"the goal is not reachable from the start for a robot of radius {radius:g} m "
            f"(checked on a {space.resolution:g} m occupancy grid)",
        )
    if robot.start.place.is_point and robot.goal.place.is_point:
        gap = math.dist(robot.start.place.center, robot.goal.place.center)
        if gap <= robot.goal_tolerance:
            raise scenario.error(
                f"{key}.goal.position",
                f"the goal is within goal_tolerance of the start ({gap:.3f} m)",
            )


def _check_formation(scenario: Scenario, space: FreeSpace, formation: FormationSpec) -> None:
    key, most, body = formation.key, formation.members[1], formation.body_radius[1]
    needed = body / math.sin(math.pi / most)
    if formation.radius[0] < needed:
        raise scenario.error(
            f"{key}.radius",
            f"a member circle of radius {formation.radius[0]:g} m cannot hold {most} members of "
            f"body radius {body:g} m without overlap (needs >= {needed:.3f} m)",
        )
    x, y = formation.center.center
    if not space.is_clear(x, y, formation.extent + PLACEMENT_GAP):
        raise scenario.error(
            f"{key}.center",
            f"members around ({x:g}, {y:g}) would stand inside a wall or obstacle: the circle of "
            f"radius {formation.extent:g} m (member circle + body) is not clear "
            f"(clearance {space.exact_clearance(x, y):.3f} m)",
        )


def _check_point(
    scenario: Scenario, space: FreeSpace, key: str, point: Point, radius: float
) -> None:
    if not space.is_clear(point[0], point[1], radius):
        raise scenario.error(
            key,
            f"({point[0]:g}, {point[1]:g}) is inside or too close to a wall or obstacle "
            f"(clearance {space.exact_clearance(*point):.3f} m, a person needs {radius:g} m)",
        )


def _check_walkers(
    scenario: Scenario, space: FreeSpace, routes: RouteGraph, entry: WalkerEntry
) -> None:
    radius, key = entry.params.radius[1], entry.key
    if entry.is_route:
        margin = radius + PLACEMENT_GAP + entry.waypoint_jitter * math.sqrt(2.0)
        keyed = [(f"{key}.route[{k}]", p) for k, p in enumerate(entry.route)]
        points = [p for _, p in keyed]
        for k, p in keyed:
            _check_point(scenario, space, k, p, margin)
        length = sum(math.dist(a, b) for a, b in itertools.pairwise(points))
        queue = (entry.count[1] - 1) * entry.spacing[1]
        if queue >= length:
            raise scenario.error(
                f"{key}.spacing",
                f"{entry.count[1]} people {entry.spacing[1]:g} m apart do not fit on a route of "
                f"{length:.2f} m",
            )
    else:
        assert entry.spawn is not None and entry.goal is not None
        keyed = [(f"{key}.spawn", entry.spawn.center)]
        keyed += [(f"{key}.via[{k}]", p) for k, p in enumerate(entry.via)]
        keyed += [(f"{key}.goal", entry.goal.center)]
        for k, p in keyed:
            _check_point(scenario, space, k, p, radius + PLACEMENT_GAP)
    legs = list(itertools.pairwise(keyed))
    if entry.loop and entry.is_route:
        legs.append((keyed[-1], keyed[0]))
    for (_, a), (k, b) in legs:
        if routes.route(a, b, radius) is None:
            raise scenario.error(
                k,
                f"a person of radius {radius:g} m cannot walk the leg from ({a[0]:g}, {a[1]:g}) "
                f"to ({b[0]:g}, {b[1]:g}): it crosses a wall or passes within "
                f"{PLACEMENT_GAP:g} m of one, and there is no way around the walls",
            )


def _check_sensors(scenario: Scenario) -> None:
    """Build each sensor config from its raw spec when the perception module exists."""
    for name, module_name, class_name in SENSOR_CONFIGS:
        key = f"sensors.{name}"
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name and module_name.startswith(exc.name):
                continue  # perception not installed: the raw spec was type-checked on load
            raise
        build = getattr(getattr(module, class_name, None), "from_spec", None)
        if build is None:
            continue
        accepted = inspect.signature(build).parameters
        kwargs = {"path": key} if "path" in accepted else {}
        if "file" in accepted:
            kwargs["file"] = scenario.source
        try:
            build(getattr(scenario.sensors, name), **kwargs)
        except InputError as exc:
            if exc.line is not None:
                raise
            raise scenario.error(exc.key or key, exc.message) from None
        except (TypeError, ValueError) as exc:
            raise scenario.error(key, str(exc)) from None
