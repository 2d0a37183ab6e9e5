"""Frozen dataclasses describing a scenario: the ranges an episode layout is drawn from.

A :class:`Scenario` is what :func:`~srpb_gym.scenarios.loader.load_scenario` builds from a
YAML file (documented in ``envs/README.md``) and what
:func:`~srpb_gym.scenarios.sampler.sample` turns into one
:class:`~srpb_gym.sim.layout.EpisodeLayout` per episode. SI units throughout (m, s, rad);
a range ``(low, high)`` is drawn uniformly, a fixed value is stored as ``(v, v)``.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.errors import InputError
from srpb_gym.scenarios.routes import RouteGraph
from srpb_gym.scenarios.space import Bounds, FreeSpace, Place, Point

# m, circumradius of the default robot (``srpb_gym.sim.robot.RobotConfig().radius``); a
# scenario is validated and sampled for the radius given to ``load_scenario``
DEFAULT_ROBOT_RADIUS = 0.275
ROBOT_RADIUS = DEFAULT_ROBOT_RADIUS  # the former name
PLACEMENT_GAP = 0.05  # m, free gap kept around every body placed at the start of an episode
MIN_FORMATION_MEMBERS = 2
MAX_FORMATION_MEMBERS = 6
MAX_GROUP_SIZE = 4  # walking groups of more than four people split up (Moussaid et al.)
MAX_ROBOTS = 64  # entries of the multi-robot ``robots`` list

Range = tuple[float, float]
IntRange = tuple[int, int]


@dataclass(frozen=True)
class YawSpec:
    """A heading: a range [rad], or the direction from the robot start to its goal."""

    towards_goal: bool = True
    range: Range = (0.0, 0.0)


@dataclass(frozen=True)
class PoseSpec:
    """Where a robot pose is drawn from: a place and a heading."""

    place: Place
    yaw: YawSpec = field(default_factory=YawSpec)


@dataclass(frozen=True)
class RobotSpec:
    """A robot's start and goal and how close to the goal counts as reached [m]."""

    start: PoseSpec
    goal: PoseSpec
    goal_tolerance: float = 0.2


@dataclass(frozen=True)
class WalkerParams:
    """Per-person parameter ranges of walking people (drawn once per person)."""

    # m/s: uniform with mean 1.34 and sd 0.26 m/s, the free walking speeds of Weidmann 1993
    preferred_speed: Range = (0.89, 1.79)
    radius: Range = (0.2, 0.3)  # m, body circle
    relaxation_time: Range = (0.4, 0.6)  # s
    robot_reaction: Range = (1.0, 1.0)  # 0 ignores robots, 1 nominal


@dataclass(frozen=True)
class WalkerEntry:
    """One ``people`` entry: walkers on a fixed route, or spawned with a random goal.

    Route entries (``route`` set): ``count`` units walk the route one after another; the
    last unit starts at the first waypoint, each earlier one ``spacing`` metres further
    along the route, and unit k starts ``k * headway`` seconds after the first.
    ``waypoint_jitter`` [m] shifts every waypoint uniformly per axis per episode.
    Spawn entries (``spawn`` set): ``count`` units start anywhere in ``spawn`` and walk via
    ``via`` to a point drawn from ``goal`` (and back again with ``loop``).
    A unit is one person, or a walking group of ``group_size`` people walking abreast.
    """

    index: int
    route: tuple[Point, ...] = ()
    spawn: Place | None = None
    goal: Place | None = None
    via: tuple[Point, ...] = ()
    count: IntRange = (1, 1)
    spacing: Range = (1.0, 1.0)  # m
    headway: Range = (0.0, 0.0)  # s
    waypoint_jitter: float = 0.0  # m
    start_delay: Range = (0.0, 0.0)  # s
    loop: bool = False
    group_size: IntRange = (1, 1)
    params: WalkerParams = field(default_factory=WalkerParams)

    @property
    def key(self) -> str:
        """The dotted key of the entry in the scenario file."""
        return f"people[{self.index}]"

    @property
    def is_route(self) -> bool:
        """True for a fixed-route entry, False for a spawn entry."""
        return bool(self.route)


@dataclass(frozen=True)
class FormationSpec:
    """One standing F-formation: members evenly spread on a circle, facing its centre.

    ``radius``: radius of the member circle [m]; ``orientation``: angle of the first member
    seen from the centre [rad]; ``body_radius``: members' body circle [m]; ``jitter``: the
    standard deviation of the members' small motion [m].
    """

    index: int
    center: Place
    members: IntRange = (2, 2)
    radius: Range = (0.6, 0.8)
    orientation: Range = (-np.pi, np.pi)
    jitter: float = 0.02
    body_radius: Range = (0.2, 0.3)

    @property
    def key(self) -> str:
        """The dotted key of the entry in the scenario file."""
        return f"formations[{self.index}]"

    @property
    def extent(self) -> float:
        """The largest distance from the centre to a member's body edge [m]."""
        return self.radius[1] + self.body_radius[1]


@dataclass(frozen=True)
class SensorSpecs:
    """Raw sensor specs (a preset name, a mapping or ``None`` for the default)."""

    lidar: str | Mapping[str, Any] | None = None
    detector: str | Mapping[str, Any] | None = None
    tracker: Mapping[str, Any] | None = None


@dataclass(frozen=True, eq=False)
class Scenario:
    """A navigation scenario: a static world and the recipes of its episodes.

    ``walls``: (S, 4) read-only array of wall segments x0, y0, x1, y1 [m], including the
    edges of the obstacles and, with ``enclose``, of the bounds. ``obstacles``: the solid
    polygons (each an (N, 2) array of vertices) whose edges are in ``walls``.
    ``robot``: the start and goal of the single robot; ``robots``: the start and goal of
    robot i when several robots share the world (empty: one robot only).
    ``reward``: the scenario's weights over the packaged reward presets, by preset name
    (``{"srpb": {"psi": -5.0, ...}}``): an environment on this scenario with that preset
    starts from the preset's weights with these replacing theirs.
    ``robot_radius``: the radius [m] of the robots the scenario is validated and sampled for
    (their clearance from walls, the reachability of their goals).
    ``source`` and ``lines`` locate keys in the file for error messages;
    ``free_space`` (for ``robot_radius``) and ``routes`` (the walking routes around walls,
    for the largest body radius of the people) are precomputed by
    :func:`~srpb_gym.scenarios.validate.validate`.
    """

    name: str
    walls: NDArray[np.float64]
    robot: RobotSpec
    bounds: Bounds
    description: str = ""
    time_limit: float = 60.0  # s
    obstacles: tuple[NDArray[np.float64], ...] = ()
    people: tuple[WalkerEntry, ...] = ()
    formations: tuple[FormationSpec, ...] = ()
    robots: tuple[RobotSpec, ...] = ()
    sensors: SensorSpecs = field(default_factory=SensorSpecs)
    reward: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    robot_radius: float = DEFAULT_ROBOT_RADIUS  # m
    source: str | None = None
    lines: Mapping[str, int] = field(default_factory=dict, repr=False)
    free_space: FreeSpace | None = field(default=None, repr=False)
    routes: RouteGraph | None = field(default=None, repr=False)

    @property
    def largest_person_radius(self) -> float:
        """The largest body radius [m] of the walking people (0 without people)."""
        return max((entry.params.radius[1] for entry in self.people), default=0.0)

    def error(self, key: str, message: str) -> InputError:
        """An :class:`InputError` about ``key`` located in the scenario file."""
        return located_error(message, self.source, self.lines, key)

    @property
    def max_robots(self) -> int:
        """How many robots the scenario places: its ``robots`` entries, else one."""
        return max(len(self.robots), 1)

    def robot_specs(self, n_robots: int = 1) -> tuple[RobotSpec, ...]:
        """The entries ``n_robots`` robots start from: ``(robot,)`` for one robot, else the
        first ``n_robots`` of ``robots``; an :class:`InputError` (key ``n_robots``) when the
        scenario has fewer places."""
        whole = isinstance(n_robots, numbers.Integral) and not isinstance(n_robots, bool)
        if not whole or n_robots < 1:
            raise InputError(f"expected a whole number >= 1, got {n_robots!r}", key="n_robots")
        limit = self.max_robots
        if n_robots > limit:
            raise InputError(
                f"scenario {self.name!r} has places for at most {limit} "
                f"robot{'s' if limit > 1 else ''}, got {n_robots}",
                key="n_robots",
            )
        return (self.robot,) if n_robots == 1 else self.robots[: int(n_robots)]

    def route_spec(self, route: int) -> RobotSpec:
        """The entry ``robots[route]`` that a single robot drives (an :class:`InputError`,
        key ``route``, when the scenario has no such entry)."""
        whole = isinstance(route, numbers.Integral) and not isinstance(route, bool)
        if not whole or not 0 <= route < len(self.robots):
            places = (f"its robots entries 0-{len(self.robots) - 1}" if self.robots
                      else "no robots entries")  # fmt: skip
            raise InputError(f"scenario {self.name!r} has {places}, got {route!r}", key="route")
        return self.robots[int(route)]

    @staticmethod
    def robot_key(index: int, n_robots: int) -> str:
        """The dotted key of robot ``index``'s entry: ``robot`` alone, else ``robots[i]``."""
        return "robot" if n_robots == 1 else f"robots[{index}]"


def line_of(lines: Mapping[str, int], key: str) -> int | None:
    """The line recorded for ``key``, else for the nearest enclosing key, else ``None``."""
    while key:
        if key in lines:
            return lines[key]
        cut = max(key.rfind("."), key.rfind("["))
        key = key[:cut] if cut > 0 else ""
    return lines.get("")


def located_error(
    message: str, source: str | None, lines: Mapping[str, int], key: str
) -> InputError:
    """An :class:`InputError` reading ``file:line: key: message`` when the line is known."""
    line = line_of(lines, key)
    if line is None:
        return InputError(message, source, key=key or None)
    return InputError(f"{key}: {message}" if key else message, source, line=line, key=key or None)


def checked_robot_radius(radius: Any, source: str | None = None) -> float:
    """``radius`` [m] as a float, or an :class:`InputError` (key ``robot_radius``) unless it
    is a finite number > 0."""
    number = isinstance(radius, numbers.Real) and not isinstance(radius, bool)
    if not (number and math.isfinite(radius) and radius > 0):
        raise InputError(f"must be a number > 0 [m], got {radius!r}", source, key="robot_radius")
    return float(radius)
