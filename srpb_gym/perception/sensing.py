"""A robot's sensing of one step in one compiled call: lidar scan, distance to the nearest
obstacle and people detection, from the robot's pose in a pose table.

The random numbers come from the sensors' own ``draw`` methods, called before (lidar, then
detector: the order :meth:`Lidar.scan` and :meth:`PeopleDetector.detect` draw them in);
the arrays are the sensors' ``arrays``. The results equal those of ``Lidar.scan``,
:func:`~srpb_gym.sim.geometry.point_obstacle_distance` and ``PeopleDetector.detect``.
"""

from __future__ import annotations

from numba import njit

from srpb_gym.perception.detector import detect_kernel
from srpb_gym.perception.lidar import scan_kernel
from srpb_gym.sim.geometry import point_obstacle_distance


@njit(cache=True, error_model="numpy")
def sense(
    pose, r, segs, circles, skip, exact, obstacle_dist,
    angles, beam_dirs, lidar_params, noise, true, scan,
    people_xy, people_yaw, people_circle,
    limits, occlusion, uniform, normal, visible, index, xy, yaw_out, std,
):  # fmt: skip
    """Sense from ``pose[r]`` (x, y, yaw) among walls ``segs`` and bodies ``circles`` (own
    circle ``skip``): the lidar scan into ``true`` and ``scan``; ``obstacle_dist[r]``, the
    distance to the nearest wall or body (``exact``) or the shortest lidar range; the
    detections (see :func:`~srpb_gym.perception.detector.detect_kernel`). Returns the number
    of detections."""
    x, y, yaw = pose[r, 0], pose[r, 1], pose[r, 2]
    scan_kernel(x, y, yaw, segs, circles, skip, angles, beam_dirs, lidar_params, noise, true,
                scan)  # fmt: skip
    if exact:
        d = point_obstacle_distance(x, y, segs, circles, skip)
    else:
        d = scan[0]
        for b in range(1, scan.shape[0]):
            d = min(d, scan[b])
    obstacle_dist[r] = d
    return detect_kernel(x, y, yaw, people_xy, people_yaw, segs, circles, skip, people_circle,
                         limits, occlusion, uniform, normal, visible, index, xy, yaw_out,
                         std)  # fmt: skip
