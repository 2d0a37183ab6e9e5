"""Compiled grid kernels of the global planner: wall distances, bilinear sampling, an A*
/ Dijkstra search over an 8-connected cost grid, people cost layers and path tracing.

Grids are cell-centred: cell (j, i) of a grid with origin (x0, y0) and cell size ``res``
[m] has its centre at (x0 + (i + 0.5) res, y0 + (j + 0.5) res).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from srpb_gym.sim.geometry import point_segment_distance

SQRT2 = math.sqrt(2.0)


@njit(cache=True, error_model="numpy")
def wall_distance(segs, x0, y0, res, reach, out):
    """``out[iy, ix]``: distance [m] from the centre of cell (iy, ix) to the nearest wall
    segment, capped at ``reach`` (only cells within ``reach`` of a segment are visited)."""
    ny, nx = out.shape
    out[:, :] = reach
    for s in range(segs.shape[0]):
        ax, ay, bx, by = segs[s, 0], segs[s, 1], segs[s, 2], segs[s, 3]
        i0 = max(int((min(ax, bx) - reach - x0) / res), 0)
        i1 = min(int((max(ax, bx) + reach - x0) / res) + 1, nx)
        j0 = max(int((min(ay, by) - reach - y0) / res), 0)
        j1 = min(int((max(ay, by) + reach - y0) / res) + 1, ny)
        for j in range(j0, j1):
            cy = y0 + (j + 0.5) * res
            for i in range(i0, i1):
                d = point_segment_distance(x0 + (i + 0.5) * res, cy, ax, ay, bx, by)
                if d < out[j, i]:
                    out[j, i] = d


@njit(cache=True, error_model="numpy")
def sample_grid(grid, x0, y0, res, xs, ys, outside, out):
    """Bilinear interpolation of ``grid`` (cell-centred) at the points (xs, ys); points off
    the grid read ``outside``."""
    ny, nx = grid.shape
    for k in range(xs.shape[0]):
        fx = (xs[k] - x0) / res - 0.5
        fy = (ys[k] - y0) / res - 0.5
        if not (-0.5 <= fx <= nx - 0.5 and -0.5 <= fy <= ny - 0.5):
            out[k] = outside
            continue
        i = min(max(int(fx), 0), nx - 2)  # fx >= -0.5: int() floors after the clamp
        j = min(max(int(fy), 0), ny - 2)
        u = min(max(fx - i, 0.0), 1.0)
        v = min(max(fy - j, 0.0), 1.0)
        out[k] = (
            (1 - u) * (1 - v) * grid[j, i]
            + u * (1 - v) * grid[j, i + 1]
            + (1 - u) * v * grid[j + 1, i]
            + u * v * grid[j + 1, i + 1]
        )


@njit(cache=True, error_model="numpy")
def _push(hk, hv, n, key, val):
    i = n
    hk[i], hv[i] = key, val
    while i > 0:
        p = (i - 1) >> 1
        if hk[p] <= hk[i]:
            break
        hk[p], hk[i] = hk[i], hk[p]
        hv[p], hv[i] = hv[i], hv[p]
        i = p
    return n + 1


@njit(cache=True, error_model="numpy")
def _pop(hk, hv, n):
    val = hv[0]
    n -= 1
    hk[0], hv[0] = hk[n], hv[n]
    i = 0
    while True:
        c = 2 * i + 1
        if c >= n:
            break
        if c + 1 < n and hk[c + 1] < hk[c]:
            c += 1
        if hk[i] <= hk[c]:
            break
        hk[c], hk[i] = hk[i], hk[c]
        hv[c], hv[i] = hv[i], hv[c]
        i = c
    return val, n


@njit(cache=True, error_model="numpy")
def grid_search(cost, nx, res, start, goal, h, weight, g, parent, done, hk, hv):
    """A* over the 8-connected grid of flat ``cost`` (per metre; inf: impassable) from cell
    ``start``; ``goal`` < 0 runs a full Dijkstra sweep. An edge costs its length times the
    mean cost of its two cells; diagonal moves may not cut impassable corners. ``h`` is a
    consistent heuristic (zeros for Dijkstra) weighted by ``weight`` (> 1: fewer nodes
    expanded, paths at most that factor costlier; 1.001 breaks ties towards deeper nodes).
    Fills ``g`` (cost from start) and ``parent``; returns whether ``goal`` was reached."""
    ncell = cost.shape[0]
    g[:] = np.inf
    parent[:] = -1
    done[:] = False
    g[start] = 0.0
    n = _push(hk, hv, 0, h[start], start)
    while n > 0:
        c, n = _pop(hk, hv, n)
        if done[c]:
            continue
        done[c] = True
        if c == goal:
            return True
        cx, cy = c % nx, c // nx
        for k in range(8):
            dx = (-1, 0, 1, -1, 1, -1, 0, 1)[k]
            dy = (-1, -1, -1, 0, 0, 1, 1, 1)[k]
            x, y = cx + dx, cy + dy
            m = y * nx + x
            if x < 0 or x >= nx or m < 0 or m >= ncell or done[m] or not cost[m] < np.inf:
                continue
            step = res
            if dx != 0 and dy != 0:
                if not (cost[cy * nx + x] < np.inf and cost[y * nx + cx] < np.inf):
                    continue
                step = res * SQRT2
            ng = g[c] + step * 0.5 * (cost[c] + cost[m])
            if ng < g[m]:
                g[m] = ng
                parent[m] = c
                if n >= hk.shape[0]:
                    return False
                n = _push(hk, hv, n, ng + weight * h[m], m)
    return goal < 0


@njit(cache=True, error_model="numpy")
def people_layer(cost, x0, y0, res, ax, ay, bx, by, core, core_cost, soft, scale, reach):
    """Add to ``cost`` (ny, nx) the temporary-obstacle cost of people swept along segments
    (ax, ay)-(bx, by): ``core_cost[p]`` within ``core`` [m], then ``soft`` exp(-(d - core)
    / ``scale``) up to ``core + reach``. Impassable cells stay impassable."""
    ny, nx = cost.shape
    r = core + reach
    for p in range(ax.shape[0]):
        i0 = max(int((min(ax[p], bx[p]) - r - x0) / res), 0)
        i1 = min(int((max(ax[p], bx[p]) + r - x0) / res) + 1, nx)
        j0 = max(int((min(ay[p], by[p]) - r - y0) / res), 0)
        j1 = min(int((max(ay[p], by[p]) + r - y0) / res) + 1, ny)
        for j in range(j0, j1):
            cy = y0 + (j + 0.5) * res
            for i in range(i0, i1):
                d = point_segment_distance(x0 + (i + 0.5) * res, cy, ax[p], ay[p], bx[p], by[p])
                if d < core:
                    cost[j, i] += core_cost[p]
                elif d < r:
                    cost[j, i] += soft * math.exp(-(d - core) / scale)


@njit(cache=True, error_model="numpy")
def trace_path(parent, goal, out):
    """Cells from the search's start to ``goal`` (following ``parent``) into ``out``;
    returns their number (0 when ``out`` is too short)."""
    n, c = 0, goal
    while c >= 0:
        if n >= out.shape[0]:
            return 0
        out[n] = c
        n += 1
        c = parent[c]
    out[:n] = out[:n][::-1].copy()
    return n
