"""Drawing one :class:`~srpb_gym.sim.layout.EpisodeLayout` from a scenario.

``sample(scenario, rng, n_robots)`` draws, in this order and only from ``rng``:

1. each robot's start (its circle of ``scenario.robot_radius`` ``GAP`` clear of walls, in
   a component that reaches its goal place) and goal (likewise clear, in the start's
   component, farther than ``goal_tolerance``), then their yaws. One robot starts from
   the scenario's ``robot`` entry; ``n_robots >= 2`` robots from its first ``robots``
   entries, robot i from entry i, each start and goal keeping ``ROBOTS_GAP`` from the
   circles of the other robots' starts and goals drawn before it;
2. each F-formation: centre, member count, circle radius, orientation and body radius;
   every member must keep ``GAP`` from walls and the formation's circle (member circle
   plus a body radius) must not overlap a robot start or goal or an earlier formation;
3. each ``people`` entry in file order: the number of units (people or walking groups),
   then every unit's placement and parameters. People keep ``GAP`` from walls, each other
   and formation circles and ``ROBOT_GAP`` from every robot start.

A leg of a person's route that the body cannot walk in a straight line (it would come
closer than ``GAP`` to a wall) gets the corners of the shortest way around the walls
inserted (:class:`~srpb_gym.scenarios.routes.RouteGraph`, computed once per scenario); a
fixed route is first walked that way for the largest body radius, and its people are
placed along it. This takes nothing from ``rng``. A unit whose route has no way around the
walls does not fit and is drawn again.

Random placements are retried up to ``MAX_TRIES`` times per robot point or unit; several
robots are redrawn together up to ``ROBOTS_TRIES`` times, a route entry as a whole up to
``ENTRY_TRIES`` times. Then a located :class:`~srpb_gym.errors.InputError`
names the entry that could not be placed.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np

from srpb_gym.angles import wrap_angle
from srpb_gym.errors import InputError
from srpb_gym.scenarios.routes import RouteGraph, route_graph
from srpb_gym.scenarios.schema import (
    PLACEMENT_GAP,
    Range,
    RobotSpec,
    Scenario,
    WalkerEntry,
    YawSpec,
)
from srpb_gym.scenarios.space import FreeSpace, Point, free_space
from srpb_gym.sim.layout import EpisodeLayout, FormationLayout, PersonLayout, RobotLayout

MAX_TRIES = 200  # random placements per robot pose, formation or walking unit
ENTRY_TRIES = 50  # redraws of a whole route entry
ROBOTS_TRIES = 20  # redraws of all the robots' starts and goals when one does not fit
GAP = PLACEMENT_GAP  # m, smallest gap between bodies, and from bodies to walls, at the start
ROBOT_GAP = 0.3  # m, smallest gap between a person and a robot at the start
ROBOTS_GAP = 0.3  # m, smallest gap between two robots' start and goal circles
GROUP_GAP = 0.2  # m, gap between the bodies of neighbours in a walking group


class _Discs:
    """Occupied circles (x, y, radius) with cheap roll-back."""

    def __init__(self) -> None:
        self.items: list[tuple[float, float, float]] = []

    def add(self, x: float, y: float, r: float) -> None:
        self.items.append((x, y, r))

    def free(self, x: float, y: float, r: float, gap: float = GAP) -> bool:
        return all((x - a) ** 2 + (y - b) ** 2 >= (r + c + gap) ** 2 for a, b, c in self.items)

    def truncate(self, size: int) -> None:
        del self.items[size:]


class _Context:
    """What the placement steps share while one layout is drawn."""

    def __init__(self, scenario: Scenario, space: FreeSpace, rng: np.random.Generator) -> None:
        self.scenario, self.space, self.rng = scenario, space, rng
        self.discs = _Discs()
        self.people: list[PersonLayout] = []
        self.groups = 0
        self._routes: RouteGraph | None = None

    @property
    def routes(self) -> RouteGraph:
        """The scenario's walking routes around walls (computed on first use)."""
        if self._routes is None:
            self._routes = routes_of(self.scenario)
        return self._routes

    def uniform(self, bounds: Range) -> float:
        lo, hi = bounds
        return lo if lo == hi else float(self.rng.uniform(lo, hi))

    def integer(self, bounds: tuple[int, int]) -> int:
        lo, hi = bounds
        return lo if lo == hi else int(self.rng.integers(lo, hi + 1))

    def fits(self, x: float, y: float, r: float) -> bool:
        return self.space.is_clear(x, y, r + GAP) and self.discs.free(x, y, r)


def sample(
    scenario: Scenario, rng: np.random.Generator, n_robots: int = 1, route: int | None = None
) -> EpisodeLayout:
    """One episode layout drawn from ``scenario`` with ``rng`` (see the module docstring),
    for ``n_robots`` robots of ``scenario.robot_radius`` [m].

    One robot starts from ``scenario.robot``, or with ``route=i`` from
    ``scenario.robots[i]``; several from ``scenario.robots[:n_robots]`` (more than
    ``scenario.max_robots`` is an :class:`~srpb_gym.errors.InputError`, key ``n_robots``;
    a ``route`` the scenario has no entry for, key ``route``). ``layout.goal_tolerance``
    is the first robot's. ``layout.walls`` is the
    scenario's read-only wall array (shared, not copied). A scenario that did not go
    through :func:`~srpb_gym.scenarios.validate.validate` for its robot radius has its free
    space computed on every call (slow); load scenarios with ``load_scenario``.
    """
    specs = scenario.robot_specs(n_robots)
    keys = tuple(Scenario.robot_key(i, n_robots) for i in range(n_robots))
    if route is not None:
        if n_robots != 1:
            raise InputError("a route is for a single robot", key="route")
        specs, keys = (scenario.route_spec(route),), (f"robots[{route}]",)
    ctx = _Context(scenario, free_space_of(scenario), rng)
    robots = _robots(ctx, specs, keys, between=n_robots > 1 or route is not None)
    for robot in robots:
        ctx.discs.add(robot.start[0], robot.start[1], scenario.robot_radius + ROBOT_GAP - GAP)
    formations = _formations(ctx, [robot.goal[:2] for robot in robots])
    for entry in scenario.people:
        (_route_entry if entry.is_route else _spawn_entry)(ctx, entry)
    return EpisodeLayout(
        walls=scenario.walls,
        robots=robots,
        people=tuple(ctx.people),
        formations=formations,
        time_limit=scenario.time_limit,
        goal_tolerance=specs[0].goal_tolerance,
        bounds=scenario.bounds,
        metadata={"scenario": scenario.name},
        doors=ctx.routes.doors if scenario.people else np.zeros((0, 6)),
    )


def free_space_of(scenario: Scenario) -> FreeSpace:
    """The free space of a scenario's world for its robot radius: the one attached by
    :func:`~srpb_gym.scenarios.validate.validate` when it is for that radius, else computed
    now (a 5 cm grid, tens of milliseconds)."""
    space = scenario.free_space
    if space is not None and space.robot_radius == scenario.robot_radius:
        return space
    robot = scenario.robot
    return free_space(scenario.bounds, scenario.walls, scenario.obstacles,
                      scenario.robot_radius, robot.start.place, robot.goal.place)  # fmt: skip


def routes_of(scenario: Scenario) -> RouteGraph:
    """The walking routes of a scenario's world for the largest body radius of its people:
    the ones attached by :func:`~srpb_gym.scenarios.validate.validate`, else computed now
    (milliseconds)."""
    radius = scenario.largest_person_radius
    routes = scenario.routes
    if routes is not None and routes.radius == radius:
        return routes
    return route_graph(scenario.bounds, scenario.walls, scenario.obstacles, radius, GAP)


def _yaw(ctx: _Context, spec: YawSpec, towards: float) -> float:
    return towards if spec.towards_goal else float(wrap_angle(ctx.uniform(spec.range)))


def _robots(
    ctx: _Context, specs: tuple[RobotSpec, ...], keys: tuple[str, ...], between: bool
) -> tuple[RobotLayout, ...]:
    """The robots' starts and goals, robot i from ``specs[i]`` (its entry's key
    ``keys[i]``), each clear of the others; several robots are all drawn again when one of
    them does not fit. ``between``: each start and goal in a component of the free space
    that both of its entry's places meet (else those of the free space's own robot, the
    scenario's ``robot``)."""
    redraws = 1 if len(specs) == 1 else ROBOTS_TRIES
    for _ in range(redraws - 1):
        try:
            return _draw_robots(ctx, specs, keys, between, redraws)
        except InputError:
            pass
    return _draw_robots(ctx, specs, keys, between, redraws)


def _draw_robots(
    ctx: _Context, specs: tuple[RobotSpec, ...], keys: tuple[str, ...], between: bool,
    redraws: int,
) -> tuple[RobotLayout, ...]:  # fmt: skip
    space, radius = ctx.space, ctx.scenario.robot_radius
    placed = _Discs()  # the start and goal circles of the robots drawn so far
    out = []
    for spec, key in zip(specs, keys):
        labels = space.robot_labels
        if between:
            labels = space.labels_between(spec.start.place, spec.goal.place)
        robot = _robot(ctx, spec, key, labels, placed, redraws)
        for x, y, _ in (robot.start, robot.goal):
            placed.add(x, y, radius)
        out.append(robot)
    return tuple(out)


def _robot(
    ctx: _Context, spec: RobotSpec, key: str, labels: frozenset[int], placed: _Discs,
    redraws: int,
) -> RobotLayout:  # fmt: skip
    space = ctx.space

    def reaching(x: float, y: float) -> bool:
        return space.label_at(x, y) in labels

    start = _draw_robot_point(ctx, spec, key, "start", reaching, placed, redraws)
    label = space.label_at(*start)

    def near_goal(x: float, y: float) -> bool:
        far = math.dist(start, (x, y)) > spec.goal_tolerance
        return far and space.label_at(x, y) == label

    goal = _draw_robot_point(ctx, spec, key, "goal", near_goal, placed, redraws)
    towards = math.atan2(goal[1] - start[1], goal[0] - start[0])
    return RobotLayout(
        start=(start[0], start[1], _yaw(ctx, spec.start.yaw, towards)),
        goal=(goal[0], goal[1], _yaw(ctx, spec.goal.yaw, towards)),
    )


def _draw_robot_point(
    ctx: _Context, spec: RobotSpec, key: str, name: str,
    accept: Callable[[float, float], bool], placed: _Discs, redraws: int,
) -> Point:  # fmt: skip
    """A start or goal point of ``spec`` clear of walls and of the ``placed`` robots."""
    place, radius = getattr(spec, name).place, ctx.scenario.robot_radius
    tries = MAX_TRIES if not place.is_point else 1
    for _ in range(tries):
        x, y = place.draw(ctx.rng)
        clear = ctx.space.is_clear(x, y, radius + GAP) and placed.free(x, y, radius, ROBOTS_GAP)
        if clear and accept(x, y):
            return (x, y)
    others = placed.items and f", {ROBOTS_GAP:g} m clear of the other robots' starts and goals"
    again = redraws > 1 and f"; all robots drawn {redraws} times"
    raise ctx.scenario.error(
        f"{key}.{name}.position",
        f"could not draw a {name} for a robot of radius {radius:g} m clear of walls{others or ''} "
        f"and reachable ({tries} tries{again or ''})",
    )


def _formations(ctx: _Context, goals: list[Point]) -> tuple[FormationLayout, ...]:
    out = []
    goal_disc = _Discs()
    for goal in goals:
        goal_disc.add(goal[0], goal[1], ctx.scenario.robot_radius)
    for spec in ctx.scenario.formations:
        for _ in range(MAX_TRIES):
            cx, cy = spec.center.draw(ctx.rng)
            n, radius = ctx.integer(spec.members), ctx.uniform(spec.radius)
            phi, body = ctx.uniform(spec.orientation), ctx.uniform(spec.body_radius)
            angles = phi + 2.0 * math.pi * np.arange(n) / n
            members = [(cx + radius * math.cos(a), cy + radius * math.sin(a)) for a in angles]
            extent = radius + body
            if not (ctx.discs.free(cx, cy, extent) and goal_disc.free(cx, cy, extent)):
                continue
            if all(ctx.space.is_clear(x, y, body + GAP) for x, y in members):
                ctx.discs.add(cx, cy, extent)
                out.append(FormationLayout((cx, cy), tuple(members), body, spec.jitter))
                break
        else:
            raise ctx.scenario.error(
                spec.key,
                f"could not place this F-formation clear of walls, the robot starts and goals "
                f"and other formations in {MAX_TRIES} tries; enlarge its centre region",
            )
    return tuple(out)


# --- walking people ------------------------------------------------------------------------


def _unit(
    ctx: _Context, entry: WalkerEntry, anchor: Point, route: tuple[Point, ...],
    size: int, delay: float,
) -> list[PersonLayout] | None:  # fmt: skip
    """A walking unit (one person, or a group abreast) at ``anchor`` facing its route, or
    ``None`` when a member does not fit (nothing is committed then)."""
    p = entry.params
    radii = [ctx.uniform(p.radius) for _ in range(size)]
    walked = _walk(ctx, anchor, route, entry.loop, max(radii))
    if walked is None:
        return None
    target = walked[0] if math.dist(anchor, walked[0]) > 1e-9 else walked[min(1, len(walked) - 1)]
    heading = math.atan2(target[1] - anchor[1], target[0] - anchor[0])
    side = (-math.sin(heading), math.cos(heading))
    step = 2.0 * max(radii) + GROUP_GAP
    speed = ctx.uniform(p.preferred_speed)  # a group walks at one speed
    group = ctx.groups if size > 1 else -1
    mark, members = len(ctx.discs.items), []
    for k, r in enumerate(radii):
        offset = (k - 0.5 * (size - 1)) * step
        x, y = anchor[0] + offset * side[0], anchor[1] + offset * side[1]
        own = walked
        if offset != 0.0:
            own = _walk(ctx, (x, y), _member_route(ctx, entry, route, offset, r, (x, y)),
                        entry.loop, r)  # fmt: skip
        if own is None or not ctx.fits(x, y, r):
            ctx.discs.truncate(mark)
            return None
        ctx.discs.add(x, y, r)
        members.append(PersonLayout(
            position=(x, y), yaw=heading, route=own, loop=entry.loop, preferred_speed=speed,
            radius=r,
            relaxation_time=ctx.uniform(p.relaxation_time),
            robot_reaction=ctx.uniform(p.robot_reaction), group=group, start_delay=delay,
        ))  # fmt: skip
    ctx.groups += size > 1
    return members


def _member_route(
    ctx: _Context, entry: WalkerEntry, route: tuple[Point, ...], offset: float,
    r: float, start: Point,
) -> tuple[Point, ...]:  # fmt: skip
    """A group member's own route: the goal moved ``offset`` metres sideways (members keep
    their places abreast there) when that point is clear; a looping spawn route returns to
    the member's own start. Via points and looping routes are shared."""
    if offset == 0.0 or (entry.is_route and entry.loop):
        return route
    at = len(entry.via) if not entry.is_route else len(route) - 1
    end = route[at]
    before = route[at - 1] if at > 0 else start
    heading = math.atan2(end[1] - before[1], end[0] - before[0])
    x, y = end[0] - offset * math.sin(heading), end[1] + offset * math.cos(heading)
    own = list(route)
    if ctx.space.is_clear(x, y, r):
        own[at] = (x, y)
    if entry.loop:
        own[-1] = start
    return tuple(own)


def _polyline(
    ctx: _Context, points: tuple[Point, ...], loop: bool, radius: float
) -> list[Point] | None:
    """``points`` with the corners around walls inserted into every leg (and, for a loop,
    the corners of the leg back to the first point appended), for a body of ``radius``
    [m]; ``None`` when a leg has no way around the walls."""
    out = [points[0]]
    legs = list(itertools.pairwise(points))
    if loop and len(points) > 1:
        legs.append((points[-1], points[0]))
    for k, (a, b) in enumerate(legs):
        corners = ctx.routes.route(a, b, radius)
        if corners is None:
            return None
        out.extend(corners)
        if k < len(points) - 1:
            out.append(b)
    return out


def _walk(
    ctx: _Context, start: Point, route: tuple[Point, ...], loop: bool, radius: float
) -> tuple[Point, ...] | None:
    """A person's route from ``start`` with the corners around walls (:func:`_polyline`);
    a looping route repeats from its first corner, so the leg from ``start`` must turn at
    the same corners as the leg that closes the loop (``None`` otherwise, or without a way
    around the walls)."""
    walked = _polyline(ctx, (start, *route), False, radius)
    if walked is None:
        return None
    if loop and len(route) > 1:
        closing = ctx.routes.route(route[-1], route[0], radius)
        if closing is None or tuple(walked[1 : 2 + len(closing)]) != (*closing, route[0]):
            return None
    return tuple(walked[1:])


def _spawn_entry(ctx: _Context, entry: WalkerEntry) -> None:
    assert entry.spawn is not None and entry.goal is not None
    for number in range(ctx.integer(entry.count)):
        size, delay = ctx.integer(entry.group_size), ctx.uniform(entry.start_delay)
        for _ in range(MAX_TRIES):
            anchor, goal = entry.spawn.draw(ctx.rng), entry.goal.draw(ctx.rng)
            if not ctx.space.is_clear(goal[0], goal[1], entry.params.radius[1]):
                continue
            route = (*entry.via, goal)
            if entry.loop:
                route = (*route, *reversed(entry.via), anchor)
            members = _unit(ctx, entry, anchor, route, size, delay)
            if members is not None:
                ctx.people.extend(members)
                break
        else:
            what = "person" if size == 1 else f"group of {size}"
            raise ctx.scenario.error(
                entry.key,
                f"could not place {what} {number + 1} clear of walls, other people, F-formations "
                f"and the robot starts, with a way around the walls to its goal, in {MAX_TRIES} "
                "tries; enlarge the spawn region or lower count",
            )


def _route_entry(ctx: _Context, entry: WalkerEntry) -> None:
    mark, groups, people = len(ctx.discs.items), ctx.groups, len(ctx.people)
    for _ in range(ENTRY_TRIES):
        if _try_route_entry(ctx, entry):
            return
        ctx.discs.truncate(mark)
        ctx.groups = groups
        del ctx.people[people:]
    raise ctx.scenario.error(
        entry.key,
        f"could not place the people of this route clear of walls, each other, F-formations "
        f"and the robot starts in {ENTRY_TRIES} tries; raise spacing or lower count",
    )


def _try_route_entry(ctx: _Context, entry: WalkerEntry) -> bool:
    route = np.asarray(entry.route, dtype=np.float64)
    if entry.waypoint_jitter > 0:
        route = route + ctx.rng.uniform(-entry.waypoint_jitter, entry.waypoint_jitter, route.shape)
    points = tuple((float(x), float(y)) for x, y in route)
    walked = _polyline(ctx, points, entry.loop, entry.params.radius[1])
    if walked is None:
        return False
    route = np.asarray(walked, dtype=np.float64)
    units, spacing = ctx.integer(entry.count), ctx.uniform(entry.spacing)
    headway, delay = ctx.uniform(entry.headway), ctx.uniform(entry.start_delay)
    for k in range(units):  # k = 0 leads, the last unit starts at the first waypoint
        anchor, rest = _along(route, (units - 1 - k) * spacing, entry.loop)
        members = _unit(
            ctx, entry, anchor, rest, ctx.integer(entry.group_size), delay + k * headway
        )
        if members is None:
            return False
        ctx.people.extend(members)
    return True


def _along(route: np.ndarray, distance: float, loop: bool) -> tuple[Point, tuple[Point, ...]]:
    """The point ``distance`` metres along ``route`` and the waypoints still ahead of it
    (for a loop, the whole cycle starting with the next waypoint)."""
    points = [tuple(map(float, p)) for p in route]
    for i in range(len(points) - 1):
        a, b = points[i], points[i + 1]
        length = math.dist(a, b)
        if distance < length or i == len(points) - 2:
            t = min(distance / length, 1.0) if length > 0 else 0.0
            here = (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))
            ahead = points[i + 1 :] + (points[: i + 1] if loop else [])
            return here, tuple(ahead)
        distance -= length
    raise ValueError("a route needs at least two waypoints")
