"""The route graph that leads walking people around walls: a visibility graph of corner and
opening nodes, built once per scenario from its walls (:func:`route_graph`).

Built on :mod:`~srpb_gym.scenarios.space` (plane geometry); the sampler draws people's
routes from it. Metres throughout.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit
from numpy.typing import NDArray

from srpb_gym.scenarios.space import Bounds, Point, inside_polygon
from srpb_gym.sim.geometry import leg_clearance, path_clearance, segment_distance, wall_between

ROUTE_DIRECTIONS = 8  # corner nodes per wall end, evenly spread around it
ROUTE_MARGIN = 0.2  # m, beyond the largest body radius: the clearance routes prefer
ROUTE_PENALTY = 20.0  # m of extra length per m a leg's clearance falls short of the preferred
OPENING_WIDTH = 2.0  # m, wall ends closer than this across free space form an opening
DOOR_WIDTH = 1.2  # m, an opening narrower than this lets one body through at a time: a door
DOOR_MERGE = 0.5  # m, openings whose middles are closer than this are one door


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
    #: (D, 6) the doors: openings narrower than ``DOOR_WIDTH`` (one body at a time), each
    #: centre x, y [m], unit normal x, y (the crossing direction), half width and half
    #: depth [m] (openings of one door less than ``DOOR_MERGE`` apart are merged)
    doors: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 6)))

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
    doors = _doors(p, q, normal / preferred)
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
    return replace(graph, nodes=nodes, dist=dist, pred=pred, doors=doors)


def _doors(p: NDArray, q: NDArray, normal: NDArray) -> NDArray[np.float64]:
    """The doors (see :attr:`RouteGraph.doors`) among the openings between wall ends ``p``
    and ``q`` (M, 2) with unit normals ``normal``: the narrow ones, merged where their
    middles lie within ``DOOR_MERGE`` of each other (a wall's thickness gives one opening
    per face and the diagonals), narrowest first; a door spans its openings' wall ends."""
    middle, width = 0.5 * (p + q), np.hypot(*(p - q).T)
    doors: list[list[NDArray]] = []
    for k in np.argsort(width, kind="stable"):
        if width[k] >= DOOR_WIDTH:
            break
        for door in doors:
            if np.hypot(*(middle[door[0]] - middle[k])) < DOOR_MERGE:
                door.append(k)
                break
        else:
            doors.append([k])
    out = np.zeros((len(doors), 6))
    for d, members in enumerate(doors):
        n = normal[members[0]]
        along = np.concatenate([p[members] @ n, q[members] @ n])
        mean = middle[members].mean(axis=0)
        center = mean + (0.5 * (along.min() + along.max()) - mean @ n) * n
        out[d] = (*center, *n, 0.5 * width[members[0]], 0.5 * (along.max() - along.min()))
    return out


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
