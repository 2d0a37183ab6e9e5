"""The sanity baseline: a straight-line proportional controller."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.planners.base import Knowledge, Planner, command_to_action, heading_error


class GoToGoal(Planner):
    """Turn towards the goal, drive straight at it, then turn to the goal heading.

    Ignores obstacles and people. ``k_turn`` [1/s]: angular gain; ``slow_radius`` [m]:
    distance under which the speed ramps down.
    """

    name = "go-to-goal"

    def __init__(self, k_turn: float = 2.0, slow_radius: float = 1.0) -> None:
        self.k_turn, self.slow_radius = k_turn, slow_radius

    def act(self, observation: Any, knowledge: Knowledge) -> NDArray[np.float32]:
        robot = knowledge.robot
        gx, gy, gyaw = knowledge.goal
        dist = math.hypot(gx - knowledge.pose[0], gy - knowledge.pose[1])
        arrive = 0.5 * knowledge.goal_tolerance
        if dist > arrive:
            err = heading_error(knowledge, gx, gy)
        else:
            err = float(wrap_angle(gyaw - knowledge.pose[2]))
        omega = float(np.clip(self.k_turn * err, -robot.w_max, robot.w_max))
        speed = 0.0
        if dist > arrive:
            speed = robot.v_max * min(1.0, dist / self.slow_radius) * max(0.0, math.cos(err)) ** 4
        return command_to_action(speed, 0.0, omega, robot)
