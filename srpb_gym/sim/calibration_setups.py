"""Set-ups of the crowd calibration (:mod:`srpb_gym.sim.calibration`): rooms, people, and
the environment's stepping of people without a robot.

:func:`simulate` steps a :class:`~srpb_gym.sim.crowd.Crowd` in a
:class:`~srpb_gym.sim.world.World` as ``srpb_gym.simulation.Simulation`` does (one crowd
update per control step of :data:`CONTROL_DT`, then physics substeps of
:data:`PHYSICS_DT`, then the crowd takes the simulated state back) with no robot. The
rooms are a ring corridor (:func:`ring_walls`) and a straight one
(:func:`corridor_walls`); people are spread over them without overlaps (:func:`spread`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from srpb_gym.sim.crowd import Crowd, SocialForceConfig
from srpb_gym.sim.layout import PersonLayout
from srpb_gym.sim.world import World

CONTROL_DT = 0.1  # [s] SimConfig().control_dt
PHYSICS_DT = 0.025  # [s] SimConfig().physics_dt
GROUP_GAP = 0.2  # [m] gap between the bodies of neighbours in a walking group (the sampler's)


@dataclass(frozen=True)
class Walkers:
    """Per-person parameter ranges, each drawn uniformly (the scenario defaults)."""

    preferred_speed: tuple[float, float] = (0.89, 1.79)  # m/s
    radius: tuple[float, float] = (0.2, 0.3)  # m
    relaxation_time: tuple[float, float] = (0.4, 0.6)  # s

    def draw(self, rng: np.random.Generator, n: int) -> tuple[NDArray[np.float64], ...]:
        """(speeds, radii, relaxation times) of ``n`` people."""
        return tuple(rng.uniform(lo, hi, n) for lo, hi in
                     (self.preferred_speed, self.radius, self.relaxation_time))  # fmt: skip


DEFAULT_WALKERS = Walkers()


@dataclass(frozen=True)
class Trajectories:
    """Positions (T + 1, P, 2) [m] at every control step, from the start."""

    xy: NDArray[np.float64]
    dt: float

    @property
    def velocity(self) -> NDArray[np.float64]:
        """(T, P, 2) mean velocity [m/s] over each control step."""
        return np.diff(self.xy, axis=0) / self.dt


def simulate(
    people: Sequence[PersonLayout], walls: NDArray[np.float64], duration: float,
    config: SocialForceConfig | None = None, rng: np.random.Generator | None = None,
    control_dt: float = CONTROL_DT, physics_dt: float = PHYSICS_DT,
) -> Trajectories:  # fmt: skip
    """People on their routes among ``walls`` (S, 4) for ``duration`` seconds, stepped as
    the environment steps them (``Simulation._advance_physics``) with no robot."""
    rng = rng if rng is not None else np.random.default_rng(0)
    walls = np.ascontiguousarray(np.asarray(walls, dtype=np.float64).reshape(-1, 4))
    crowd = Crowd(config)
    crowd.reset(people, (), walls, rng)
    substeps = round(control_dt / physics_dt)
    world = World(walls, [], crowd.position.copy(), crowd.radius, physics_dt, substeps)
    none2, none1, commands = np.zeros((0, 2)), np.zeros(0), np.zeros((0, 3))
    steps = round(duration / control_dt)
    xy = np.empty((steps + 1, len(people), 2))
    xy[0] = world.people_xy
    for k in range(steps):
        v = crowd.desired_velocity(k * control_dt, control_dt, none2, none2, none1, walls, rng)
        world.step(commands, v)
        crowd.sync(world.people_xy, world.people_velocity)
        xy[k + 1] = world.people_xy
    return Trajectories(xy, control_dt)


def ring_walls(inner: float, outer: float, segments: int = 96) -> NDArray[np.float64]:
    """The walls (2 ``segments``, 4) of an annulus: two regular polygons with their
    vertices on the circles of radius ``inner`` and ``outer`` [m] around the origin."""
    a = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    rings = [np.stack([r * np.cos(a[:-1]), r * np.sin(a[:-1]), r * np.cos(a[1:]),
                       r * np.sin(a[1:])], axis=1) for r in (inner, outer)]  # fmt: skip
    return np.concatenate(rings)


def corridor_walls(x0: float, x1: float, width: float) -> NDArray[np.float64]:
    """The two side walls of a corridor along x from ``x0`` to ``x1``, y in [0, width]."""
    return np.array([[x0, 0.0, x1, 0.0], [x0, width, x1, width]], dtype=np.float64)


def spread(
    xy: NDArray[np.float64], radius: NDArray[np.float64],
    clamp: Callable[[NDArray[np.float64]], NDArray[np.float64]], gap: float = 0.03,
    iterations: int = 2000,
) -> NDArray[np.float64]:  # fmt: skip
    """Positions near ``xy`` at which no two bodies overlap (``gap`` [m] apart): overlaps
    pushed apart, then ``clamp`` (positions -> positions inside the room), repeated."""
    xy = clamp(np.array(xy, dtype=np.float64))
    reach = 2.0 * float(radius.max(initial=0.0)) + gap
    for _ in range(iterations):
        i, j = cKDTree(xy).query_pairs(reach, output_type="ndarray").T
        d = xy[i] - xy[j]
        dist = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
        over = np.clip(radius[i] + radius[j] + gap - dist, 0.0, None)
        if over.max(initial=0.0) < 1e-3:
            break
        push = (0.5 * over / dist)[:, None] * d
        delta = np.zeros_like(xy)
        np.add.at(delta, i, push)
        np.add.at(delta, j, -push)
        xy = clamp(xy + delta)
    return xy


Lengths = Callable[[NDArray[np.float64]], NDArray[np.float64]]


def _rows(n: int, low: float, high: float, lengths: Lengths
          ) -> tuple[NDArray[np.float64], NDArray[np.int64], float]:  # fmt: skip
    """Rows of a near-hexagonal packing of ``n`` points: the rows' cross positions in
    [``low``, ``high``], how many points lie on each (in proportion to the rows'
    ``lengths``, a function of the cross positions) and the spacing of the points [m]."""
    width = high - low
    span = float(lengths(np.array([0.5 * (low + high)]))[0])
    a = math.sqrt(2.0 * width * span / (math.sqrt(3.0) * max(n, 1)))  # hexagonal spacing
    m = max(1, int(width / (0.5 * math.sqrt(3.0) * a)) + 1)
    at = np.linspace(low, high, m) if m > 1 else np.array([0.5 * (low + high)])
    share = lengths(at) / lengths(at).sum() * n
    counts = np.floor(share).astype(np.int64)
    counts[np.argsort(counts - share)[: n - counts.sum()]] += 1
    return at, counts, a


def _circumference(r: NDArray[np.float64]) -> NDArray[np.float64]:
    return 2.0 * np.pi * r


def _ring_route(r: float, theta: float, direction: int, waypoints: int) -> tuple:
    """Waypoints every 2 pi / ``waypoints`` on the circle of radius ``r``, from the first one
    ahead of angle ``theta`` in ``direction`` (+1 anticlockwise), once around."""
    step = 2.0 * np.pi / waypoints
    first = (math.floor(theta / step) + 1) if direction > 0 else (math.ceil(theta / step) - 1)
    angles = (first + direction * np.arange(waypoints)) * step
    return tuple(zip((r * np.cos(angles)).tolist(), (r * np.sin(angles)).tolist()))


def ring_people(
    n: int, inner: float, outer: float, walkers: Walkers, rng: np.random.Generator,
    waypoints: int = 12, direction: NDArray[np.int64] | None = None,
) -> list[PersonLayout]:  # fmt: skip
    """``n`` walkers spread over the annulus, each looping around it, anticlockwise or as
    ``direction`` (+-1 each) says, through ``waypoints`` waypoints on its own circle (its
    lane): the radius it starts at, but far enough from the inner wall that the legs
    between the waypoints (chords) keep its body 5 cm off the wall. Few waypoints keep the
    pull back to the lane weak (a walker aims at a waypoint metres ahead)."""
    speed, radius, tau = walkers.draw(rng, n)
    low, high = inner + radius + 0.02, outer - radius - 0.02

    def clamp(xy: NDArray[np.float64]) -> NDArray[np.float64]:
        r = np.maximum(np.hypot(xy[:, 0], xy[:, 1]), 1e-9)
        return xy * (np.clip(r, low, high) / r)[:, None]

    rows, counts, a = _rows(n, low.max(initial=inner), high.min(initial=outer), _circumference)
    r0 = np.repeat(rows, counts)
    th0 = np.concatenate([(np.arange(c) + rng.uniform()) * 2.0 * np.pi / c for c in counts])
    xy = np.stack([r0 * np.cos(th0), r0 * np.sin(th0)], axis=1)[rng.permutation(n)]
    xy = spread(xy + rng.uniform(-0.5 * a, 0.5 * a, xy.shape), radius, clamp)
    rad, theta = np.hypot(xy[:, 0], xy[:, 1]), np.arctan2(xy[:, 1], xy[:, 0]) % (2.0 * np.pi)
    lane = np.maximum(rad, (inner + radius + 0.05) / math.cos(math.pi / waypoints))
    lane = np.minimum(lane, outer - radius - 0.05)
    sign = np.ones(n, dtype=np.int64) if direction is None else np.asarray(direction)
    return [PersonLayout((float(xy[i, 0]), float(xy[i, 1])), float(theta[i] + sign[i] * np.pi / 2),
                         _ring_route(float(lane[i]), float(theta[i]), int(sign[i]), waypoints),
                         loop=True, preferred_speed=float(speed[i]), radius=float(radius[i]),
                         relaxation_time=float(tau[i]))
            for i in range(n)]  # fmt: skip


def corridor_people(
    n: int, box: tuple[float, float, float, float], heading: int, walkers: Walkers,
    rng: np.random.Generator, width: float, end: float,
) -> list[PersonLayout]:  # fmt: skip
    """``n`` walkers spread over ``box`` (x0, y0, x1, y1) of a corridor of ``width``, each
    walking along x in ``heading`` (+-1) to a goal at x = ``end`` on its own line."""
    speed, radius, tau = walkers.draw(rng, n)
    x0, y0, x1, y1 = box

    def clamp(xy: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.stack([np.clip(xy[:, 0], x0, x1), np.clip(xy[:, 1], np.maximum(y0, radius + 0.02),
                         np.minimum(y1, width - radius - 0.02))], axis=1)  # fmt: skip

    low = max(y0, float(radius.max(initial=0.0)) + 0.02)
    high = min(y1, width - float(radius.max(initial=0.0)) - 0.02)
    rows, counts, a = _rows(n, low, high, lambda y: np.full(y.shape, x1 - x0))
    x = np.concatenate([x0 + (np.arange(c) + rng.uniform()) * (x1 - x0) / c for c in counts])
    xy = np.stack([x, np.repeat(rows, counts)], axis=1)[rng.permutation(n)]
    xy = spread(xy + rng.uniform(-0.5 * a, 0.5 * a, xy.shape), radius, clamp)
    return [PersonLayout((float(x), float(y)), 0.0 if heading > 0 else math.pi, ((end, float(y)),),
                         preferred_speed=float(v), radius=float(r), relaxation_time=float(t))
            for (x, y), v, r, t in zip(xy, speed, radius, tau)]  # fmt: skip


def group_layout(
    groups: int, rng: np.random.Generator, walkers: Walkers, width: float, end: float,
    spacing: float,
) -> list[PersonLayout]:  # fmt: skip
    """``groups`` groups of three abreast in the middle of the corridor, one behind the
    other, walking +x; a group shares one speed (the sampler's rule) and each member
    walks to its own place abreast at x = ``end``."""
    people = []
    for g in range(groups):
        speed, radius, tau = walkers.draw(rng, 3)
        step = 2.0 * radius.max() + GROUP_GAP
        for k in range(3):
            y = 0.5 * width + (k - 1) * step
            people.append(PersonLayout((-2.0 - spacing * g, y), 0.0, ((end, y),),
                                       preferred_speed=float(speed[0]), radius=float(radius[k]),
                                       relaxation_time=float(tau[k]), group=g))  # fmt: skip
    return people
