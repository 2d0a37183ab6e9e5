"""Drawing one :class:`~srpb_gym.sim.layout.EpisodeLayout` from a scenario.

``sample(scenario, rng)`` draws, in this order and only from ``rng``:

1. the robot start (its circle of ``scenario.robot_radius`` ``GAP`` clear of walls, in a
   component that reaches the goal place) and goal (likewise clear, in the start's
   component, farther than ``goal_tolerance``), then their yaws;
2. each F-formation: centre, member count, circle radius, orientation and body radius;
   every member must keep ``GAP`` from walls and the formation's circle (member circle
   plus a body radius) must not overlap the robot start or goal or an earlier formation;
3. each ``people`` entry in file order: the number of units (people or walking groups),
   then every unit's placement and parameters. People keep ``GAP`` from walls, each other
   and formation circles and ``ROBOT_GAP`` from the robot start.

Random placements are retried up to ``MAX_TRIES`` times per unit; a route entry is redrawn
as a whole up to ``ENTRY_TRIES`` times. Then a located :class:`~srpb_gym.errors.InputError`
names the entry that could not be placed.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from srpb_gym.angles import wrap_angle
from srpb_gym.scenarios.schema import PLACEMENT_GAP, Range, Scenario, WalkerEntry, YawSpec
from srpb_gym.scenarios.space import FreeSpace, Point, free_space
from srpb_gym.sim.layout import EpisodeLayout, FormationLayout, PersonLayout, RobotLayout

MAX_TRIES = 200  # random placements per robot pose, formation or walking unit
ENTRY_TRIES = 50  # redraws of a whole route entry
GAP = PLACEMENT_GAP  # m, smallest gap between bodies, and from bodies to walls, at the start
ROBOT_GAP = 0.3  # m, smallest gap between a person and the robot at the start
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

    def uniform(self, bounds: Range) -> float:
        lo, hi = bounds
        return lo if lo == hi else float(self.rng.uniform(lo, hi))

    def integer(self, bounds: tuple[int, int]) -> int:
        lo, hi = bounds
        return lo if lo == hi else int(self.rng.integers(lo, hi + 1))

    def fits(self, x: float, y: float, r: float) -> bool:
        return self.space.is_clear(x, y, r + GAP) and self.discs.free(x, y, r)


def sample(scenario: Scenario, rng: np.random.Generator) -> EpisodeLayout:
    """One episode layout drawn from ``scenario`` with ``rng`` (see the module docstring),
    for a robot of ``scenario.robot_radius`` [m].

    ``layout.walls`` is the scenario's read-only wall array (shared, not copied). A scenario
    that did not go through :func:`~srpb_gym.scenarios.validate.validate` for its robot
    radius has its free space computed on every call (slow); load scenarios with
    ``load_scenario``.
    """
    ctx = _Context(scenario, free_space_of(scenario), rng)
    robot = _robot(ctx)
    ctx.discs.add(robot.start[0], robot.start[1], scenario.robot_radius + ROBOT_GAP - GAP)
    formations = _formations(ctx, robot.goal[:2])
    for entry in scenario.people:
        (_route_entry if entry.is_route else _spawn_entry)(ctx, entry)
    return EpisodeLayout(
        walls=scenario.walls,
        robots=(robot,),
        people=tuple(ctx.people),
        formations=formations,
        time_limit=scenario.time_limit,
        goal_tolerance=scenario.robot.goal_tolerance,
        bounds=scenario.bounds,
        metadata={"scenario": scenario.name},
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


def _yaw(ctx: _Context, spec: YawSpec, towards: float) -> float:
    return towards if spec.towards_goal else float(wrap_angle(ctx.uniform(spec.range)))


def _robot(ctx: _Context) -> RobotLayout:
    spec, space = ctx.scenario.robot, ctx.space
    start = _draw_robot_point(ctx, "start", lambda x, y: space.label_at(x, y) in space.robot_labels)
    label = space.label_at(*start)

    def near_goal(x: float, y: float) -> bool:
        far = math.dist(start, (x, y)) > spec.goal_tolerance
        return far and space.label_at(x, y) == label

    goal = _draw_robot_point(ctx, "goal", near_goal)
    towards = math.atan2(goal[1] - start[1], goal[0] - start[0])
    return RobotLayout(
        start=(start[0], start[1], _yaw(ctx, spec.start.yaw, towards)),
        goal=(goal[0], goal[1], _yaw(ctx, spec.goal.yaw, towards)),
    )


def _draw_robot_point(ctx: _Context, name: str, accept: Callable[[float, float], bool]) -> Point:
    place = getattr(ctx.scenario.robot, name).place
    for _ in range(MAX_TRIES if not place.is_point else 1):
        x, y = place.draw(ctx.rng)
        if ctx.space.is_clear(x, y, ctx.scenario.robot_radius + GAP) and accept(x, y):
            return (x, y)
    raise ctx.scenario.error(
        f"robot.{name}.position",
        f"could not draw a {name} for a robot of radius {ctx.scenario.robot_radius:g} m clear "
        f"of walls and reachable ({MAX_TRIES if not place.is_point else 1} tries)",
    )


def _formations(ctx: _Context, goal: Point) -> tuple[FormationLayout, ...]:
    out = []
    goal_disc = _Discs()
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
                f"could not place this F-formation clear of walls, the robot start and goal and "
                f"other formations in {MAX_TRIES} tries; enlarge its centre region",
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
    target = route[0] if math.dist(anchor, route[0]) > 1e-9 else route[min(1, len(route) - 1)]
    heading = math.atan2(target[1] - anchor[1], target[0] - anchor[0])
    side = (-math.sin(heading), math.cos(heading))
    step = 2.0 * max(radii) + GROUP_GAP
    speed = ctx.uniform(p.preferred_speed)  # a group walks at one speed
    group = ctx.groups if size > 1 else -1
    mark, members = len(ctx.discs.items), []
    for k, r in enumerate(radii):
        offset = (k - 0.5 * (size - 1)) * step
        x, y = anchor[0] + offset * side[0], anchor[1] + offset * side[1]
        if not ctx.fits(x, y, r):
            ctx.discs.truncate(mark)
            return None
        ctx.discs.add(x, y, r)
        members.append(PersonLayout(
            position=(x, y), yaw=heading, route=_member_route(ctx, entry, route, offset, r, (x, y)),
            loop=entry.loop, preferred_speed=speed, radius=r,
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
                f"and the robot start in {MAX_TRIES} tries; enlarge the spawn region or lower "
                "count",
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
        f"and the robot start in {ENTRY_TRIES} tries; raise spacing or lower count",
    )


def _try_route_entry(ctx: _Context, entry: WalkerEntry) -> bool:
    route = np.asarray(entry.route, dtype=np.float64)
    if entry.waypoint_jitter > 0:
        route = route + ctx.rng.uniform(-entry.waypoint_jitter, entry.waypoint_jitter, route.shape)
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
