"""What the local planners do at the goal and when stuck: turn in place to the goal
heading; detect a lack of progress and run a recovery (give way, back up, rotate, replan).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.knowledge import Knowledge
from srpb_gym.planners.config import PlannerConfig
from srpb_gym.planners.global_planner import GlobalPlanner

#: Gain [1/s] of the turn in place to the goal heading, and its least speed [rad/s].
GOAL_TURN_GAIN, GOAL_TURN_MIN = 2.0, 0.15


def goal_turn(knowledge: Knowledge) -> tuple[float, float]:
    """(v, omega) that turns in place to the goal heading, braking in time (no overshoot)."""
    robot = knowledge.robot
    err = float(wrap_angle(float(knowledge.goal[2] - knowledge.pose[2])))
    w = min(robot.w_max, GOAL_TURN_GAIN * abs(err),
            0.9 * math.sqrt(2.0 * robot.acc_ang * abs(err)))  # fmt: skip
    return 0.0, math.copysign(max(w, GOAL_TURN_MIN), err)


@dataclass(frozen=True)
class RecoveryConfig(PlannerConfig):
    """Settings of the :class:`Recovery` behaviours (lengths in m, times in s)."""

    window: float = 6.0  # s, stuck: the cost-to-go fell less than ``progress`` in this time
    progress: float = 0.3  # m (cost-weighted), the progress expected within ``window``
    yield_range: float = 2.5  # m, give way to a tracked person this close ahead ...
    narrow: float = 1.0  # m, ... where the static clearance is under this (door, corridor)
    retreat: float = 1.2  # m, giving way: back along the own trail to the point this far ...
    retreat_time: float = 8.0  # s, ... for at most this long, ...
    wait_time: float = 3.0  # s, ... then wait there this long
    backup_time: float = 1.5  # s, otherwise back up for at most this long ...
    backup_speed: float = 0.1  # m/s, ... at this speed (at most the robot's -v_min), ...
    rotate_time: float = 2.0  # s, ... then rotate towards the path for at most this long

    def __post_init__(self) -> None:
        self._positive("window")
        self._nonnegative("progress", "yield_range", "narrow", "retreat", "retreat_time",
                          "wait_time", "backup_time", "backup_speed", "rotate_time")  # fmt: skip


class Recovery:
    """Stuck detection and recovery behaviours (like ROS move_base's recoveries).

    The robot is stuck when its static cost-to-go of the goal (metres weighted by the
    inflation cost) fell by less than ``progress`` in ``window`` [s]. When a tracked person
    is within ``yield_range`` [m] ahead in a narrow place (static clearance under ``narrow``
    [m]: a door, a corridor), the robot gives way: it drives back along its own
    trail to the point ``retreat`` [m] away ("retreat", at most ``retreat_time`` [s]) and
    waits there ``wait_time`` [s] ("wait"). Otherwise it backs up at ``backup_speed``
    [m/s] (at most the robot's reverse speed limit) for ``backup_time`` [s] while the way
    behind is clear ("backup"; not for a base that cannot reverse) and rotates in place
    towards the path for at most ``rotate_time`` [s] ("rotate").

    ``config``: the settings (:class:`RecoveryConfig`, a mapping of the fields to change,
    or ``None``: the defaults).
    """

    def __init__(self, config: RecoveryConfig | Mapping[str, Any] | None = None) -> None:
        self.config = RecoveryConfig.from_spec(config)
        self.reset()

    def reset(self) -> None:
        self.history: deque[tuple[float, float]] = deque()
        self.trail: deque[tuple[float, float]] = deque(maxlen=600)
        self.phase, self.until = "", -math.inf
        self.target = np.zeros(2)

    def observe(
        self, knowledge: Knowledge, cost_to_go: float, ahead: NDArray, clearance: float
    ) -> bool:
        """Record this step (``ahead``: unit direction of the path, ``clearance``: the
        static clearance [m] here); returns whether a recovery starts now."""
        t, x, y = knowledge.t, float(knowledge.pose[0]), float(knowledge.pose[1])
        cfg = self.config
        if not self.trail or math.hypot(x - self.trail[-1][0], y - self.trail[-1][1]) > 0.05:
            self.trail.append((x, y))
        if self.phase:
            return False
        self.history.append((t, cost_to_go))
        while self.history[0][0] < t - cfg.window - 1e-9:
            self.history.popleft()
        t0, c0 = self.history[0]
        if t - t0 < cfg.window - 1e-9 or c0 - cost_to_go >= cfg.progress:
            return False
        self.history.clear()
        rel = knowledge.tracks.xy - knowledge.pose[:2]
        dist = np.hypot(rel[:, 0], rel[:, 1])
        front = (dist < cfg.yield_range) & (rel @ ahead > 0.3 * dist)
        trail = np.array(self.trail)
        far = np.flatnonzero(np.hypot(trail[:, 0] - x, trail[:, 1] - y) >= cfg.retreat)
        if front.any() and far.size and clearance < cfg.narrow:
            self.phase, self.until = "retreat", t + cfg.retreat_time
            self.target = trail[far[-1]]
        else:
            self.phase, self.until = "backup", t + cfg.backup_time
        return True

    def command(
        self, knowledge: Knowledge, planner: GlobalPlanner, target: NDArray[np.float64]
    ) -> tuple[float, float] | None:
        """(v, omega) of a backup, rotate or wait phase now (None: the phase is over or
        is "retreat", which the planner drives itself)."""
        t, (x, y, yaw) = knowledge.t, knowledge.pose
        cfg, robot = self.config, knowledge.robot
        if self.phase == "retreat":
            if t < self.until and math.hypot(self.target[0] - x, self.target[1] - y) > 0.25:
                return None
            self.phase, self.until = "wait", t + cfg.wait_time
        if self.phase == "wait":
            if t < self.until:
                return 0.0, 0.0
            self.phase, self.until = "rotate", t + cfg.rotate_time
        if self.phase == "backup":
            back = np.arange(1, 5) * 0.1
            clear = planner.clearance(x - back * math.cos(yaw), y - back * math.sin(yaw))
            rel = knowledge.tracks.xy - knowledge.pose[:2]
            behind = (rel @ np.array([math.cos(yaw), math.sin(yaw)])) < 0.2
            people = (np.hypot(*rel.T) < 1.2) & behind
            clear_behind = clear.min() > planner.robot_radius + 0.05 and not people.any()
            if t < self.until and robot.v_min < 0.0 and clear_behind:
                return max(-cfg.backup_speed, robot.v_min), 0.0
            self.phase, self.until = "rotate", t + cfg.rotate_time
        if self.phase == "rotate":
            err = float(wrap_angle(math.atan2(target[1] - y, target[0] - x) - yaw))
            if t < self.until and abs(err) > 0.15:
                w = min(robot.w_max, 2.0 * abs(err), math.sqrt(2 * robot.acc_ang * abs(err)))
                return 0.0, math.copysign(w, err)
            self.phase = ""
            planner.last_plan = -math.inf  # replan now
        return None
