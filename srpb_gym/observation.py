"""Observation types: a flat normalised vector, or a ``Dict`` of its parts.

Layout of the flat vector (float32, every element in [-1, 1]; robot frame: x ahead, y left):

| slice | element | normalisation |
| --- | --- | --- |
| 0 | distance to the goal | / ``goal_scale``, clipped to 1 |
| 1, 2 | cos, sin of the goal's bearing | x min(1, distance / ``goal_fade``) |
| 3, 4 | cos, sin of (goal yaw - robot yaw) | - |
| 5, 6, 7 | measured vx, vy, omega | / the robot's largest speed, / ``w_max`` |
| 8 .. 8+L | lidar: shortest range r in each of ``lidar_bins`` equal sectors | see below |
| then K x 7 | per tracked person, nearest first (see below) | |

Each person slot: x, y (relative position, robot frame) / ``people_range``; vx, vy
(relative velocity, robot frame) / ``speed_scale``; the position standard deviation along
the robot's x and y axes / ``uncertainty_scale``; presence (1, or 0 for an empty slot,
whose other elements are 0). Values are clipped to [-1, 1].

``goal_fade``: a distance [m] within which the goal's bearing fades to (0, 0) at the goal
(its cos and sin scaled by distance / ``goal_fade``); 0 (default): never. The bearing of
a goal a centimetre away turns with every millimetre the robot moves: a policy that
steers by it at the goal turns to and fro there instead of turning onto the goal's
heading (elements 3, 4). Faded, it points the same way with a length that tells the
last centimetres apart.

``lidar_encoding``: ``"linear"`` (default) r / range_max, or ``"log"``
log(r / range_min) / log(range_max / range_min), both in [0, 1] (readings below range_min
read 0; a range_min below range_max / 1000, a lidar reading from 0 m, is taken as
range_max / 1000). The linear encoding of a 25 m lidar moves by 0.001 per 2.5 cm: the clearance of a
0.95 m door is below what a policy resolves. The log encoding moves by the same amount for
the same relative change at every range (0.013 per 2.5 cm at 0.3 m, 0.0016 per 1 %) and
keeps the far readings.

``lidar_groups``: a level in (0, 1) draws the O-spaces of the standing groups into the
lidar sectors as obstacles, out to where their ``fsi`` value falls to that level: a beam
reads the shorter of its range and its distance to such a contour. 0 (default) draws
none. The groups are found among the tracks, as a planner must find them
(:func:`srpb_gym.perception.groups.detect_groups`: at least two tracks standing, slower
than 0.3 m/s and tracked for 1 s or more, each within ``group_distance`` of another); the
O-space is the ``fsi`` metric's Gaussian of the metric's small-group ellipse (centre the
members' mean, semi-axes half the longest distance between two members and the members'
spread across it, or the occupancy radius d_ocp = 0.28 m for members in a line such as a
pair; standard deviations half those) plus the members' largest tracking covariance (the
metric fits an ellipse to groups of five or more instead). ``group_distance`` is 3 m,
not ``social-dwa``'s 2 m: the pairs of ``crowd`` stand 2.4-2.6 m apart. At 0.01 a
standing pair 2.5 m apart, tracked to 0.003 m^2, is drawn as an ellipse 3.8 m long and
0.9 m across: the robot sees an obstacle between and around the two. The physical lidar,
the people slots and the reward are unchanged; a contour the robot is inside is not drawn.

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
from srpb_gym.metrics.kernels import fallback_ellipses, group_covariances
from srpb_gym.metrics.params import MetricParams
from srpb_gym.perception.groups import standing_groups
from srpb_gym.sim.robot import RobotConfig

OBSERVATION_TYPES = ("flat", "dict")
LIDAR_ENCODINGS = ("linear", "log")
GOAL, VELOCITY, PERSON = 5, 3, 7
#: a track slower than this [m/s], tracked this long [s] at least, stands (``lidar_groups``)
STANDING_SPEED, MIN_TRACK_AGE = 0.3, 1.0


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
    lidar_groups: float = 0.0  # fsi level of the O-space contours drawn into the lidar (0: none)
    group_distance: float = 3.0  # m, standing tracks this close to another form a group
    goal_fade: float = 0.0  # m, the goal's bearing fades to (0, 0) within this (0: never)

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
        if not (math.isfinite(self.goal_fade) and self.goal_fade >= 0.0):
            raise ValueError(f"goal_fade must be a distance >= 0 (0: the bearing never "
                             f"fades), got {self.goal_fade!r}")  # fmt: skip
        if not 0.0 <= self.lidar_groups < 1.0:
            raise ValueError(f"lidar_groups must be in [0, 1) (0: no O-spaces in the lidar), "
                             f"got {self.lidar_groups!r}")  # fmt: skip
        for name in ("goal_scale", "people_range", "speed_scale", "uncertainty_scale",
                     "group_distance"):  # fmt: skip
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
    dist = math.hypot(dx, dy)
    out[0] = min(dist / scales[0], 1.0)
    fade = min(dist / scales[4], 1.0) if scales[4] > 0.0 else 1.0
    out[1], out[2] = fade * math.cos(bearing), fade * math.sin(bearing)
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
    near = np.empty(n)
    for i in range(n):
        near[i] = math.hypot(xy[i, 0] - x, xy[i, 1] - y)
    order[:n] = np.argsort(near)
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


@njit(cache=True, error_model="numpy")
def draw_contours(x, y, yaw, angles, scan, rows, radius2, out):
    """``out`` (n_beams,): each beam's range in ``scan``, or its distance from the robot at
    (x, y, yaw) to the nearest contour d^T S^-1 d = ``radius2`` of the O-space Gaussians
    ``rows`` (G, 8: centre x, y, semi-axes a, b, orientation, covariance sxx, sxy, syy;
    S = R diag((a/2)^2, (b/2)^2) R^T + cov, as the ``fsi`` metric) where shorter. A contour
    around the robot is not drawn."""
    out[:] = scan
    for g in range(rows.shape[0]):
        va, vb = (0.5 * rows[g, 2]) ** 2, (0.5 * rows[g, 3]) ** 2
        c, s = math.cos(rows[g, 4]), math.sin(rows[g, 4])
        sxx = c * c * va + s * s * vb + rows[g, 5]
        sxy = c * s * (va - vb) + rows[g, 6]
        syy = s * s * va + c * c * vb + rows[g, 7]
        det = sxx * syy - sxy * sxy
        if not det > 0.0:
            continue
        ixx, ixy, iyy = syy / det, -sxy / det, sxx / det
        ox, oy = x - rows[g, 0], y - rows[g, 1]
        q0 = ixx * ox * ox + 2.0 * ixy * ox * oy + iyy * oy * oy - radius2
        if q0 <= 0.0:
            continue
        for j in range(angles.shape[0]):
            ux, uy = math.cos(yaw + angles[j]), math.sin(yaw + angles[j])
            qa = ixx * ux * ux + 2.0 * ixy * ux * uy + iyy * uy * uy
            qb = 2.0 * (ixx * ox * ux + ixy * (ox * uy + oy * ux) + iyy * oy * uy)
            disc = qb * qb - 4.0 * qa * q0
            if disc < 0.0 or qb >= 0.0:  # no crossing, or the contour is behind the beam
                continue
            t = (-qb - math.sqrt(disc)) / (2.0 * qa)
            if t < out[j]:
                out[j] = t


@njit(cache=True, error_model="numpy")
def draw_groups(x, y, yaw, angles, scan, xy, velocity, age, cov, distance, occupancy_radius,
                radius2, parent, members, start, size, skip, rows, out):  # fmt: skip
    """``out``: ``scan`` with the O-space contours of the groups standing among the tracks
    (:func:`srpb_gym.perception.groups.standing_groups`; each group's fallback ellipse of
    the ``fsi`` metric and its members' largest covariance, :func:`draw_contours`) drawn
    in. ``parent``, ``members`` (K,), ``start``, ``size``, ``skip`` (K // 2,) and ``rows``
    (K // 2, 8) are scratch."""
    g, _ = standing_groups(xy, velocity, age, STANDING_SPEED, distance, MIN_TRACK_AGE,
                           parent, members, start, size)  # fmt: skip
    if g == 0:
        out[:] = scan
        return
    st, sz, r = start[:g], size[:g], rows[:g]
    skip[:g] = False
    fallback_ellipses(xy[:, 0], xy[:, 1], members, st, sz, occupancy_radius, False,
                      skip[:g], r[:, 0], r[:, 1], r[:, 2], r[:, 3], r[:, 4])  # fmt: skip
    group_covariances(cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 0], cov[:, 1, 1], members, st, sz,
                      False, r[:, 5], r[:, 6], r[:, 7])  # fmt: skip
    draw_contours(x, y, yaw, angles, scan, r, radius2, out)


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
                 range_min: float = 0.05, angles: NDArray[np.float64] | None = None,
                 ) -> None:  # fmt: skip
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
                                config.uncertainty_scale, config.goal_fade])  # fmt: skip
        self.size = GOAL + VELOCITY + bins + PERSON * config.people
        self.bins = bins
        self._order = np.zeros(64, dtype=np.int64)
        self.space = observation_space(config)
        self._groups = config.lidar_groups > 0.0
        if self._groups:
            if angles is None or np.shape(angles) != (n_beams,):
                raise ValueError("lidar_groups needs the lidar's beam angles (n_beams,)")
            self._angles = np.array(angles, dtype=np.float64)  # a writable copy: one kernel
            self._scan = np.empty(n_beams)
            self._radius2 = -2.0 * math.log(config.lidar_groups)
            self._occupancy = MetricParams().person_occupancy_radius
            self._scratch(16)

    def _scratch(self, k: int) -> None:
        """Scratch arrays of the group kernel for ``k`` tracks."""
        self._parent, self._members = np.empty(k, np.int64), np.empty(k, np.int64)
        self._start, self._size = np.empty(k // 2, np.int64), np.empty(k // 2, np.int64)
        self._skip, self._rows = np.empty(k // 2, np.bool_), np.empty((k // 2, 8))

    @classmethod
    def for_robot(cls, config: ObservationConfig, robot: RobotConfig, n_beams: int,
                  range_min: float, range_max: float,
                  angles: NDArray[np.float64] | None = None) -> ObservationBuilder:  # fmt: skip
        """The builder of ``config`` for a robot with these limits and lidar (``angles``:
        its beam angles, needed to draw O-spaces): the speed scales are the largest linear
        speed either way, the lateral and the angular one."""
        return cls(config, n_beams, range_max, max(robot.v_max, -robot.v_min), robot.vy_max,
                   robot.w_max, range_min, angles)  # fmt: skip

    def build(self, pose, goal, velocity, scan, tracks) -> NDArray[np.float32] | dict:
        """A fresh observation from the robot's pose, goal, measured velocity, lidar scan
        and its tracker's tracks."""
        out = np.empty(self.size, dtype=np.float32)
        if self._groups:
            k = tracks.xy.shape[0]
            if k > self._parent.shape[0]:
                self._scratch(2 * k)
            draw_groups(pose[0], pose[1], pose[2], self._angles, scan, tracks.xy,
                        tracks.velocity, tracks.age, tracks.covariance,
                        self.config.group_distance, self._occupancy, self._radius2,
                        self._parent, self._members, self._start, self._size, self._skip,
                        self._rows, self._scan)  # fmt: skip
            scan = self._scan
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
