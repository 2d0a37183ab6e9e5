"""Geometric checks of a scenario and the free-space model its sampler draws from.

:func:`validate` checks a parsed :class:`~srpb_gym.scenarios.schema.Scenario` and returns it
with its :class:`FreeSpace` attached (a clearance field and the connected components of the
space the robot fits in, on a 5 cm grid), so that sampling needs no geometry set-up. What
is checked, each failure raising a located :class:`~srpb_gym.errors.InputError`:

* every place (robot start and goal, spawn and goal regions, F-formation centres) lies
  inside ``bounds`` (all corners of a region);
* the robot's circle (radius 0.275 m) at the centre of its start and goal places keeps
  ``PLACEMENT_GAP`` (5 cm) from walls and obstacles, and the goal is reachable from the
  start: some grid cell of the
  start place and some grid cell of the goal place are connected (4-neighbour) through
  cells whose centres are more than the robot radius away from every wall;
* an F-formation's members fit on its circle without overlapping at the smallest radius
  and the most members, and its whole circle plus a body radius around the centre of its
  place is clear of walls;
* every route waypoint and ``via`` point, and the centres of spawn and goal regions, are at
  least the largest body radius plus 5 cm (plus the waypoint jitter) away from walls (the
  F-formation circle, likewise, keeps 5 cm), and no leg of a
  route (taken between region centres for spawn entries) crosses a wall;
* a route is long enough for its people to queue along it;
* sensor specs are accepted by the perception configs (when those modules are present);
* a few trial layouts can be drawn (so crowded recipes fail at load time, not mid-run).
"""

from __future__ import annotations

import importlib
import inspect
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from srpb_gym.errors import InputError
from srpb_gym.scenarios.schema import (
    PLACEMENT_GAP,
    ROBOT_RADIUS,
    FormationSpec,
    Place,
    Point,
    Scenario,
    WalkerEntry,
)

RESOLUTION = 0.05  # m, grid cell size
TRIAL_SEEDS = 8  # layouts drawn at load time
SENSOR_CONFIGS = (
    ("lidar", "srpb_gym.perception.lidar", "LidarConfig"),
    ("detector", "srpb_gym.perception.detector", "DetectorConfig"),
    ("tracker", "srpb_gym.perception.tracker", "TrackerConfig"),
)


# --- geometry ------------------------------------------------------------------------------


def segment_distances(x: NDArray | float, y: NDArray | float, seg: NDArray) -> NDArray:
    """Distance [m] from points (x, y) (any shape) to one segment x0, y0, x1, y1."""
    x0, y0, x1, y1 = seg
    dx, dy = x1 - x0, y1 - y0
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0 else np.clip(((x - x0) * dx + (y - y0) * dy) / length2, 0.0, 1.0)
    return np.hypot(x - (x0 + t * dx), y - (y0 + t * dy))


def point_distance(x: float, y: float, segments: NDArray) -> float:
    """Distance [m] from the point (x, y) to the nearest of ``segments`` (S, 4)."""
    if len(segments) == 0:
        return math.inf
    x0, y0, x1, y1 = segments.T
    dx, dy = x1 - x0, y1 - y0
    length2 = np.where(dx * dx + dy * dy > 0, dx * dx + dy * dy, 1.0)
    t = np.clip(((x - x0) * dx + (y - y0) * dy) / length2, 0.0, 1.0)
    return float(np.min(np.hypot(x - (x0 + t * dx), y - (y0 + t * dy))))


def inside_polygon(x: NDArray | float, y: NDArray | float, poly: NDArray) -> NDArray:
    """Whether points (x, y) lie inside the polygon (N, 2) (even-odd rule)."""
    inside = np.zeros(np.broadcast(x, y).shape, dtype=bool)
    for (xa, ya), (xb, yb) in zip(poly, np.roll(poly, -1, axis=0)):
        crosses = (ya > y) != (yb > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cross = xa + (y - ya) * (xb - xa) / (yb - ya)
        inside ^= crosses & (x < x_cross)
    return inside


def crosses_walls(a: Point, b: Point, walls: NDArray) -> bool:
    """Whether the segment a-b properly crosses any wall segment (touching does not count)."""
    if len(walls) == 0:
        return False
    p, q = walls[:, :2], walls[:, 2:]
    a_, b_ = np.asarray(a), np.asarray(b)

    def orient(u: NDArray, v: NDArray, w: NDArray) -> NDArray:
        return np.sign((v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1])
                       - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0]))  # fmt: skip

    d1, d2 = orient(p, q, a_), orient(p, q, b_)
    d3, d4 = orient(a_, b_, p), orient(a_, b_, q)
    proper = (d1 * d2 < 0) & (d3 * d4 < 0)
    return bool(np.any(proper))


def ring_segments(points: Sequence[Point]) -> list[tuple[float, ...]]:
    """The closed chain of edge segments (x0, y0, x1, y1) through ``points``."""
    return [(*points[i - 1], *points[i]) for i in range(len(points))]


def polygon_area(poly: Sequence[Point]) -> float:
    """Signed area of a polygon [m^2] (positive counter-clockwise)."""
    return 0.5 * sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(poly, [*poly[1:], poly[0]]))


def rectangle_corners(center: Point, size: Point, yaw: float) -> tuple[Point, ...]:
    """Corners of a ``size`` = (width, height) rectangle [m] turned by ``yaw`` [rad]."""
    (cx, cy), (w, h), c, s = center, size, math.cos(yaw), math.sin(yaw)
    half = ((-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2))
    return tuple((cx + c * u - s * v, cy + s * u + c * v) for u, v in half)


# --- free space ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class FreeSpace:
    """Clearance field and robot-reachable components of a scenario's world.

    ``clearance[i, j]``: distance [m] from the centre of cell (row i = y, column j = x) to
    the nearest wall, obstacle or bounds edge (0 inside obstacles). ``labels``: connected
    components of the cells the robot fits in (0: it does not). ``robot_labels``: the
    components holding both a start cell and a goal cell of the robot.
    """

    origin: Point
    resolution: float
    clearance: NDArray[np.float64]
    labels: NDArray[np.int32]
    robot_labels: frozenset[int]
    segments: NDArray[np.float64]
    obstacles: tuple[NDArray[np.float64], ...]
    bounds: tuple[float, float, float, float]

    def cell(self, x: float, y: float) -> tuple[int, int] | None:
        """The (row, column) of the cell holding (x, y), or ``None`` outside the grid."""
        j = int((x - self.origin[0]) // self.resolution)
        i = int((y - self.origin[1]) // self.resolution)
        rows, cols = self.clearance.shape
        return (i, j) if 0 <= i < rows and 0 <= j < cols else None

    def exact_clearance(self, x: float, y: float) -> float:
        """Distance [m] from (x, y) to the nearest wall or bounds edge; 0 inside obstacles
        or outside the bounds."""
        xmin, ymin, xmax, ymax = self.bounds
        if not (xmin <= x <= xmax and ymin <= y <= ymax):
            return 0.0
        if any(inside_polygon(x, y, poly) for poly in self.obstacles):
            return 0.0
        return point_distance(x, y, self.segments)

    def is_clear(self, x: float, y: float, radius: float) -> bool:
        """Whether a circle of ``radius`` [m] at (x, y) touches no wall, obstacle or edge."""
        cell = self.cell(x, y)
        if cell is None:
            return False
        slack = self.resolution * math.sqrt(0.5)
        value = self.clearance[cell]
        if value - slack >= radius:
            return True
        if value + slack < radius:
            return False
        return self.exact_clearance(x, y) >= radius

    def label_at(self, x: float, y: float) -> int:
        """The robot component at (x, y): of its cell, else of the nearest neighbour cell."""
        cell = self.cell(x, y)
        if cell is None:
            return 0
        i, j = cell
        if self.labels[i, j]:
            return int(self.labels[i, j])
        best, best_d = 0, math.inf
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                ii, jj = i + di, j + dj
                if 0 <= ii < self.labels.shape[0] and 0 <= jj < self.labels.shape[1]:
                    cx, cy = self.center_of(ii, jj)
                    d = math.hypot(cx - x, cy - y)
                    if self.labels[ii, jj] and d < best_d:
                        best, best_d = int(self.labels[ii, jj]), d
        return best

    def center_of(self, i: int, j: int) -> Point:
        """The centre (x, y) [m] of cell (i, j)."""
        return (
            self.origin[0] + (j + 0.5) * self.resolution,
            self.origin[1] + (i + 0.5) * self.resolution,
        )

    def labels_in(self, place: Place) -> set[int]:
        """The robot components met by a place (the cells whose centres lie in it)."""
        found = {self.label_at(*place.center)}
        if not place.is_point:
            res, (x0, y0) = self.resolution, self.origin
            j0, j1 = (
                math.ceil((place.xmin - x0) / res - 0.5),
                math.floor((place.xmax - x0) / res - 0.5),
            )
            i0, i1 = (
                math.ceil((place.ymin - y0) / res - 0.5),
                math.floor((place.ymax - y0) / res - 0.5),
            )
            rows, cols = self.labels.shape
            block = self.labels[
                max(i0, 0) : min(i1, rows - 1) + 1, max(j0, 0) : min(j1, cols - 1) + 1
            ]
            found.update(int(v) for v in np.unique(block))
        found.discard(0)
        return found


def free_space(scenario: Scenario, resolution: float = RESOLUTION) -> FreeSpace:
    """The :class:`FreeSpace` of a scenario (grid over its bounds)."""
    xmin, ymin, xmax, ymax = scenario.bounds
    cols, rows = (
        max(1, math.ceil((xmax - xmin) / resolution)),
        max(1, math.ceil((ymax - ymin) / resolution)),
    )
    xs = xmin + (np.arange(cols) + 0.5) * resolution
    ys = ymin + (np.arange(rows) + 0.5) * resolution
    X, Y = np.meshgrid(xs, ys)
    edges = np.array([[xmin, ymin, xmax, ymin], [xmax, ymin, xmax, ymax],
                      [xmax, ymax, xmin, ymax], [xmin, ymax, xmin, ymin]])  # fmt: skip
    segments = np.vstack([scenario.walls.reshape(-1, 4), edges])
    clearance = np.full(X.shape, np.inf)
    for seg in segments:
        np.minimum(clearance, segment_distances(X, Y, seg), out=clearance)
    for poly in scenario.obstacles:
        clearance[inside_polygon(X, Y, poly)] = 0.0
    clearance[(xmax < X) | (ymax < Y)] = 0.0
    labels, _ = ndimage.label(clearance > ROBOT_RADIUS)
    space = FreeSpace((xmin, ymin), resolution, clearance, labels.astype(np.int32), frozenset(),
                      segments, scenario.obstacles, scenario.bounds)  # fmt: skip
    start = space.labels_in(scenario.robot.start.place)
    goal = space.labels_in(scenario.robot.goal.place)
    return replace(space, robot_labels=frozenset(start & goal))


# --- checks --------------------------------------------------------------------------------


def validate(scenario: Scenario, trials: int = TRIAL_SEEDS) -> Scenario:
    """Check a scenario (see the module docstring) and return it with its free space."""
    if not scenario.time_limit > 0:
        raise scenario.error("time_limit", f"must be > 0, got {scenario.time_limit}")
    _check_places(scenario)
    space = free_space(scenario)
    _check_robot(scenario, space)
    for formation in scenario.formations:
        _check_formation(scenario, space, formation)
    for entry in scenario.people:
        _check_walkers(scenario, space, entry)
    _check_sensors(scenario)
    prepared = replace(scenario, free_space=space)
    if trials:
        from srpb_gym.scenarios.sampler import sample

        for seed in range(trials):
            sample(prepared, np.random.default_rng(seed))
    return prepared


def _places(scenario: Scenario) -> list[tuple[str, Place]]:
    found = [("robot.start.position", scenario.robot.start.place),
             ("robot.goal.position", scenario.robot.goal.place)]  # fmt: skip
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


def _check_robot(scenario: Scenario, space: FreeSpace) -> None:
    robot = scenario.robot
    for name, pose in (("start", robot.start), ("goal", robot.goal)):
        x, y = pose.place.center
        if not space.is_clear(x, y, ROBOT_RADIUS + PLACEMENT_GAP):
            what = "the point" if pose.place.is_point else "the centre of the region"
            raise scenario.error(
                f"robot.{name}.position",
                f"the robot (radius {ROBOT_RADIUS} m) at {what} ({x:g}, {y:g}) overlaps a wall or "
                f"obstacle or comes within {PLACEMENT_GAP} m of one "
                f"(clearance {space.exact_clearance(x, y):.3f} m)",
            )
    if not space.robot_labels:
        raise scenario.error(
            "robot.goal.position",
            f"the goal is unreachable from the start for a robot of radius {ROBOT_RADIUS} m "
            f"(checked on a {space.resolution:g} m occupancy grid)",
        )
    if robot.start.place.is_point and robot.goal.place.is_point:
        gap = math.dist(robot.start.place.center, robot.goal.place.center)
        if gap <= robot.goal_tolerance:
            raise scenario.error(
                "robot.goal.position",
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


def _check_walkers(scenario: Scenario, space: FreeSpace, entry: WalkerEntry) -> None:
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
        if crosses_walls(a, b, scenario.walls):
            raise scenario.error(
                k, f"the leg from ({a[0]:g}, {a[1]:g}) to ({b[0]:g}, {b[1]:g}) crosses a wall"
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
