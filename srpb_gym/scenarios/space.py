"""Plane geometry of scenario worlds and the free-space model the sampler draws from (the
route graph that leads walking people around walls is :mod:`~srpb_gym.scenarios.routes`).

This module knows nothing of scenarios: :mod:`~srpb_gym.scenarios.routes`,
:mod:`~srpb_gym.scenarios.schema`,
:mod:`~srpb_gym.scenarios.validate`, :mod:`~srpb_gym.scenarios.sampler` and
:mod:`~srpb_gym.scenarios.loader` build on it. Metres throughout.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

RESOLUTION = 0.05  # m, grid cell size of the free-space model

Point = tuple[float, float]
Bounds = tuple[float, float, float, float]  # xmin, ymin, xmax, ymax [m]


@dataclass(frozen=True)
class Place:
    """A point (``xmin == xmax`` and ``ymin == ymax``) or an axis-aligned rectangle [m]."""

    xmin: float
    ymin: float
    xmax: float
    ymax: float

    @classmethod
    def point(cls, x: float, y: float) -> Place:
        """The place holding the single point (x, y) [m]."""
        return cls(x, y, x, y)

    @property
    def is_point(self) -> bool:
        """True when the place has no extent."""
        return self.xmin == self.xmax and self.ymin == self.ymax

    @property
    def center(self) -> Point:
        """The centre (x, y) [m]."""
        return (0.5 * (self.xmin + self.xmax), 0.5 * (self.ymin + self.ymax))

    def corners(self) -> tuple[Point, ...]:
        """The four corners (one point for a point place) [m]."""
        if self.is_point:
            return ((self.xmin, self.ymin),)
        return (
            (self.xmin, self.ymin), (self.xmax, self.ymin),
            (self.xmax, self.ymax), (self.xmin, self.ymax),
        )  # fmt: skip

    def draw(self, rng: np.random.Generator) -> Point:
        """A point drawn uniformly from the place [m]."""
        if self.is_point:
            return (self.xmin, self.ymin)
        return (float(rng.uniform(self.xmin, self.xmax)), float(rng.uniform(self.ymin, self.ymax)))


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


def repeated_point(points: Sequence[Point], closed: bool) -> str | None:
    """Why a chain (a ring when ``closed``) has an edge of zero length, or ``None``."""
    for k in range(1, len(points)):
        if points[k] == points[k - 1]:
            return f"points {k - 1} and {k} are the same point"
    if closed and len(points) > 2 and points[0] == points[-1]:
        return "the last point repeats the first (the ring closes itself)"
    return None


def polygon_problem(poly: Sequence[Point]) -> str | None:
    """Why ``poly`` is not a simple polygon with an area, or ``None``: a repeated point,
    fewer than 3 distinct points, all points on one line, edges that cross or touch
    (other than neighbours at their shared point), or an area under 1e-9 m^2."""
    problem = repeated_point(poly, closed=True)
    if problem is not None:
        return f"the polygon has an edge of zero length: {problem}"
    if len(set(poly)) < 3:
        return "the polygon has fewer than 3 distinct points"
    p = np.asarray(poly, dtype=np.float64)
    a, b = p, np.roll(p, -1, axis=0)  # edge i runs from point i to point i + 1
    rel = p - p[0]
    far = rel[np.argmax(np.hypot(rel[:, 0], rel[:, 1]))]
    if not np.any(far[0] * rel[:, 1] - far[1] * rel[:, 0]):
        return "the polygon has zero area: all its points lie on one line"
    n = len(p)
    for i in range(n):
        j = np.arange(i + 1, n)
        crossing = _segments_meet(a[i], b[i], a[j], b[j])
        for k in j[crossing]:
            if k == i + 1 or (i == 0 and k == n - 1):  # neighbours: only a fold-back counts
                shared, u, v = (b[i], a[i], b[k]) if k == i + 1 else (a[i], b[i], a[k])
                du, dv = u - shared, v - shared
                if du[0] * dv[1] - du[1] * dv[0] != 0 or du @ dv <= 0:
                    continue
            return (
                f"the polygon intersects itself: its edge from point {i} to point "
                f"{(i + 1) % n} meets its edge from point {k} to point {(k + 1) % n}"
            )
    if abs(polygon_area(poly)) < 1e-9:
        return "the polygon has zero area"
    return None


def _segments_meet(p: NDArray, q: NDArray, r: NDArray, s: NDArray) -> NDArray:
    """Whether segment p-q meets each segment r-s (rows of r and s), touching included."""

    def orient(u: NDArray, v: NDArray, w: NDArray) -> NDArray:
        return np.sign((v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1])
                       - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0]))  # fmt: skip

    def on(u: NDArray, v: NDArray, w: NDArray) -> NDArray:  # w, collinear, within u-v's box
        lo, hi = np.minimum(u, v), np.maximum(u, v)
        return np.all((lo <= w) & (w <= hi), axis=-1)

    d1, d2, d3, d4 = orient(r, s, p), orient(r, s, q), orient(p, q, r), orient(p, q, s)
    proper = (d1 * d2 < 0) & (d3 * d4 < 0)
    touch = ((d1 == 0) & on(r, s, p)) | ((d2 == 0) & on(r, s, q))
    touch |= ((d3 == 0) & on(p, q, r)) | ((d4 == 0) & on(p, q, s))
    return proper | touch


def rectangle_corners(center: Point, size: Point, yaw: float) -> tuple[Point, ...]:
    """Corners of a ``size`` = (width, height) rectangle [m] turned by ``yaw`` [rad]."""
    (cx, cy), (w, h), c, s = center, size, math.cos(yaw), math.sin(yaw)
    half = ((-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2))
    return tuple((cx + c * u - s * v, cy + s * u + c * v) for u, v in half)


# --- free space ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class FreeSpace:
    """Clearance field and robot-reachable components of a world, for one robot radius.

    ``clearance[i, j]``: distance [m] from the centre of cell (row i = y, column j = x) to
    the nearest wall, obstacle or bounds edge (0 inside obstacles). ``labels``: connected
    components of the cells a robot of ``robot_radius`` [m] fits in (clearance greater than
    the radius; 0: it does not). ``robot_labels``: the components holding both a start cell
    and a goal cell of the robot.
    """

    origin: Point
    resolution: float
    clearance: NDArray[np.float64]
    labels: NDArray[np.int32]
    robot_labels: frozenset[int]
    segments: NDArray[np.float64]
    obstacles: tuple[NDArray[np.float64], ...]
    bounds: Bounds
    robot_radius: float

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

    def labels_between(self, start: Place, goal: Place) -> frozenset[int]:
        """The robot components met by both places: a start drawn in one of them can reach
        a goal drawn in the same one."""
        return frozenset(self.labels_in(start) & self.labels_in(goal))


def free_space(
    bounds: Bounds,
    walls: NDArray[np.float64],
    obstacles: Sequence[NDArray[np.float64]],
    robot_radius: float,
    start: Place,
    goal: Place,
    resolution: float = RESOLUTION,
) -> FreeSpace:
    """The :class:`FreeSpace` of a world (a grid of ``resolution`` [m] over ``bounds``) for
    a robot of ``robot_radius`` [m] going from the ``start`` place to the ``goal`` place.

    ``walls``: (S, 4) segments x0, y0, x1, y1 [m]; ``obstacles``: solid polygons (N, 2).
    """
    xmin, ymin, xmax, ymax = bounds
    cols, rows = (
        max(1, math.ceil((xmax - xmin) / resolution)),
        max(1, math.ceil((ymax - ymin) / resolution)),
    )
    xs = xmin + (np.arange(cols) + 0.5) * resolution
    ys = ymin + (np.arange(rows) + 0.5) * resolution
    X, Y = np.meshgrid(xs, ys)
    edges = np.array([[xmin, ymin, xmax, ymin], [xmax, ymin, xmax, ymax],
                      [xmax, ymax, xmin, ymax], [xmin, ymax, xmin, ymin]])  # fmt: skip
    segments = np.vstack([walls.reshape(-1, 4), edges])
    clearance = np.full(X.shape, np.inf)
    for seg in segments:
        np.minimum(clearance, segment_distances(X, Y, seg), out=clearance)
    for poly in obstacles:
        clearance[inside_polygon(X, Y, poly)] = 0.0
    clearance[(xmax < X) | (ymax < Y)] = 0.0
    labels, _ = ndimage.label(clearance > robot_radius)
    space = FreeSpace((xmin, ymin), resolution, clearance, labels.astype(np.int32), frozenset(),
                      segments, tuple(obstacles), bounds, robot_radius)  # fmt: skip
    return replace(space, robot_labels=space.labels_between(start, goal))
