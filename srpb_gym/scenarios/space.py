"""Plane geometry of scenario worlds, the free-space model the sampler draws from and the
route graph that leads walking people around walls.

This module knows nothing of scenarios: :mod:`~srpb_gym.scenarios.schema`,
:mod:`~srpb_gym.scenarios.validate`, :mod:`~srpb_gym.scenarios.sampler` and
:mod:`~srpb_gym.scenarios.loader` build on it. Metres throughout.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import ndimage

from srpb_gym.sim.geometry import leg_clearance, path_clearance, segment_distance, wall_between

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


# --- walking routes around walls -----------------------------------------------------------

ROUTE_DIRECTIONS = 8  # corner nodes per wall end, evenly spread around it
ROUTE_MARGIN = 0.2  # m, beyond the largest body radius: the clearance routes prefer
ROUTE_PENALTY = 20.0  # m of extra length per m a leg's clearance falls short of the preferred
OPENING_WIDTH = 2.0  # m, wall ends closer than this across free space form an opening


def segment_clearance(a: NDArray, b: NDArray, walls: NDArray) -> NDArray:
    """Smallest distance [m] from each segment ``a[m]``-``b[m]`` ((M, 2) each) to the walls
    (S, 4): 0 where it meets one, ``inf`` with no walls. Returns (M,)."""
    a = np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 2)
    b = np.ascontiguousarray(b, dtype=np.float64).reshape(-1, 2)
    segs = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 4)
    return path_clearance(a[:, 0], a[:, 1], b[:, 0], b[:, 1], segs, np.empty(len(a)))


@dataclass(frozen=True, eq=False)
class RouteGraph:
    """Walking routes around walls: a visibility graph of corner and opening nodes.

    ``clearance = radius + margin`` [m] is the clearance from walls a route prefers for
    bodies up to ``radius`` [m]; ``radius + gap`` the least it accepts. Nodes lie
    ``clearance`` from every wall end in ``ROUTE_DIRECTIONS`` directions (to walk around
    corners), and in the middle of every opening between two wall ends less than
    ``OPENING_WIDTH`` apart and ``clearance`` before and after it along its normal (to walk
    straight through doors); nodes closer than ``radius + gap`` to a wall, an edge of the
    bounds or inside an obstacle are dropped. A straight leg (between nodes, or from or to
    a route's ends) is usable when it keeps ``radius + gap`` from the walls; its cost is
    its length plus ``ROUTE_PENALTY`` times what its clearance falls short of
    ``clearance``, so routes keep their distance from walls where there is room and go
    through the middle of narrow openings. ``dist`` and ``pred`` hold the cheapest paths
    between all nodes (``pred[i, j]``: the node before j on the path from i, -1 none).
    """

    segments: NDArray[np.float64]  # walls and the edges of the bounds
    obstacles: tuple[NDArray[np.float64], ...]
    bounds: Bounds
    radius: float
    gap: float
    margin: float
    nodes: NDArray[np.float64]
    dist: NDArray[np.float64]
    pred: NDArray[np.int32]

    @property
    def clearance(self) -> float:
        """The clearance from walls [m] routes prefer."""
        return self.radius + self.margin

    def point_clearance(self, points: NDArray) -> NDArray:
        """Distance [m] from each point (K, 2) to the nearest wall or edge of the bounds; 0
        inside an obstacle or outside the bounds."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        x, y = pts[:, 0], pts[:, 1]
        clear = segment_clearance(pts, pts, self.segments)
        xmin, ymin, xmax, ymax = self.bounds
        clear[(x < xmin) | (x > xmax) | (y < ymin) | (y > ymax)] = 0.0
        for poly in self.obstacles:
            clear[inside_polygon(x, y, poly)] = 0.0
        return clear

    def leg_costs(self, a: NDArray, b: NDArray, least: float, preferred: float) -> NDArray:
        """The cost [m] of each straight leg ``a[m]``-``b[m]``: its length plus the penalty
        for a clearance below ``preferred``; ``inf`` below ``least``."""
        clear = segment_clearance(a, b, self.segments)
        length = np.hypot(*(np.asarray(a) - np.asarray(b)).reshape(-1, 2).T)
        cost = length + ROUTE_PENALTY * np.maximum(preferred - clear, 0.0)
        return np.where(clear >= least - 1e-9, cost, np.inf)

    def route(self, a: Point, b: Point, radius: float) -> tuple[Point, ...] | None:
        """The nodes [m] a body of ``radius`` walks through from ``a`` to ``b`` on the
        cheapest route: ``()`` for the straight leg, ``None`` when there is no route. The
        least clearance is ``radius + gap`` and the preferred one :attr:`clearance`, each
        lowered to the clearance of ``a`` or ``b`` where that is smaller."""
        # the ends are placed in the free space: their clearance needs no polygon test
        a, b = (float(a[0]), float(a[1])), (float(b[0]), float(b[1]))
        leg, ends_clear = leg_clearance(a[0], a[1], b[0], b[1], self.segments)
        least = min(radius + self.gap, ends_clear)
        preferred = min(self.clearance, ends_clear)
        if leg >= preferred:
            return ()
        direct = math.dist(a, b) + ROUTE_PENALTY * (preferred - leg) if leg >= least else math.inf
        if len(self.nodes) == 0:
            return () if np.isfinite(direct) else None
        i, j = _cheapest_link(a[0], a[1], b[0], b[1], self.nodes, self.dist, self.segments,
                              least, preferred, direct)  # fmt: skip
        if i < 0:
            return () if np.isfinite(direct) else None
        path = [int(j)]
        while path[-1] != i:
            path.append(int(self.pred[i, path[-1]]))
        return tuple((float(self.nodes[k, 0]), float(self.nodes[k, 1])) for k in reversed(path))


def route_graph(
    bounds: Bounds,
    walls: NDArray[np.float64],
    obstacles: Sequence[NDArray[np.float64]],
    radius: float,
    gap: float,
    margin: float = ROUTE_MARGIN,
) -> RouteGraph:
    """The :class:`RouteGraph` of a world for bodies up to ``radius`` [m] keeping at least
    ``gap`` and preferably ``margin`` [m] from walls.

    ``walls``: (S, 4) segments x0, y0, x1, y1 [m]; ``obstacles``: solid polygons (N, 2).
    """
    xmin, ymin, xmax, ymax = bounds
    edges = np.array([[xmin, ymin, xmax, ymin], [xmax, ymin, xmax, ymax],
                      [xmax, ymax, xmin, ymax], [xmin, ymax, xmin, ymin]])  # fmt: skip
    walls = np.asarray(walls, dtype=np.float64).reshape(-1, 4)
    segments = np.vstack([walls, edges])
    graph = RouteGraph(segments, tuple(obstacles), bounds, float(radius), float(gap),
                       float(margin), np.zeros((0, 2)), np.zeros((0, 0)),
                       np.zeros((0, 0), np.int32))  # fmt: skip
    least, preferred = radius + gap, graph.clearance
    ends = np.unique(walls.reshape(-1, 2), axis=0)
    angles = 2.0 * np.pi * np.arange(ROUTE_DIRECTIONS) / ROUTE_DIRECTIONS
    ring = preferred * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    candidates = [(ends[:, None, :] + ring[None, :, :]).reshape(-1, 2)]
    i, j = np.triu_indices(len(ends), 1)
    width = np.hypot(*(ends[i] - ends[j]).T)
    k = (width >= 2.0 * least) & (width < OPENING_WIDTH)
    p, q = ends[i[k]], ends[j[k]]
    middle = 0.5 * (p + q)
    open_ = (graph.point_clearance(middle) >= least) & _free_between(p, q, segments)
    p, q, middle = p[open_], q[open_], middle[open_]
    normal = np.stack([p[:, 1] - q[:, 1], q[:, 0] - p[:, 0]], axis=1)
    normal *= preferred / np.hypot(*normal.T)[:, None]
    candidates += [middle, middle + normal, middle - normal]
    nodes = np.concatenate(candidates)
    if len(nodes):
        nodes = nodes[graph.point_clearance(nodes) >= least]
        nodes = np.unique(np.round(nodes, 9), axis=0)
    n = len(nodes)
    i, j = np.triu_indices(n, 1)
    dist = np.full((n, n), np.inf)
    np.fill_diagonal(dist, 0.0)
    dist[i, j] = dist[j, i] = graph.leg_costs(nodes[i], nodes[j], least, preferred)
    pred = np.where(np.isfinite(dist), np.arange(n)[:, None], -1).astype(np.int32)
    np.fill_diagonal(pred, -1)
    for k in range(n):  # Floyd-Warshall: the cheapest paths between all nodes
        through = dist[:, k : k + 1] + dist[k : k + 1, :]
        better = through < dist
        dist = np.where(better, through, dist)
        pred = np.where(better, pred[k : k + 1, :], pred)
    return replace(graph, nodes=nodes, dist=dist, pred=pred)


@njit(cache=True, error_model="numpy")
def _cheapest_link(
    ax: float, ay: float, bx: float, by: float, nodes: NDArray, dist: NDArray, segs: NDArray,
    least: float, preferred: float, bound: float,
) -> tuple[int, int]:  # fmt: skip
    """The first and last node (i, j) of the cheapest route from (ax, ay) through the graph
    to (bx, by) (legs costed as in :meth:`RouteGraph.leg_costs`), or (-1, -1) when none
    costs less than ``bound``."""
    n = nodes.shape[0]
    to_b = np.empty(n)
    for k in range(n):
        to_b[k] = _leg_cost(nodes[k, 0], nodes[k, 1], bx, by, segs, least, preferred)
    best, bi, bj = bound, -1, -1
    for i in range(n):
        from_a = _leg_cost(ax, ay, nodes[i, 0], nodes[i, 1], segs, least, preferred)
        if not from_a < best:
            continue
        for j in range(n):
            total = from_a + dist[i, j] + to_b[j]
            if total < best:
                best, bi, bj = total, i, j
    return bi, bj


@njit(cache=True, inline="always", error_model="numpy")
def _leg_cost(
    ax: float, ay: float, bx: float, by: float, segs: NDArray, least: float, preferred: float
) -> float:
    clear = math.inf
    for s in range(segs.shape[0]):
        clear = min(clear, segment_distance(ax, ay, bx, by, segs[s, 0], segs[s, 1], segs[s, 2],
                                            segs[s, 3]))  # fmt: skip
    if clear < least - 1e-9:
        return math.inf
    return math.hypot(bx - ax, by - ay) + ROUTE_PENALTY * max(preferred - clear, 0.0)


def _free_between(p: NDArray, q: NDArray, segments: NDArray) -> NDArray:
    """Whether the open segment between each pair of wall ends p[m], q[m] meets no wall
    (an opening; the walls at its ends do not count)."""
    out = np.ones(len(p), dtype=bool)
    for m in range(len(p)):
        out[m] = not wall_between(p[m, 0], p[m, 1], q[m, 0], q[m, 1], segments)
    return out
