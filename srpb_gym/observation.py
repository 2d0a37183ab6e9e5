"""Observation types: a flat normalised vector, or a ``Dict`` of its parts.

Layout of the flat vector (float32, every element in [-1, 1]; robot frame: x ahead, y left):

| slice | element | normalisation |
| --- | --- | --- |
| 0 | distance to the goal | / ``goal_scale``, clipped to 1 |
| 1, 2 | cos, sin of the goal's bearing | - |
| 3, 4 | cos, sin of (goal yaw - robot yaw) | - |
| 5, 6, 7 | measured vx, vy, omega | / the robot's largest speed, / ``w_max`` |
| 8 .. 8+L | lidar: shortest range r in each of ``lidar_bins`` equal sectors | see below |
| then K x 7 | per tracked person, nearest first (see below) | |

Each person slot: x, y (relative position, robot frame) / ``people_range``; vx, vy
(relative velocity, robot frame) / ``speed_scale``; the position standard deviation along
the robot's x and y axes / ``uncertainty_scale``; presence (1, or 0 for an empty slot,
whose other elements are 0). Values are clipped to [-1, 1].

``lidar_encoding``: ``"linear"`` (default) r / range_max, or ``"log"``
log(r / range_min) / log(range_max / range_min), both in [0, 1] (readings below range_min
read 0; a range_min below range_max / 1000, a lidar reading from 0 m, is taken as
range_max / 1000). The linear encoding of a 25 m lidar moves by 0.001 per 2.5 cm: the clearance of a
0.95 m door is below what a policy resolves. The log encoding moves by the same amount for
the same relative change at every range (0.013 per 2.5 cm at 0.3 m, 0.0016 per 1 %) and
keeps the far readings.

The ``dict`` type has the keys ``goal`` (5,), ``velocity`` (3,), ``lidar`` (L,),
``people`` (K, 6) and ``people_mask`` (K,), with the same values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numba import njit
from numpy.typing import NDArray

from srpb_gym.config import from_spec
from srpb_gym.errors import InputError
from srpb_gym.sim.robot import RobotConfig

OBSERVATION_TYPES = ("flat", "dict")
LIDAR_ENCODINGS = ("linear", "log")
GOAL, VELOCITY, PERSON = 5, 3, 7


@dataclass(frozen=True)
class ObservationConfig:
    """What the agent observes (see the module docstring for the layout)."""

    type: str = "flat"  # "flat" (Box) or "dict" (Dict of Boxes)
    lidar_bins: int = 30  # sectors of the lidar scan (shortest range of each)
    people: int = 6  # K, the nearest tracked people observed
    goal_scale: float = 20.0  # m
    people_range: float = 8.0  # m
    speed_scale: float = 2.0  # m/s, people's relative velocities
    uncertainty_scale: float = 1.0  # m, position standard deviations
    lidar_encoding: str = "linear"  # "linear" (r / range_max) or "log" (see the module doc)

    def __post_init__(self) -> None:
        if self.type not in OBSERVATION_TYPES:
            raise ValueError(
                f"observation type must be one of {OBSERVATION_TYPES}, got {self.type!r}"
            )
        if self.lidar_encoding not in LIDAR_ENCODINGS:
            raise ValueError(
                f"lidar_encoding must be one of {LIDAR_ENCODINGS}, got {self.lidar_encoding!r}"
            )
        if self.lidar_bins < 1 or self.people < 0:
            raise ValueError("lidar_bins must be >= 1 and people >= 0")
        for name in ("goal_scale", "people_range", "speed_scale", "uncertainty_scale"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")

    @classmethod
    def from_spec(cls, spec: Any, path: str = "observation") -> ObservationConfig:
        presets = {"default": cls(), "flat": cls(), "dict": cls(type="dict")}
        return from_spec(cls, spec, presets, path)


@njit(cache=True, error_model="numpy")
def fill_observation(pose, goal, velocity, vel_scale, scan, edges, range_min, range_max, log,
                     xy, vel, cov, scales, order, out):  # fmt: skip
    """Write the flat observation into ``out`` (float32); ``order`` is scratch (K_tracks,);
    ``log``: the log lidar encoding (else r / range_max)."""
    x, y, yaw = pose[0], pose[1], pose[2]
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = goal[0] - x, goal[1] - y
    bearing = math.atan2(dy, dx) - yaw
    out[0] = min(math.hypot(dx, dy) / scales[0], 1.0)
    out[1], out[2] = math.cos(bearing), math.sin(bearing)
    out[3], out[4] = math.cos(goal[2] - yaw), math.sin(goal[2] - yaw)
    for k in range(3):
        out[5 + k] = min(max(velocity[k] / vel_scale[k], -1.0), 1.0)
    bins = edges.shape[0] - 1
    for b in range(bins):
        low = range_max
        for j in range(edges[b], edges[b + 1]):
            low = min(low, scan[j])
        if log:
            low = max(low, range_min)
            out[8 + b] = math.log(low / range_min) / math.log(range_max / range_min)
        else:
            out[8 + b] = low / range_max
    base = 8 + bins
    k_slots = (out.shape[0] - base) // 7
    n = xy.shape[0]
    dist = np.empty(n)
    for i in range(n):
        dist[i] = math.hypot(xy[i, 0] - x, xy[i, 1] - y)
    order[:n] = np.argsort(dist)
    for slot in range(k_slots):
        o = base + 7 * slot
        if slot >= n:
            for j in range(7):
                out[o + j] = 0.0
            continue
        i = order[slot]
        rx, ry = xy[i, 0] - x, xy[i, 1] - y
        rvx, rvy = (
            vel[i, 0] - velocity[0] * c + velocity[1] * s,
            vel[i, 1] - velocity[0] * s - velocity[1] * c,
        )
        sxx = c * c * cov[i, 0, 0] + 2 * c * s * cov[i, 0, 1] + s * s * cov[i, 1, 1]
        syy = s * s * cov[i, 0, 0] - 2 * c * s * cov[i, 0, 1] + c * c * cov[i, 1, 1]
        vals = (c * rx + s * ry, -s * rx + c * ry, c * rvx + s * rvy, -s * rvx + c * rvy)
        for j in range(4):
            scale = scales[1] if j < 2 else scales[2]
            out[o + j] = min(max(vals[j] / scale, -1.0), 1.0)
        out[o + 4] = min(math.sqrt(max(sxx, 0.0)) / scales[3], 1.0)
        out[o + 5] = min(math.sqrt(max(syy, 0.0)) / scales[3], 1.0)
        out[o + 6] = 1.0


def observation_space(config: ObservationConfig) -> gym.Space:
    """The Gymnasium space of the observations that ``config`` describes."""
    box = lambda *shape: gym.spaces.Box(-1.0, 1.0, shape, np.float32)  # noqa: E731
    bins, k = config.lidar_bins, config.people
    if config.type == "flat":
        return box(GOAL + VELOCITY + bins + PERSON * k)
    return gym.spaces.Dict({
        "goal": box(GOAL), "velocity": box(VELOCITY), "lidar": box(bins),
        "people": box(k, PERSON - 1),
        "people_mask": gym.spaces.Box(0.0, 1.0, (k,), np.float32),
    })  # fmt: skip


class ObservationBuilder:
    """Builds observations of one robot; ``space`` is the matching Gymnasium space."""

    def __init__(self, config: ObservationConfig, n_beams: int, range_max: float,
                 v_scale: float, vy_scale: float, w_max: float,
                 range_min: float = 0.05) -> None:  # fmt: skip
        self.config = config
        if config.lidar_bins > n_beams:
            raise InputError(f"{config.lidar_bins} lidar sectors need at least as many beams; "
                             f"the lidar has {n_beams}", key="observation.lidar_bins")  # fmt: skip
        bins = config.lidar_bins
        self.edges = np.linspace(0, n_beams, bins + 1).round().astype(np.int64)
        self.range_max = float(range_max)
        # the log encoding needs a positive lower end (a lidar may read from 0 m)
        self.range_min = max(float(range_min), 1e-3 * self.range_max)
        self._log = config.lidar_encoding == "log"
        self.vel_scale = np.array([v_scale, vy_scale if vy_scale > 0 else v_scale, w_max])
        self.scales = np.array([config.goal_scale, config.people_range, config.speed_scale,
                                config.uncertainty_scale])  # fmt: skip
        self.size = GOAL + VELOCITY + bins + PERSON * config.people
        self.bins = bins
        self._order = np.zeros(64, dtype=np.int64)
        self.space = observation_space(config)

    @classmethod
    def for_robot(cls, config: ObservationConfig, robot: RobotConfig, n_beams: int,
                  range_min: float, range_max: float) -> ObservationBuilder:  # fmt: skip
        """The builder of ``config`` for a robot with these limits and lidar: the speed
        scales are the largest linear speed either way, the lateral and the angular one."""
        return cls(config, n_beams, range_max, max(robot.v_max, -robot.v_min), robot.vy_max,
                   robot.w_max, range_min)  # fmt: skip

    def build(self, pose, goal, velocity, scan, tracks) -> NDArray[np.float32] | dict:
        """A fresh observation from the robot's pose, goal, measured velocity, lidar scan
        and its tracker's tracks."""
        out = np.empty(self.size, dtype=np.float32)
        if tracks.xy.shape[0] > self._order.shape[0]:
            self._order = np.zeros(2 * tracks.xy.shape[0], dtype=np.int64)
        fill_observation(pose, goal, velocity, self.vel_scale, scan, self.edges,
                         self.range_min, self.range_max, self._log, tracks.xy,
                         tracks.velocity, tracks.covariance, self.scales, self._order,
                         out)  # fmt: skip
        if self.config.type == "flat":
            return out
        base = GOAL + VELOCITY + self.bins
        people = out[base:].reshape(self.config.people, PERSON)
        return {
            "goal": out[:GOAL].copy(), "velocity": out[GOAL:base - self.bins].copy(),
            "lidar": out[GOAL + VELOCITY:base].copy(), "people": people[:, :6].copy(),
            "people_mask": people[:, 6].copy(),
        }  # fmt: skip
