"""Mobile base model: kinematic limits, command limiting and measured velocity.

Commands are body-frame velocities (vx [m/s], vy [m/s], omega [rad/s]). A differential-drive
base (the default, like the robot of the SRPB paper) ignores vy. Commands are clipped to
the velocity limits and then to what the acceleration limits allow from the previous
command, as a velocity smoother on a real base does. What the robot actually did (the
velocity the metrics read) is measured from its pose change, so collisions show up in it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numba import njit
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.config import from_spec

KINEMATICS = ("diff", "holonomic")


@dataclass(frozen=True)
class RobotConfig:
    """Limits and physical properties of a mobile base (SRPB paper, Table 2)."""

    kinematics: str = "diff"  # "diff" (unicycle) or "holonomic"
    radius: float = 0.275  # m, circumradius of the circular footprint
    v_min: float = -0.1  # m/s, forward velocity range
    v_max: float = 0.5  # m/s
    vy_max: float = 0.3  # m/s, lateral velocity bound (holonomic only)
    w_max: float = 1.05  # rad/s, angular velocity bound
    acc_lin: float = 1.0  # m/s^2, linear acceleration bound (x and y)
    acc_ang: float = 1.05  # rad/s^2, angular acceleration bound
    mass: float = 30.0  # kg
    drive_accel: float = 20.0  # m/s^2, the most the drive can accelerate the body
    # m, collision skin around the footprint. The physics detects a contact only after a
    # substep has moved the body, so a body can overlap by up to speed x physics_dt (12.5
    # mm at 0.5 m/s and 0.025 s) before it is pushed back; the bumper absorbs that overlap
    # and a contact of the bumper is what counts as a collision.
    bumper: float = 0.01

    DIMS: ClassVar[dict[str, int]] = {"diff": 2, "holonomic": 3}

    def __post_init__(self) -> None:
        if self.kinematics not in KINEMATICS:
            raise ValueError(f"kinematics must be one of {KINEMATICS}, got {self.kinematics!r}")
        if not (self.v_min <= 0.0 < self.v_max):
            raise ValueError("need v_min <= 0 < v_max")
        for name in ("radius", "w_max", "acc_lin", "acc_ang", "mass", "drive_accel"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")
        if self.vy_max < 0 or self.bumper < 0:
            raise ValueError("vy_max and bumper must be >= 0")

    @property
    def action_dims(self) -> int:
        """2 (vx, omega) for a differential drive, 3 (vx, vy, omega) for a holonomic base."""
        return self.DIMS[self.kinematics]

    @property
    def max_speed(self) -> float:
        """The largest linear speed the base can reach [m/s] (forward or backward; with the
        lateral bound for a holonomic base)."""
        speed = max(self.v_max, -self.v_min)
        return math.hypot(speed, self.vy_max) if self.kinematics == "holonomic" else speed

    @property
    def velocity_bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper bounds of (vx, vy, omega)."""
        vy = self.vy_max if self.kinematics == "holonomic" else 0.0
        low = np.array([self.v_min, -vy, -self.w_max])
        high = np.array([self.v_max, vy, self.w_max])
        return low, high

    @classmethod
    def from_spec(cls, spec: Any, path: str = "robot", file: str | None = None) -> RobotConfig:
        return from_spec(cls, spec, PRESETS, path, file)


PRESETS: dict[str, RobotConfig] = {
    "default": RobotConfig(),
    "paper": RobotConfig(),
    "holonomic": RobotConfig(kinematics="holonomic"),
}


@njit(cache=True, error_model="numpy")
def limit_commands(target, previous, low, high, acc, dt, lateral, out):
    """Clip body-frame commands (R, 3) to [low, high], then to within acc * dt of the
    previous command; ``acc`` = (acc_lin, acc_lin, acc_ang). Without ``lateral`` (a
    differential drive) the vy command is taken as 0 whatever ``target`` says."""
    for r in range(target.shape[0]):
        for k in range(3):
            v = target[r, k] if lateral or k != 1 else 0.0
            v = min(max(v, low[k]), high[k])
            step = acc[k] * dt
            out[r, k] = min(max(v, previous[r, k] - step), previous[r, k] + step)


@njit(cache=True, error_model="numpy")
def measure_velocity(before, after, dt, out):
    """Body-frame (vx, vy, omega) of each robot's motion from pose ``before[r]`` to pose
    ``after[r]`` (x, y, yaw) over ``dt``.

    The displacement is expressed in the frame of the mid-step heading, so a base that
    drives an arc of constant curvature measures vy = 0.
    """
    for r in range(before.shape[0]):
        dyaw = wrap_angle(after[r, 2] - before[r, 2])
        mid = before[r, 2] + 0.5 * dyaw
        c, s = math.cos(mid), math.sin(mid)
        dx, dy = after[r, 0] - before[r, 0], after[r, 1] - before[r, 1]
        out[r, 0] = (c * dx + s * dy) / dt
        out[r, 1] = (-s * dx + c * dy) / dt
        out[r, 2] = dyaw / dt


@njit(cache=True, error_model="numpy")
def body_to_world(cmd, pose, dt, out):
    """World-frame (vx, vy, omega) of body-frame commands of robots at ``pose`` (R rows x,
    y, yaw), along the chord of the arc the base drives in ``dt`` (heading yaw + omega
    dt / 2)."""
    for r in range(cmd.shape[0]):
        mid = pose[r, 2] + 0.5 * cmd[r, 2] * dt
        c, s = math.cos(mid), math.sin(mid)
        out[r, 0] = c * cmd[r, 0] - s * cmd[r, 1]
        out[r, 1] = s * cmd[r, 0] + c * cmd[r, 1]
        out[r, 2] = cmd[r, 2]
