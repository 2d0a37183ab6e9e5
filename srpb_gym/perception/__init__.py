"""Robot perception: a planar lidar, a noisy people detector and a Kalman people tracker.

Quick use::

    from srpb_gym.perception import Lidar, PeopleDetector
    lidar = Lidar("wide")                       # or a LidarConfig, a mapping, None
    ranges = lidar.scan(x, y, yaw, segs, circles, skip, rng)
    detector = PeopleDetector("camera")
    found = detector.detect(x, y, yaw, people_xy, people_yaw, circles, skip,
                            people_circle, segs, rng)
"""

from srpb_gym.perception.detector import PRESETS as DETECTOR_PRESETS
from srpb_gym.perception.detector import (
    Detections,
    DetectorConfig,
    PeopleDetector,
    visible_people,
)
from srpb_gym.perception.lidar import PRESETS as LIDAR_PRESETS
from srpb_gym.perception.lidar import Lidar, LidarConfig, beam_angles
from srpb_gym.perception.tracker import PRESETS as TRACKER_PRESETS
from srpb_gym.perception.tracker import KalmanTracker, TrackerConfig, Tracks

__all__ = [
    "DETECTOR_PRESETS",
    "LIDAR_PRESETS",
    "TRACKER_PRESETS",
    "Detections",
    "DetectorConfig",
    "KalmanTracker",
    "Lidar",
    "LidarConfig",
    "PeopleDetector",
    "TrackerConfig",
    "Tracks",
    "beam_angles",
    "visible_people",
]
