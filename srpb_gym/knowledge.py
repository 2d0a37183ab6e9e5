"""What a robot knows at one control step: the snapshot the task hands to planners.

Below both the task (:meth:`srpb_gym.task.RobotTask.knowledge` builds it) and the planners
(:mod:`srpb_gym.planners` read it), so neither imports the other. :func:`true_people` puts
the people as they are in the tracker's :class:`Tracks` form, for the reference planners
that are handed the ground truth (:data:`srpb_gym.planners.REFERENCE_PLANNERS`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from srpb_gym.perception.tracker import Tracks
from srpb_gym.sim.robot import RobotConfig

__all__ = ["Knowledge", "true_people"]


@dataclass(frozen=True)
class Knowledge:
    """What the robot knows at one control step (arrays are read-only views; copy to keep).

    ``walls`` (S, 4) segments and ``bounds`` (xmin, ymin, xmax, ymax) [m]: the static map.
    ``pose`` (x, y, yaw), ``velocity`` measured body-frame (vx, vy, omega), ``command`` the
    last command sent (vx, vy, omega), ``goal`` (x, y, yaw), ``goal_tolerance`` [m].
    ``tracks``: the tracker's people (ids, xy, velocity, yaw, 2x2 covariance, ...); for a
    reference planner (``Planner.ground_truth``) the true people (:func:`true_people`).
    ``scan`` lidar ranges [m] at ``scan_angles`` (relative to the heading), ``range_max``
    and ``range_min`` [m], the lidar's reading limits.
    ``robot``: the base's limits; ``control_dt`` [s]; ``t`` [s] since the episode start.
    """

    walls: NDArray[np.float64]
    bounds: tuple[float, float, float, float]
    pose: NDArray[np.float64]
    velocity: NDArray[np.float64]
    command: NDArray[np.float64]
    goal: NDArray[np.float64]
    goal_tolerance: float
    goal_yaw_tolerance: float
    tracks: Tracks
    scan: NDArray[np.float64]
    scan_angles: NDArray[np.float64]
    range_max: float
    robot: RobotConfig
    control_dt: float
    t: float
    range_min: float = 0.05  # the default lidar's


def true_people(
    xy: NDArray[np.float64], velocity: NDArray[np.float64], yaw: NDArray[np.float64], t: float
) -> Tracks:
    """The people as they are, in the tracker's :class:`Tracks` form: every person, ``ids``
    their index in the episode, exact ``xy`` (P, 2) [m], ``velocity`` (P, 2) [m/s] and
    ``yaw`` (P,) [rad], zero covariance (as the ground-truth record holds them), each
    there since the episode start (``age`` ``t`` [s]) and seen now (``time_since_update``
    0, ``matched``; ``detection`` -1: no detector involved). Read-only copies, like the
    tracker's views."""
    p = xy.shape[0]
    arrays = (
        np.arange(p, dtype=np.int64), np.array(xy, dtype=np.float64),
        np.array(velocity, dtype=np.float64), np.array(yaw, dtype=np.float64),
        np.zeros((p, 2, 2)), np.full(p, float(t)), np.zeros(p), np.ones(p, dtype=bool),
        np.full(p, -1, dtype=np.int64),
    )  # fmt: skip
    for a in arrays:
        a.flags.writeable = False
    return Tracks(*arrays)
