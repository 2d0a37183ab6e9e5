"""What the local planners do at the goal and when stuck: turn in place to the goal
heading; detect a lack of progress and run a recovery (give way, back up, rotate, replan).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.planners.base import Knowledge
from srpb_gym.planners.global_planner import GlobalPlanner


def goal_turn(knowledge: Knowledge, gain: float = 2.0) -> tuple[float, float]:
    """(v, omega) that turns in place to the goal heading, braking in time (no overshoot)."""
    robot = knowledge.robot
    err = float(wrap_angle(float(knowledge.goal[2] - knowledge.pose[2])))
    w = min(robot.w_max, gain * abs(err), 0.9 * math.sqrt(2.0 * robot.acc_ang * abs(err)))
    return 0.0, math.copysign(max(w, 0.15), err)


class Recovery:
    """Stuck detection and recovery behaviours (like ROS move_base's recoveries).

    The robot is stuck when its static cost-to-go of the goal (metres weighted by the
    inflation cost) fell by less than ``progress`` in ``window`` [s]. When a tracked person
    is within ``yield_range`` [m] ahead in a narrow place (static clearance under ``narrow``
    [m]: a door, a corridor), the robot gives way: it drives back along its own
    trail to the point ``retreat`` [m] away ("retreat", at most ``retreat_time`` [s]) and
    waits there ``wait_time`` [s] ("wait"). Otherwise it backs up at ``backup_speed``
    [m/s] for ``backup_time`` [s] while the way behind is clear ("backup") and rotates in
    place towards the path for at most ``rotate_time`` [s] ("rotate").
    """

    def __init__(
        self, window: float = 6.0, progress: float = 0.3, yield_range: float = 2.5,
        retreat: float = 1.2, retreat_time: float = 8.0, wait_time: float = 3.0,
        narrow: float = 1.0,
        backup_time: float = 1.5, backup_speed: float = -0.1, rotate_time: float = 2.0,
    ) -> None:  # fmt: skip
        self.window, self.progress, self.yield_range = window, progress, yield_range
        self.retreat, self.retreat_time, self.wait_time = retreat, retreat_time, wait_time
        self.narrow = narrow
        self.backup_time, self.backup_speed = backup_time, backup_speed
        self.rotate_time = rotate_time
        self.reset()

    def reset(self) -> None:
        self.history: deque[tuple[float, float]] = deque()
        self.trail: deque[tuple[float, float]] = deque(maxlen=600)
        self.phase, self.until, self.count = "", -math.inf, 0
        self.target = np.zeros(2)

    def observe(
        self, knowledge: Knowledge, cost_to_go: float, ahead: NDArray, clearance: float
    ) -> bool:
        """Record this step (``ahead``: unit direction of the path, ``clearance``: the
        static clearance [m] here); returns whether a recovery starts now."""
        t, x, y = knowledge.t, float(knowledge.pose[0]), float(knowledge.pose[1])
        if not self.trail or math.hypot(x - self.trail[-1][0], y - self.trail[-1][1]) > 0.05:
            self.trail.append((x, y))
        if self.phase:
            return False
        self.history.append((t, cost_to_go))
        while self.history[0][0] < t - self.window - 1e-9:
            self.history.popleft()
        t0, c0 = self.history[0]
        if t - t0 < self.window - 1e-9 or c0 - cost_to_go >= self.progress:
            return False
        self.count += 1
        self.history.clear()
        rel = knowledge.tracks.xy - knowledge.pose[:2]
        dist = np.hypot(rel[:, 0], rel[:, 1])
        front = (dist < self.yield_range) & (rel @ ahead > 0.3 * dist)
        trail = np.array(self.trail)
        far = np.flatnonzero(np.hypot(trail[:, 0] - x, trail[:, 1] - y) >= self.retreat)
        if front.any() and far.size and clearance < self.narrow:
            self.phase, self.until = "retreat", t + self.retreat_time
            self.target = trail[far[-1]]
        else:
            self.phase, self.until = "backup", t + self.backup_time
        return True

    def command(
        self, knowledge: Knowledge, planner: GlobalPlanner, target: NDArray[np.float64]
    ) -> tuple[float, float] | None:
        """(v, omega) of a backup, rotate or wait phase now (None: the phase is over or
        is "retreat", which the planner drives itself)."""
        t, (x, y, yaw) = knowledge.t, knowledge.pose
        if self.phase == "retreat":
            if t < self.until and math.hypot(self.target[0] - x, self.target[1] - y) > 0.25:
                return None
            self.phase, self.until = "wait", t + self.wait_time
        if self.phase == "wait":
            if t < self.until:
                return 0.0, 0.0
            self.phase, self.until = "rotate", t + self.rotate_time
        if self.phase == "backup":
            back = np.arange(1, 5) * 0.1
            clear = planner.clearance(x - back * math.cos(yaw), y - back * math.sin(yaw))
            rel = knowledge.tracks.xy - knowledge.pose[:2]
            behind = (rel @ np.array([math.cos(yaw), math.sin(yaw)])) < 0.2
            people = (np.hypot(*rel.T) < 1.2) & behind
            if t < self.until and clear.min() > planner.robot_radius + 0.05 and not people.any():
                return self.backup_speed, 0.0
            self.phase, self.until = "rotate", t + self.rotate_time
        if self.phase == "rotate":
            err = float(wrap_angle(math.atan2(target[1] - y, target[0] - x) - yaw))
            if t < self.until and abs(err) > 0.15:
                robot = knowledge.robot
                w = min(robot.w_max, 2.0 * abs(err), math.sqrt(2 * robot.acc_ang * abs(err)))
                return 0.0, math.copysign(w, err)
            self.phase = ""
            planner.last_plan = -math.inf  # replan now
        return None
