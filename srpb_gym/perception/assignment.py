"""Linear sum assignment, compiled: the tracker's pairing of tracks and detections.

:func:`linear_sum_assignment` is the shortest augmenting path algorithm of Crouse (2016),
step for step as :func:`scipy.optimize.linear_sum_assignment` runs it (same order of the
columns searched, same tie-breaking, same floating-point operations), so both return the
same pairs, ties included; ``tests/perception/test_assignment.py`` checks that against
scipy. Being a numba function, it runs inside the tracker's compiled step.

    D. F. Crouse, "On implementing 2D rectangular assignment algorithms", IEEE Transactions
    on Aerospace and Electronic Systems 52(4), 1679-1696, 2016.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

INFEASIBLE, INVALID = -1, -2  # return codes of linear_sum_assignment


@njit(cache=True, error_model="numpy")
def _augmenting_path(nc, cost, u, v, path, row4col, spc, i, SR, SC, remaining):
    """The sink column of the shortest augmenting path from row ``i`` and its length (or -1
    when every remaining column is unreachable)."""
    min_val = 0.0
    num_remaining = nc
    for it in range(nc):
        remaining[it] = nc - it - 1  # reverse order: a constant matrix gives the identity
    SR[:] = False
    SC[:] = False
    spc[:] = math.inf
    sink = -1
    while sink == -1:
        index = -1
        lowest = math.inf
        SR[i] = True
        for it in range(num_remaining):
            j = remaining[it]
            r = min_val + cost[i * nc + j] - u[i] - v[j]
            if r < spc[j]:
                path[j] = i
                spc[j] = r
            # among equal costs prefer a column that ends the path
            if spc[j] < lowest or (spc[j] == lowest and row4col[j] == -1):
                lowest = spc[j]
                index = it
        min_val = lowest
        if min_val == math.inf:
            return -1, min_val
        j = remaining[index]
        if row4col[j] == -1:
            sink = j
        else:
            i = row4col[j]
        SC[j] = True
        num_remaining -= 1
        remaining[index] = remaining[num_remaining]
    return sink, min_val


@njit(cache=True, error_model="numpy")
def linear_sum_assignment(cost, nr, nc, rows, cols):
    """Minimum-cost assignment of the ``nr`` x ``nc`` matrix ``cost`` (row-major, flat,
    float64): writes the row and column of each of the min(nr, nc) pairs into ``rows`` and
    ``cols`` (rows ascending) and returns their number, or :data:`INFEASIBLE` (no complete
    assignment of finite cost) or :data:`INVALID` (a NaN or -inf entry)."""
    if nr == 0 or nc == 0:
        return 0
    transpose = nc < nr
    if transpose:  # the algorithm needs at least as many columns as rows
        c = np.empty(nr * nc)
        for i in range(nr):
            for j in range(nc):
                c[j * nr + i] = cost[i * nc + j]
        nr, nc = nc, nr
    else:
        c = cost[: nr * nc]
    for k in range(nr * nc):
        if c[k] != c[k] or c[k] == -math.inf:
            return INVALID
    u, v, spc = np.zeros(nr), np.zeros(nc), np.empty(nc)
    path, row4col = np.full(nc, -1, np.int64), np.full(nc, -1, np.int64)
    col4row, remaining = np.full(nr, -1, np.int64), np.empty(nc, np.int64)
    SR, SC = np.zeros(nr, np.bool_), np.zeros(nc, np.bool_)
    for cur in range(nr):
        sink, min_val = _augmenting_path(nc, c, u, v, path, row4col, spc, cur, SR, SC,
                                         remaining)  # fmt: skip
        if sink < 0:
            return INFEASIBLE
        u[cur] += min_val  # update the dual variables
        for i in range(nr):
            if SR[i] and i != cur:
                u[i] += min_val - spc[col4row[i]]
        for j in range(nc):
            if SC[j]:
                v[j] -= min_val - spc[j]
        j = sink  # augment the previous solution
        while True:
            i = path[j]
            row4col[j] = i
            col4row[i], j = j, col4row[i]
            if i == cur:
                break
    if transpose:  # pairs (col4row[j], j) in order of the original rows
        for k in range(nr):
            rows[k], cols[k] = col4row[k], k
        for k in range(1, nr):  # insertion sort by row (distinct rows, few pairs)
            a, b, m = rows[k], cols[k], k - 1
            while m >= 0 and rows[m] > a:
                rows[m + 1], cols[m + 1] = rows[m], cols[m]
                m -= 1
            rows[m + 1], cols[m + 1] = a, b
    else:
        for k in range(nr):
            rows[k], cols[k] = k, col4row[k]
    return nr
