"""One SRPB sample per robot and step, written by one compiled call.

:func:`record_sample` appends the robot's state with the people its tracker reports (the
tracked record) and with all people as they are (the ground-truth record), straight into
the tables of two :class:`~srpb_gym.metrics.record.EpisodeRecord` objects, with the
F-formations seen in each. It reads the tracker's state arrays
(:attr:`~srpb_gym.perception.tracker.KalmanTracker.arrays`, laid out as
:mod:`srpb_gym.perception.kalman` says) and the detector's true person
index of each detection, and remembers which true person each reported track followed
(``track_person``, for the groups the robot sees).
"""

from __future__ import annotations

import math

from numba import njit

from srpb_gym.angles import wrap_angle
from srpb_gym.metrics.record import (
    GROUPS,
    LAST_GROUP,
    LAST_MEMBER,
    LAST_ROW,
    MEMBERS,
    ROWS,
    SAMPLES,
)
from srpb_gym.perception.groups import seen_groups
from srpb_gym.perception.kalman import C_HITS, F_YAW, I_DET, I_HITS, I_ID, N_LIVE

OK, GROW_TRACK_PERSON, GROW_TRACKED, GROW_TRUTH = range(4)  # return codes of record_sample
MIN_GROUP = 2  # tracked members a formation needs to be reported as a group


@njit(cache=True, inline="always", error_model="numpy")
def _fits(tables, n, rows, groups, members):
    """Whether a record's tables have room for one more sample of this size."""
    return (
        n[SAMPLES] < tables[0].shape[0]
        and n[ROWS] + rows <= tables[1].shape[0]
        and n[ROWS] + rows <= tables[2].shape[0]
        and n[GROUPS] + groups <= tables[3].shape[0]
        and n[MEMBERS] + members <= tables[4].shape[0]
    )


@njit(cache=True, inline="always", error_model="numpy")
def _begin(tables, n, t, pose, r, velocity, goal, obstacle_dist, gids, sizes, members, g, m):
    """Write the robot row and the groups of a new sample (members index the sample's own
    people rows); returns the sample index."""
    sample = n[SAMPLES]
    row = tables[0][sample]
    row[0], row[1], row[2], row[3] = t, pose[r, 0], pose[r, 1], wrap_angle(pose[r, 2])
    row[4], row[5], row[6] = velocity[r, 0], velocity[r, 1], velocity[r, 2]
    row[7], row[8], row[9] = goal[0], goal[1], goal[2]
    row[10], row[11] = obstacle_dist[r], math.nan
    first = n[ROWS]
    n[LAST_ROW], n[LAST_GROUP], n[LAST_MEMBER] = first, n[GROUPS], n[MEMBERS]
    gint, mem = tables[3], tables[4]
    start = n[MEMBERS]
    for i in range(g):
        k = n[GROUPS] + i
        gint[k, 0], gint[k, 1], gint[k, 2], gint[k, 3] = sample, gids[i], start, sizes[i]
        start += sizes[i]
    for i in range(m):
        mem[n[MEMBERS] + i] = members[i] + first
    n[GROUPS] += g
    n[MEMBERS] += m
    n[SAMPLES] += 1
    return sample


@njit(cache=True, error_model="numpy")
def record_sample(
    t, pose, velocity, r, goal, obstacle_dist, planning_time,
    x, P, f, iv, cnt, cfg, det_index, track_person, formation_of, form_counts, scratch,
    people_xy, people_yaw, people_vel, gt_gids, gt_sizes, gt_members,
    tables, n, gt_tables, gt_n,
):  # fmt: skip
    """Append one sample of robot ``r`` to its tracked record (``tables``, ``n``) and its
    ground-truth record (``gt_tables``, ``gt_n``).

    The robot row is ``t``, ``pose[r]`` (yaw wrapped), ``velocity[r]``, ``goal``,
    ``obstacle_dist[r]`` and NaN planning time; ``planning_time`` (unless NaN) goes to the
    previous sample of both records, the decision taken there. Tracked people: the
    confirmed tracks of the tracker arrays ``x, P, f, iv, cnt, cfg``, each remembered in
    ``track_person[id]`` as ``det_index`` of its detection this step. True people: all of
    them, exact (zero covariance), with the formations ``gt_gids, gt_sizes, gt_members``.
    ``scratch`` (5, capacity) int64 and ``form_counts`` (F,) are workspace.

    Returns :data:`OK`, or without appending what the caller must grow first:
    :data:`GROW_TRACK_PERSON` (an id beyond ``track_person``), :data:`GROW_TRACKED` or
    :data:`GROW_TRUTH` (a record's tables).
    """
    if not math.isnan(planning_time):
        if n[SAMPLES] > 0:
            tables[0][n[SAMPLES] - 1, 11] = planning_time
        if gt_n[SAMPLES] > 0:
            gt_tables[0][gt_n[SAMPLES] - 1, 11] = planning_time
    live = cnt[N_LIVE]
    sel, person = scratch[0], scratch[1]
    k = 0
    for s in range(live):
        if iv[I_HITS, s] >= cfg[C_HITS]:
            if iv[I_ID, s] >= track_person.shape[0]:
                return GROW_TRACK_PERSON
            sel[k] = s
            k += 1
    for i in range(k):
        s = sel[i]
        if iv[I_DET, s] >= 0:
            track_person[iv[I_ID, s]] = det_index[iv[I_DET, s]]
        person[i] = track_person[iv[I_ID, s]]
    gids, sizes, members = scratch[2], scratch[3], scratch[4]
    g, m = seen_groups(person[:k], formation_of, MIN_GROUP, form_counts, gids, sizes, members)
    p = people_xy.shape[0]
    if not _fits(tables, n, k, g, m):
        return GROW_TRACKED
    if not _fits(gt_tables, gt_n, p, gt_gids.shape[0], gt_members.shape[0]):
        return GROW_TRUTH
    # the tracked sample
    first = n[ROWS]
    sample = _begin(tables, n, t, pose, r, velocity, goal, obstacle_dist, gids, sizes,
                    members, g, m)  # fmt: skip
    rows, ints = tables[1], tables[2]
    for i in range(k):
        s, q = sel[i], first + i
        rows[q, 0], rows[q, 1], rows[q, 2] = x[s, 0], x[s, 1], f[F_YAW, s]
        rows[q, 3], rows[q, 4], rows[q, 5], rows[q, 6] = (
            P[s, 0, 0],
            P[s, 0, 1],
            P[s, 1, 0],
            P[s, 1, 1],
        )
        rows[q, 7], rows[q, 8] = x[s, 2], x[s, 3]
        ints[q, 0], ints[q, 1] = sample, iv[I_ID, s]
    n[ROWS] += k
    # the ground-truth sample
    first = gt_n[ROWS]
    sample = _begin(gt_tables, gt_n, t, pose, r, velocity, goal, obstacle_dist, gt_gids,
                    gt_sizes, gt_members, gt_gids.shape[0], gt_members.shape[0])  # fmt: skip
    rows, ints = gt_tables[1], gt_tables[2]
    for i in range(p):
        q = first + i
        rows[q, 0], rows[q, 1], rows[q, 2] = people_xy[i, 0], people_xy[i, 1], people_yaw[i]
        rows[q, 3] = rows[q, 4] = rows[q, 5] = rows[q, 6] = 0.0
        rows[q, 7], rows[q, 8] = people_vel[i, 0], people_vel[i, 1]
        ints[q, 0], ints[q, 1] = sample, i
    gt_n[ROWS] += p
    return OK
