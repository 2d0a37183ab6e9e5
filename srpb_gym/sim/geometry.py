"""Compiled 2-D geometry queries against the static walls and the body circles.

Shared conventions (global frame, SI units, angles in rad):

* ``segs``: float64 array (S, 4) of wall segments ``x0, y0, x1, y1``. Walls have zero
  thickness and are seen from both sides; a zero-length segment is a point obstacle.
* ``circles``: float64 array (C, 3) of bodies ``x, y, radius`` (the simulator passes all
  people, then all robots).
* ``skip``: the index in ``circles`` of the querying body's own circle, ignored by every
  query; ``-1`` ignores nothing.

A query that starts inside another body (or on its boundary) is blocked by it at once: every
ray hits it at distance 0 and every line of sight is blocked, as with pymunk's
``segment_query`` (a sensor buried in a person sees nothing else). A ray along a wall's own
line hits the wall's nearer end (pymunk reports no hit there).

Every kernel is a plain loop compiled by numba (``cache=True``); only the ray casts allocate,
a few small scratch arrays per call.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from srpb_gym.angles import wrap_angle

__all__ = [
    "leg_clearance",
    "line_of_sight",
    "path_clearance",
    "point_obstacle_distance",
    "point_segment_distance",
    "ray_circle_distance",
    "ray_segment_distance",
    "raycast",
    "raycast_beams",
    "segment_clear",
    "segment_distance",
    "wall_between",
    "wall_within",
]

PI = math.pi
TWO_PI = 2.0 * math.pi
# Directions closer than this sine of their angle count as parallel to a segment.
PARALLEL_SINE = 1e-12
# A parallel ray or sight line within this distance of a segment's line runs along it [m].
COLLINEAR_TOLERANCE = 1e-9
# Extra angle around an obstacle's angular extent within which beams are tested [rad].
WINDOW_MARGIN = 1e-9


@njit(cache=True, inline="always", error_model="numpy")
def ray_segment_distance(
    ox: float, oy: float, dx: float, dy: float, x0: float, y0: float, x1: float, y1: float
) -> float:
    """Distance along the unit direction (dx, dy) from (ox, oy) to segment (x0, y0)-(x1, y1),
    or ``inf`` if the ray misses it.

    A ray running along the segment's own line hits its nearer end (0 if the origin lies
    on the segment); a zero-length segment is hit only when it lies on the ray.
    """
    ex = x1 - x0
    ey = y1 - y0
    wx = x0 - ox
    wy = y0 - oy
    denom = dx * ey - dy * ex
    if denom * denom > PARALLEL_SINE * PARALLEL_SINE * (ex * ex + ey * ey):
        t = (wx * ey - wy * ex) / denom
        u = (wx * dy - wy * dx) / denom
        if t >= 0.0 and 0.0 <= u <= 1.0:
            return t
        return math.inf
    if abs(wx * dy - wy * dx) > COLLINEAR_TOLERANCE:  # parallel, beside the ray
        return math.inf
    t0 = wx * dx + wy * dy
    t1 = (wx + ex) * dx + (wy + ey) * dy
    if t0 * t1 <= 0.0:  # the origin lies on the segment
        return 0.0
    if t0 > 0.0:
        return min(t0, t1)
    return math.inf


@njit(cache=True, inline="always", error_model="numpy")
def ray_circle_distance(
    ox: float, oy: float, dx: float, dy: float, cx: float, cy: float, r: float
) -> float:
    """Distance along the unit direction (dx, dy) from (ox, oy) to where the ray enters the
    circle (cx, cy, r): 0 when it starts inside or on it, ``inf`` when it misses it."""
    fx = cx - ox
    fy = cy - oy
    b = fx * dx + fy * dy
    if b + r < 0.0:  # the whole circle lies behind the origin
        return math.inf
    cc = fx * fx + fy * fy - r * r
    if cc <= 0.0:
        return 0.0
    disc = b * b - cc
    if disc < 0.0:
        return math.inf
    t = b - math.sqrt(disc)
    if t < 0.0:
        return math.inf
    return t


@njit(cache=True, error_model="numpy")
def _beam_window(angles: np.ndarray, lo: float, hi: float, window: np.ndarray) -> None:
    """The beams whose angle lies in [lo, hi] modulo 2 pi, as two index ranges
    ``window[0]:window[1]`` and ``window[2]:window[3]`` of the sorted ``angles`` (all in
    [-pi, pi]); ``hi - lo`` must be below 2 pi."""
    window[0] = np.searchsorted(angles, lo)
    window[1] = np.searchsorted(angles, hi, side="right")
    window[2] = 0
    window[3] = 0
    if lo < -PI:
        window[2] = np.searchsorted(angles, lo + TWO_PI)
        window[3] = angles.shape[0]
    elif hi > PI:
        window[3] = np.searchsorted(angles, hi - TWO_PI, side="right")


@njit(cache=True, error_model="numpy")
def _segment_window(
    ox: float, oy: float, yaw: float, seg: np.ndarray, angles: np.ndarray, window: np.ndarray
) -> None:
    """The beams that may hit segment ``seg``: those between the bearings of its ends (the
    arc facing the origin), or all beams when the origin lies on the segment's line."""
    ax = seg[0] - ox
    ay = seg[1] - oy
    bx = seg[2] - ox
    by = seg[3] - oy
    cross = ax * by - ay * bx
    dot = ax * bx + ay * by
    length = math.hypot(bx - ax, by - ay)
    if (ax == 0.0 and ay == 0.0) or (dot <= 0.0 and abs(cross) <= COLLINEAR_TOLERANCE * length):
        window[0] = 0
        window[1] = angles.shape[0]
        window[2] = 0
        window[3] = 0
        return
    start = wrap_angle(math.atan2(ay, ax) - yaw)
    sweep = math.atan2(cross, dot)  # signed angle from end a to end b, in (-pi, pi)
    lo = start + min(sweep, 0.0) - WINDOW_MARGIN
    hi = start + max(sweep, 0.0) + WINDOW_MARGIN
    _beam_window(angles, lo, hi, window)


@njit(cache=True, error_model="numpy")
def _circle_window(
    ox: float, oy: float, yaw: float, cx: float, cy: float, r: float, angles: np.ndarray,
    window: np.ndarray,
) -> None:  # fmt: skip
    """The beams that may hit the circle (cx, cy, r): those within its angular radius
    asin(r / distance) of its bearing, or all beams from inside it."""
    fx = cx - ox
    fy = cy - oy
    dist = math.hypot(fx, fy)
    if dist <= r or dist == 0.0:
        window[0] = 0
        window[1] = angles.shape[0]
        window[2] = 0
        window[3] = 0
        return
    half = math.asin(r / dist) + WINDOW_MARGIN
    bearing = wrap_angle(math.atan2(fy, fx) - yaw)
    _beam_window(angles, bearing - half, bearing + half, window)


@njit(cache=True, error_model="numpy")
def _is_window_sorted(angles: np.ndarray) -> bool:
    """Whether ``angles`` increase within [-pi, pi], so beams can be picked by bisection."""
    n = angles.shape[0]
    if n == 0 or angles[0] < -PI or angles[n - 1] > PI:
        return False
    increasing = True
    for b in range(1, n):
        if angles[b] < angles[b - 1]:
            increasing = False
            break
    return increasing


@njit(cache=True, error_model="numpy")
def raycast_beams(
    ox: float,
    oy: float,
    yaw: float,
    angles: np.ndarray,
    beam_dirs: np.ndarray,
    range_max: float,
    segs: np.ndarray,
    circles: np.ndarray,
    skip: int,
    out: np.ndarray,
) -> np.ndarray:
    """:func:`raycast` with ``beam_dirs[b] = (cos(angles[b]), sin(angles[b]))`` given, so a
    sensor with fixed beams computes no trigonometry per beam. Returns ``out``."""
    n = angles.shape[0]
    cos_yaw = math.cos(yaw)
    sin_yaw = math.sin(yaw)
    dirs = np.empty((n, 2))
    for b in range(n):
        dirs[b, 0] = cos_yaw * beam_dirs[b, 0] - sin_yaw * beam_dirs[b, 1]
        dirs[b, 1] = sin_yaw * beam_dirs[b, 0] + cos_yaw * beam_dirs[b, 1]
        out[b] = range_max
    windowed = _is_window_sorted(angles)
    window = np.zeros(4, dtype=np.int64)
    window[1] = n
    for i in range(segs.shape[0]):
        x0, y0, x1, y1 = segs[i, 0], segs[i, 1], segs[i, 2], segs[i, 3]
        if point_segment_distance(ox, oy, x0, y0, x1, y1) >= range_max:
            continue
        if windowed:
            _segment_window(ox, oy, yaw, segs[i], angles, window)
        for k in (0, 2):
            for b in range(window[k], window[k + 1]):
                t = ray_segment_distance(ox, oy, dirs[b, 0], dirs[b, 1], x0, y0, x1, y1)
                if t < out[b]:
                    out[b] = t
    for j in range(circles.shape[0]):
        cx, cy, r = circles[j, 0], circles[j, 1], circles[j, 2]
        dist = math.hypot(cx - ox, cy - oy)
        if j == skip or dist - r >= range_max:
            continue
        if windowed:
            _circle_window(ox, oy, yaw, cx, cy, r, angles, window)
        for k in (0, 2):
            for b in range(window[k], window[k + 1]):
                t = ray_circle_distance(ox, oy, dirs[b, 0], dirs[b, 1], cx, cy, r)
                if t < out[b]:
                    out[b] = t
    return out


@njit(cache=True, error_model="numpy")
def raycast(
    ox: float,
    oy: float,
    yaw: float,
    angles: np.ndarray,
    range_max: float,
    segs: np.ndarray,
    circles: np.ndarray,
    skip: int,
    out: np.ndarray,
) -> np.ndarray:
    """Cast one ray per beam from (ox, oy) in direction ``yaw + angles[b]`` [rad].

    ``out[b]`` becomes the distance [m] to the first wall segment or circle (other than
    circle ``skip``) hit by beam ``b``, or ``range_max`` when nothing is hit within
    ``range_max``. Every beam reads 0 when the origin is inside (or on) a circle or on a
    wall. Returns ``out``.

    Each obstacle is tested against the beams that can reach it only: obstacles beyond
    ``range_max`` are skipped and, when ``angles`` increase within [-pi, pi] (any lidar's
    beams), the beams outside an obstacle's angular extent too. Any other order of
    ``angles`` gives the same ranges, testing every beam.
    """
    n = angles.shape[0]
    beam_dirs = np.empty((n, 2))
    for b in range(n):
        beam_dirs[b, 0] = math.cos(angles[b])
        beam_dirs[b, 1] = math.sin(angles[b])
    return raycast_beams(ox, oy, yaw, angles, beam_dirs, range_max, segs, circles, skip, out)


@njit(cache=True, inline="always", error_model="numpy")
def point_segment_distance(
    px: float, py: float, x0: float, y0: float, x1: float, y1: float
) -> float:
    """Distance [m] from (px, py) to the closest point of segment (x0, y0)-(x1, y1)."""
    ex = x1 - x0
    ey = y1 - y0
    wx = px - x0
    wy = py - y0
    len2 = ex * ex + ey * ey
    u = 0.0
    if len2 > 0.0:
        u = min(max((wx * ex + wy * ey) / len2, 0.0), 1.0)
    return math.hypot(wx - u * ex, wy - u * ey)


@njit(cache=True, error_model="numpy")
def point_obstacle_distance(
    px: float, py: float, segs: np.ndarray, circles: np.ndarray, skip: int
) -> float:
    """Smallest distance [m] from (px, py) to any wall segment or any circle's boundary
    (``|p - c| - r``, 0 inside the circle), ignoring circle ``skip``; ``inf`` if there is
    no obstacle at all."""
    best = math.inf
    for i in range(segs.shape[0]):
        d = point_segment_distance(px, py, segs[i, 0], segs[i, 1], segs[i, 2], segs[i, 3])
        if d < best:
            best = d
    for j in range(circles.shape[0]):
        if j == skip:
            continue
        d = max(math.hypot(px - circles[j, 0], py - circles[j, 1]) - circles[j, 2], 0.0)
        if d < best:
            best = d
    return best


@njit(cache=True, inline="always", error_model="numpy")
def _crosses_segment(
    ox: float, oy: float, dx: float, dy: float, x0: float, y0: float, x1: float, y1: float
) -> bool:
    """Whether the open segment from (ox, oy) to (ox + dx, oy + dy) meets segment
    (x0, y0)-(x1, y1) (closed)."""
    ex = x1 - x0
    ey = y1 - y0
    wx = x0 - ox
    wy = y0 - oy
    denom = dx * ey - dy * ex
    len2 = dx * dx + dy * dy
    if denom * denom > PARALLEL_SINE * PARALLEL_SINE * (ex * ex + ey * ey) * len2:
        t = (wx * ey - wy * ex) / denom
        u = (wx * dy - wy * dx) / denom
        return 0.0 < t < 1.0 and 0.0 <= u <= 1.0
    cross = wx * dy - wy * dx
    if cross * cross > COLLINEAR_TOLERANCE * COLLINEAR_TOLERANCE * len2:
        return False
    t0 = (wx * dx + wy * dy) / len2
    t1 = ((wx + ex) * dx + (wy + ey) * dy) / len2
    return min(t0, t1) < 1.0 and max(t0, t1) > 0.0


@njit(cache=True, inline="always", error_model="numpy")
def _enters_circle(
    ox: float, oy: float, dx: float, dy: float, cx: float, cy: float, r: float
) -> bool:
    """Whether the segment from (ox, oy) to (ox + dx, oy + dy) starts inside or on the
    circle or enters it before its end point (grazing does not count)."""
    fx = cx - ox
    fy = cy - oy
    cc = fx * fx + fy * fy - r * r
    if cc <= 0.0:
        return True
    b = fx * dx + fy * dy
    if b <= 0.0:
        return False
    a = dx * dx + dy * dy
    disc = b * b - a * cc
    if disc <= 0.0:
        return False
    return b - math.sqrt(disc) < a


@njit(cache=True, error_model="numpy")
def segment_clear(
    ox: float,
    oy: float,
    tx: float,
    ty: float,
    segs: np.ndarray,
    circles: np.ndarray,
    skip: int,
    own: int,
) -> bool:
    """Whether the open segment from (ox, oy) to (tx, ty) crosses no wall segment and meets
    no circle other than ``skip`` and ``own`` (it starts in none and enters none)."""
    dx = tx - ox
    dy = ty - oy
    if dx == 0.0 and dy == 0.0:
        return True
    for i in range(segs.shape[0]):
        if _crosses_segment(ox, oy, dx, dy, segs[i, 0], segs[i, 1], segs[i, 2], segs[i, 3]):
            return False
    for j in range(circles.shape[0]):
        if j == skip or j == own:  # noqa: SIM109 (plain comparisons compile best)
            continue
        if _enters_circle(ox, oy, dx, dy, circles[j, 0], circles[j, 1], circles[j, 2]):
            return False
    return True


@njit(cache=True, error_model="numpy")
def line_of_sight(
    ox: float,
    oy: float,
    tx: np.ndarray,
    ty: np.ndarray,
    segs: np.ndarray,
    circles: np.ndarray,
    skip: int,
    target_circle: np.ndarray,
    out: np.ndarray,
) -> np.ndarray:
    """``out[t] = True`` if target t at (tx[t], ty[t]) is visible from (ox, oy): the open
    segment between them crosses no wall and enters no circle other than ``skip`` and the
    target's own ``target_circle[t]`` (-1 for none). Returns ``out`` (bool, (T,)).

    A circle containing the origin or the target blocks (as in :func:`raycast`, a target is
    visible exactly when a ray toward it reaches it first). A wall passing exactly through
    the origin or the target does not block.
    """
    for t in range(tx.shape[0]):
        out[t] = segment_clear(ox, oy, tx[t], ty[t], segs, circles, skip, target_circle[t])
    return out


@njit(cache=True, inline="always", error_model="numpy")
def segment_distance(
    ax: float, ay: float, bx: float, by: float, x0: float, y0: float, x1: float, y1: float
) -> float:
    """Smallest distance [m] between segment (ax, ay)-(bx, by) and segment (x0, y0)-(x1, y1):
    0 when they meet (crossing or touching), else that of the nearest end point."""
    dx = bx - ax
    dy = by - ay
    ex = x1 - x0
    ey = y1 - y0
    denom = dx * ey - dy * ex
    if denom != 0.0:
        wx = x0 - ax
        wy = y0 - ay
        t = (wx * ey - wy * ex) / denom
        u = (wx * dy - wy * dx) / denom
        if 0.0 <= t <= 1.0 and 0.0 <= u <= 1.0:
            return 0.0
    return min(
        point_segment_distance(ax, ay, x0, y0, x1, y1),
        point_segment_distance(bx, by, x0, y0, x1, y1),
        point_segment_distance(x0, y0, ax, ay, bx, by),
        point_segment_distance(x1, y1, ax, ay, bx, by),
    )


@njit(cache=True, error_model="numpy")
def path_clearance(
    ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray, segs: np.ndarray,
    out: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """``out[m]``: the smallest distance [m] from segment (ax[m], ay[m])-(bx[m], by[m]) to
    the wall segments ``segs`` (0 where it meets one, ``inf`` without walls); a zero-length
    segment gives its point's distance. Returns ``out``."""
    for m in range(ax.shape[0]):
        best = math.inf
        for s in range(segs.shape[0]):
            d = segment_distance(ax[m], ay[m], bx[m], by[m], segs[s, 0], segs[s, 1], segs[s, 2],
                                 segs[s, 3])  # fmt: skip
            if d < best:
                best = d
        out[m] = best
    return out


@njit(cache=True, inline="always", error_model="numpy")
def wall_between(ax: float, ay: float, bx: float, by: float, segs: np.ndarray) -> bool:
    """Whether the open segment from (ax, ay) to (bx, by) meets any wall segment of
    ``segs`` (crossing or touching it): the two points do not see each other."""
    dx = bx - ax
    dy = by - ay
    if dx == 0.0 and dy == 0.0:
        return False
    for s in range(segs.shape[0]):
        if _crosses_segment(ax, ay, dx, dy, segs[s, 0], segs[s, 1], segs[s, 2], segs[s, 3]):
            return True
    return False


@njit(cache=True, inline="always", error_model="numpy")
def wall_within(ax: float, ay: float, bx: float, by: float, reach: float, segs: np.ndarray) -> bool:
    """Whether any wall segment of ``segs`` comes closer than ``reach`` [m] to the segment
    from (ax, ay) to (bx, by): a disc of radius ``reach`` cannot sweep along it."""
    lox = min(ax, bx) - reach
    hix = max(ax, bx) + reach
    loy = min(ay, by) - reach
    hiy = max(ay, by) + reach
    for s in range(segs.shape[0]):
        x0, y0, x1, y1 = segs[s, 0], segs[s, 1], segs[s, 2], segs[s, 3]
        if max(x0, x1) < lox or min(x0, x1) > hix or max(y0, y1) < loy or min(y0, y1) > hiy:
            continue
        if segment_distance(ax, ay, bx, by, x0, y0, x1, y1) < reach:
            return True
    return False


@njit(cache=True, error_model="numpy")
def leg_clearance(
    ax: float, ay: float, bx: float, by: float, segs: np.ndarray
) -> tuple[float, float]:
    """The smallest distance [m] from the segment (ax, ay)-(bx, by) to the wall segments
    ``segs``, and the smaller of its two end points' distances to them (``inf`` without
    walls)."""
    leg = math.inf
    ends = math.inf
    for s in range(segs.shape[0]):
        x0, y0, x1, y1 = segs[s, 0], segs[s, 1], segs[s, 2], segs[s, 3]
        leg = min(leg, segment_distance(ax, ay, bx, by, x0, y0, x1, y1))
        ends = min(ends, point_segment_distance(ax, ay, x0, y0, x1, y1),
                   point_segment_distance(bx, by, x0, y0, x1, y1))  # fmt: skip
    return leg, ends
