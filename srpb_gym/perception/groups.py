"""F-formations as the robot's perception reports them: groups of tracked people.

A group is reported at a step when at least ``min_members`` of its members are tracked
then (two by default: one person alone is not recognised as a group). Which formation a
track belongs to comes from the person the track last followed.
"""

from __future__ import annotations

from numba import njit


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
