"""F-formations as the robot's perception reports them: groups of tracked people.

:func:`seen_groups` gives the groups the metrics score: it knows which formation the
person a track last followed belongs to, and reports a group at a step when at least
``min_members`` of its members are tracked then (two by default: one person alone is not
recognised as a group). :func:`detect_groups` finds groups from the tracks alone, as a
planner or a policy must, and :func:`ospace_gaussians` gives their O-spaces as the
``fsi`` metric sees them.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from numpy.typing import NDArray

from srpb_gym.metrics import kernels
from srpb_gym.metrics.episode import group_ellipses

if TYPE_CHECKING:
    from srpb_gym.metrics.params import MetricParams
    from srpb_gym.perception.tracker import Tracks


@njit(cache=True, error_model="numpy")
def seen_groups(track_person, formation_of, min_members, counts, gids, sizes, members):
    """Groups among the tracks: ``track_person`` (K,) is the person each track follows (-1
    unknown), ``formation_of`` (P,) each person's formation (-1 none), ``counts`` a scratch
    array with one entry per formation. Writes group ids (formation indices), sizes and
    member track rows into the first entries of ``gids``, ``sizes``, ``members``; returns
    (number of groups, number of members)."""
    counts[:] = 0
    for i in range(track_person.shape[0]):
        p = track_person[i]
        if p >= 0 and formation_of[p] >= 0:
            counts[formation_of[p]] += 1
    g, m = 0, 0
    for f in range(counts.shape[0]):
        if counts[f] < min_members:
            continue
        gids[g], sizes[g] = f, counts[f]
        g += 1
        for i in range(track_person.shape[0]):
            p = track_person[i]
            if p >= 0 and formation_of[p] == f:
                members[m] = i
                m += 1
    return g, m


@njit(cache=True, error_model="numpy")
def standing_groups(xy, velocity, age, standing_speed, distance, min_age, parent, members,
                    start, size):  # fmt: skip
    """The kernel of :func:`detect_groups`: ``parent`` (K,) is scratch; writes the member
    rows (increasing within a group; groups in the order of their first member) and each
    group's start and size into the first entries of ``members``, ``start``, ``size``;
    returns (number of groups, number of members)."""
    n = xy.shape[0]
    for i in range(n):
        still = math.hypot(velocity[i, 0], velocity[i, 1]) < standing_speed
        parent[i] = i if still and age[i] >= min_age else -1
    for i in range(n):  # union by the smaller root: each root is its set's first row
        if parent[i] < 0:
            continue
        for j in range(i + 1, n):
            if parent[j] < 0 or math.hypot(xy[j, 0] - xy[i, 0], xy[j, 1] - xy[i, 1]) >= distance:
                continue
            ri, rj = i, j
            while parent[ri] != ri:
                ri = parent[ri]
            while parent[rj] != rj:
                rj = parent[rj]
            if ri != rj:
                parent[max(ri, rj)] = min(ri, rj)
    for i in range(n):  # flatten: every row points at its root
        if parent[i] >= 0:
            r = i
            while parent[r] != r:
                r = parent[r]
            parent[i] = r
    g, m = 0, 0
    for r in range(n):
        if parent[r] != r:
            continue
        k = 0
        for j in range(r, n):
            if parent[j] == r:
                members[m + k] = j
                k += 1
        if k >= 2:
            start[g], size[g] = m, k
            g += 1
            m += k
    return g, m


def detect_groups(
    tracks: Tracks, standing_speed: float = 0.3, distance: float = 2.0, min_age: float = 1.0
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """F-formations among the tracks, from what the robot sees alone: connected sets of at
    least two standing tracks (slower than ``standing_speed`` [m/s], tracked for ``min_age``
    [s] at least: new tracks start at rest) each within ``distance`` [m] of another.

    Returns (members, start, size) in the layout of the metric code: group g's member
    track rows are ``members[start[g] : start[g] + size[g]]``.
    """
    n = tracks.xy.shape[0]
    parent, members = np.empty(n, np.int64), np.empty(n, np.int64)
    start, size = np.empty(n // 2, np.int64), np.empty(n // 2, np.int64)
    g, m = standing_groups(np.ascontiguousarray(tracks.xy, dtype=np.float64),
                           np.ascontiguousarray(tracks.velocity, dtype=np.float64),
                           np.ascontiguousarray(tracks.age, dtype=np.float64),
                           float(standing_speed), float(distance), float(min_age), parent,
                           members, start, size)  # fmt: skip
    return members[:m].copy(), start[:g].copy(), size[:g].copy()


def ospace_gaussians(
    tracks: Tracks, members: NDArray[np.int64], start: NDArray[np.int64],
    size: NDArray[np.int64], params: MetricParams,
) -> NDArray[np.float64]:  # fmt: skip
    """(G, 8) rows of the groups' O-spaces as the ``fsi`` metric sees them (``paper``
    semantics): the ellipse (centre x, y, semi-axes a, b, orientation) of
    :func:`srpb_gym.metrics.episode.group_ellipses` and the element-wise largest position
    covariance of the members (sxx, sxy, syy)."""
    g = size.shape[0]
    if g == 0:
        return np.zeros((0, 8))
    px, py = np.ascontiguousarray(tracks.xy[:, 0]), np.ascontiguousarray(tracks.xy[:, 1])
    ellipses, _ = group_ellipses(px, py, members, start, size, params, False)
    cov = tracks.covariance
    sxx, sxy, syy = np.empty(g), np.empty(g), np.empty(g)
    kernels.group_covariances(
        np.ascontiguousarray(cov[:, 0, 0]), np.ascontiguousarray(cov[:, 0, 1]),
        np.ascontiguousarray(cov[:, 1, 0]), np.ascontiguousarray(cov[:, 1, 1]),
        members, start, size, False, sxx, sxy, syy,
    )  # fmt: skip
    return np.column_stack([ellipses, sxx, sxy, syy])
