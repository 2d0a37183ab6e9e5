"""What a robot knows at one control step: the snapshot the task hands to planners.

Below both the task (:meth:`srpb_gym.task.RobotTask.knowledge` builds it) and the planners
(:mod:`srpb_gym.planners` read it), so neither imports the other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from srpb_gym.perception.tracker import Tracks
from srpb_gym.sim.robot import RobotConfig

__all__ = ["Knowledge"]


@dataclass(frozen=True)
class Knowledge:
    """What the robot knows at one control step (arrays are read-only views; copy to keep).

    ``walls`` (S, 4) segments and ``bounds`` (xmin, ymin, xmax, ymax) [m]: the static map.
    ``pose`` (x, y, yaw), ``velocity`` measured body-frame (vx, vy, omega), ``command`` the
    last command sent (vx, vy, omega), ``goal`` (x, y, yaw), ``goal_tolerance`` [m].
    ``tracks``: the tracker's people (ids, xy, velocity, yaw, 2x2 covariance, ...).
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
