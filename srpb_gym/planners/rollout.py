"""Trajectory rollouts of the local planners and what they are checked against.

:func:`rollout` simulates sampled velocity targets of a differential drive under its
acceleration limits in one compiled kernel and measures each trajectory's clearance from
the static map and the lidar points and its gap to the tracked people predicted at constant
velocity. :func:`scan_points` and :func:`people_array` build those obstacles from the
robot's :class:`~srpb_gym.knowledge.Knowledge`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from srpb_gym.knowledge import Knowledge
from srpb_gym.planners.global_planner import GlobalPlanner


@njit(cache=True, inline="always", error_model="numpy")
def _bilinear(grid, x0, y0, res, x, y):
    ny, nx = grid.shape
    fx = (x - x0) / res - 0.5
    fy = (y - y0) / res - 0.5
    if not (-0.5 <= fx <= nx - 0.5 and -0.5 <= fy <= ny - 0.5):
        return 0.0
    i = min(max(int(fx), 0), nx - 2)  # fx >= -0.5: int() floors after the clamp
    j = min(max(int(fy), 0), ny - 2)
    u = min(max(fx - i, 0.0), 1.0)
    v = min(max(fy - j, 0.0), 1.0)
    return (
        (1 - u) * (1 - v) * grid[j, i]
        + u * (1 - v) * grid[j, i + 1]
        + ((1 - u) * v * grid[j + 1, i] + u * v * grid[j + 1, i + 1])
    )


@njit(cache=True, error_model="numpy")
def rollout(
    x, y, yaw, v0, w0, vt, wt, acc_v, acc_w, dt, grid, gx0, gy0, res, pts, people,
    r_static, t_near, hold, traj, clear, t_static, gap, t_people, gap_near,
):  # fmt: skip
    """Simulate every sample s (target ``vt[s]``, ``wt[s]`` from the command (v0, w0) at
    most ``acc_v``, ``acc_w`` per second) for ``traj.shape[1]`` steps of ``dt`` [s].

    ``grid``: static wall distances [m] (origin gx0, gy0, cell ``res``); ``pts`` (M, 2):
    obstacle points; ``people`` (P, 5): x, y, vx, vy and collision distance [m].
    Writes ``traj[s, k]`` = (x, y, yaw, v) after step k + 1, ``clear[s]`` the smallest
    obstacle distance [m], ``t_static[s]`` the first time it falls under ``r_static``
    (inf: never), ``gap[s]`` the smallest predicted person distance minus its collision
    distance [m], ``t_people[s]`` the first time that gap is negative [s] and
    ``gap_near[s]`` the smallest gap up to ``t_near`` [s]. The people gap also covers
    ``hold`` more steps with the robot stopped at the trajectory's end (so a trajectory
    that ends in a person's way is seen to).
    """
    steps = traj.shape[1]
    dv, dw = acc_v * dt, acc_w * dt
    d0 = np.empty(pts.shape[0])  # points by distance from the start: the search stops at
    for m in range(pts.shape[0]):  # the first one that cannot be nearer than the best
        d0[m] = math.hypot(pts[m, 0] - x, pts[m, 1] - y)
    order = np.argsort(d0)
    for s in range(vt.shape[0]):
        px, py, pth, v, w = x, y, yaw, v0, w0
        cmin, gmin, gnear = np.inf, np.inf, np.inf
        ts, tp, travel = np.inf, np.inf, 0.0
        for k in range(steps):
            v += min(max(vt[s] - v, -dv), dv)
            w += min(max(wt[s] - w, -dw), dw)
            mid = pth + 0.5 * w * dt
            px += v * math.cos(mid) * dt
            py += v * math.sin(mid) * dt
            pth += w * dt
            travel += abs(v) * dt
            traj[s, k, 0], traj[s, k, 1], traj[s, k, 2], traj[s, k, 3] = px, py, pth, v
            t = (k + 1) * dt
            c = _bilinear(grid, gx0, gy0, res, px, py)
            for q in range(order.shape[0]):
                m = order[q]
                if d0[m] - travel >= c:
                    break
                c = min(c, math.hypot(px - pts[m, 0], py - pts[m, 1]))
            cmin = min(cmin, c)
            if c < r_static and ts == np.inf:
                ts = t
            for j in range(people.shape[0]):
                d = math.hypot(px - people[j, 0] - people[j, 2] * t,
                               py - people[j, 1] - people[j, 3] * t) - people[j, 4]  # fmt: skip
                gmin = min(gmin, d)
                if t <= t_near:
                    gnear = min(gnear, d)
                if d < 0.0 and tp == np.inf:
                    tp = t
        for k in range(steps, steps + hold):
            t = (k + 1) * dt
            for j in range(people.shape[0]):
                d = math.hypot(px - people[j, 0] - people[j, 2] * t,
                               py - people[j, 1] - people[j, 3] * t) - people[j, 4]  # fmt: skip
                gmin = min(gmin, d)
        clear[s], t_static[s], gap[s], t_people[s], gap_near[s] = cmin, ts, gmin, tp, gnear


def scan_points(
    k: Knowledge, planner: GlobalPlanner, reach: float, person_radius: float
) -> NDArray[np.float64]:
    """(M, 2) lidar points within ``reach`` [m] that are neither static walls (closer than
    0.1 m to one) nor people tracked this step (a coasting track may be off: its person's
    points stay obstacles)."""
    r = k.scan
    ang = k.pose[2] + k.scan_angles
    pts = np.column_stack([k.pose[0] + r * np.cos(ang), k.pose[1] + r * np.sin(ang)])
    pts = pts[r < min(reach, k.range_max - 1e-6)]
    if pts.shape[0]:
        pts = pts[planner.clearance(pts[:, 0], pts[:, 1]) > 0.1]
    fresh = k.tracks.xy[k.tracks.time_since_update < 0.5 * k.control_dt]
    if pts.shape[0] and fresh.shape[0]:  # people seen now: predicted as tracks instead
        d = np.hypot(pts[:, None, 0] - fresh[None, :, 0], pts[:, None, 1] - fresh[None, :, 1])
        pts = pts[d.min(axis=1) > person_radius + 0.25]
    return np.ascontiguousarray(pts)


def people_array(
    k: Knowledge, robot_radius: float, person_radius: float, margin: float,
    standing_speed: float,
) -> NDArray[np.float64]:  # fmt: skip
    """(P, 5) x, y, vx, vy and collision distance [m] of the tracked people: robot radius
    plus ``person_radius`` plus ``margin``, or for a person already closer the distance it
    has (minus 5 cm, at least the two radii plus 1 cm). People slower than
    ``standing_speed`` [m/s] get zero velocity (their estimate is mostly noise)."""
    tr = k.tracks
    out = np.empty((tr.xy.shape[0], 5))
    out[:, :2], out[:, 2:4] = tr.xy, tr.velocity
    out[np.hypot(*tr.velocity.T) < standing_speed, 2:4] = 0.0
    full = robot_radius + person_radius + margin
    hard = robot_radius + person_radius + 0.01
    now = np.hypot(tr.xy[:, 0] - k.pose[0], tr.xy[:, 1] - k.pose[1])
    out[:, 4] = np.maximum(hard, np.minimum(full, now - 0.05))
    return out
