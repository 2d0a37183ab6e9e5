"""The sanity baseline: a straight-line proportional controller."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.knowledge import Knowledge
from srpb_gym.planners.base import Planner, command_to_action, heading_error
from srpb_gym.planners.config import PlannerConfig


@dataclass(frozen=True)
class GoToGoalConfig(PlannerConfig):
    """Settings of the :class:`GoToGoal` controller."""

    k_turn: float = 2.0  # 1/s, angular velocity per radian of heading error
    slow_radius: float = 1.0  # m, closer to the goal the speed ramps down linearly

    def __post_init__(self) -> None:
        self._positive("k_turn", "slow_radius")


class GoToGoal(Planner):
    """Turn towards the goal, drive straight at it, then turn to the goal heading.

    Ignores obstacles and people. ``k_turn`` [1/s]: angular gain; ``slow_radius`` [m]:
    distance under which the speed ramps down. The speed and turn rate limits are the
    robot's. ``config``: the settings (:class:`GoToGoalConfig`, a mapping of the fields to
    change, or ``None``: the defaults).
    """

    name = "go-to-goal"
    config_class: ClassVar[type[GoToGoalConfig]] = GoToGoalConfig

    def __init__(self, config: GoToGoalConfig | Mapping[str, Any] | None = None) -> None:
        self.config = self.config_class.from_spec(config)

    def act(self, observation: Any, knowledge: Knowledge) -> NDArray[np.float32]:
        cfg, robot = self.config, knowledge.robot
        gx, gy, gyaw = knowledge.goal
        dist = math.hypot(gx - knowledge.pose[0], gy - knowledge.pose[1])
        arrive = 0.5 * knowledge.goal_tolerance
        if dist > arrive:
            err = heading_error(knowledge, gx, gy)
        else:
            err = float(wrap_angle(gyaw - knowledge.pose[2]))
        omega = float(np.clip(cfg.k_turn * err, -robot.w_max, robot.w_max))
        speed = 0.0
        if dist > arrive:
            speed = robot.v_max * min(1.0, dist / cfg.slow_radius) * max(0.0, math.cos(err)) ** 4
        return command_to_action(speed, 0.0, omega, robot)
