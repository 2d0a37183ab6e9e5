"""One interface for everything that drives the robot.

A planner sees what the robot knows, never the ground truth: the observation and a
:class:`Knowledge` snapshot (static map, own state, goal, tracked people with
covariances, lidar scan), from which classical planners decide and learned policies that
record their observation settings build their own observation. It returns an action of
the environment's action space (``Box(-1, 1)``; see :class:`srpb_gym.env.SRPBNavEnv`).
:class:`Knowledge` lives in :mod:`srpb_gym.knowledge`, below the task that builds it and the
planners that read it. The one exception are the reference planners
(:data:`srpb_gym.planners.REFERENCE_PLANNERS`, ``ground_truth`` set): whoever drives them
hands them the true people in ``knowledge.tracks``, to show what a good driver achieves when
perception is perfect; they are no baselines.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.knowledge import Knowledge
from srpb_gym.sim.robot import RobotConfig

#: Assumed body radius of a tracked person [m], the default of the planners' settings.
PERSON_RADIUS = 0.3


class Planner(ABC):
    """A policy for the environment. ``reset`` starts an episode; ``act`` decides a step.

    A planner with settings names their frozen dataclass in ``config_class`` and is built
    as ``Planner(config)`` (an instance, a mapping of the fields to change, or ``None``);
    it keeps the resolved settings in ``config``. A planner with ``ground_truth`` is handed
    the true people instead of the tracker's (:func:`knowledge_for`).
    """

    name: ClassVar[str] = "planner"
    config_class: ClassVar[type[Any] | None] = None
    #: whether the planner is handed the true people in ``knowledge.tracks`` (reference
    #: planners only): drivers build its knowledge with ``knowledge(ground_truth=True)``
    ground_truth: ClassVar[bool] = False

    def reset(self, knowledge: Knowledge) -> None:  # noqa: B027 - optional hook
        """Start an episode (plan on the static map, clear state)."""

    @abstractmethod
    def act(self, observation: Any, knowledge: Knowledge) -> NDArray[np.float32]:
        """The action for this step."""


def knowledge_for(planner: Planner, source: Callable[..., Knowledge], *args: Any) -> Knowledge:
    """The knowledge ``planner`` is handed: ``source(*args)`` (an environment's
    ``knowledge``, e.g. ``env.unwrapped.knowledge`` or a PettingZoo environment's with the
    agent), with the true people for a planner with ``ground_truth``."""
    if getattr(planner, "ground_truth", False):
        return source(*args, ground_truth=True)
    return source(*args)


def command_to_action(
    vx: float, vy: float, omega: float, robot: RobotConfig
) -> NDArray[np.float32]:
    """The environment action that requests the body-frame command (vx [m/s], vy [m/s],
    omega [rad/s]) of ``robot`` (a base that cannot reverse gets 0 for vx < 0)."""
    reverse = -robot.v_min if robot.v_min < 0 else math.inf
    lin = vx / robot.v_max if vx >= 0 else vx / reverse
    rot = omega / robot.w_max
    if robot.kinematics == "holonomic":
        side = vy / robot.vy_max if robot.vy_max > 0 else 0.0
        return np.clip(np.array([lin, side, rot], dtype=np.float32), -1.0, 1.0)
    return np.clip(np.array([lin, rot], dtype=np.float32), -1.0, 1.0)


def heading_error(knowledge: Knowledge, x: float, y: float) -> float:
    """Angle from the robot's heading to the point (x, y), in (-pi, pi]."""
    px, py, yaw = knowledge.pose
    return float(wrap_angle(math.atan2(y - py, x - px) - yaw))
