from __future__ import annotations

import numpy as np
import pytest

from srpb_gym.metrics import EpisodeRecord


def robot_rows(t, x=0.0, y=0.0, yaw=0.0, vx=0.0, vy=0.0, omega=0.0,
               goal=(100.0, 0.0, 0.0), obstacle_dist=10.0, planning_time=0.0):  # fmt: skip
    """(N, 12) robot table; scalars broadcast over the samples."""
    t = np.asarray(t, dtype=float)
    cols = [t, x, y, yaw, vx, vy, omega, goal[0], goal[1], goal[2], obstacle_dist, planning_time]
    return np.stack([np.broadcast_to(np.asarray(c, dtype=float), t.shape) for c in cols], axis=1)


def person(x, y, yaw=0.0, vx=0.0, vy=0.0, cov=(0.0, 0.0, 0.0, 0.0)):
    """One people row (PERSON_FIELDS order)."""
    return [x, y, yaw, cov[0], cov[1], cov[2], cov[3], vx, vy]


def record_with(robot, people_at=None, groups_at=None) -> EpisodeRecord:
    """A record from a robot table; ``people_at[n]`` = list of (id, row) at sample n;
    ``groups_at[n]`` = list of (group id, [member local indices])."""
    rec = EpisodeRecord()
    people_at = people_at or {}
    groups_at = groups_at or {}
    for n, row in enumerate(robot):
        people = people_at.get(n, [])
        groups = groups_at.get(n, [])
        rec.append(
            row,
            [pid for pid, _ in people] if people else None,
            [p for _, p in people] if people else None,
            [g for g, _ in groups] if groups else None,
            [len(m) for _, m in groups] if groups else None,
            [i for _, m in groups for i in m] if groups else None,
        )
    return rec


@pytest.fixture
def make_record():
    return record_with
