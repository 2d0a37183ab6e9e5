"""Reward: a weighted sum of named terms, with SRPB per-step terms.

Term values of step k (from sample k to sample k+1, dt = t_{k+1} - t_k), before weights:

| term | value | unit |
| --- | --- | --- |
| ``progress`` | goal distance at k minus goal distance at k+1 | m |
| ``success`` | 1 on reaching the goal with no collision in the episode | - |
| ``collision`` | 1 if the robot touched a wall, a person or a robot | - |
| ``time`` | dt | s |
| ``approach`` | approach error at k minus approach error at k+1 (below) | m |
| ``obs`` | dt if the obstacle distance at k < ``safety_distance`` | s |
| ``vsm`` | hypot(dvx, dvy) / dt | m/s^2 |
| ``hsm`` | abs(d omega) / dt | rad/s^2 |
| ``osc``, ``bwd``, ``iprot`` | dt if oscillating / moving backward / rotating in place at k | s |
| ``chc`` | abs(wrap(yaw_{k+1} - yaw_k)) | rad |
| ``psi``, ``fsi``, ``dir`` | dt x the largest per-person (per-group) value at k | s |

``approach`` is potential-based shaping of the last metres (in the sense of Ng et al.
1999, undiscounted, as ``progress``), in no preset: a learner that must reach the goal's
position and heading within their tolerances (0.2 m, 0.2 rad) with a differential drive,
and stops beside the goal facing its heading, gains nothing from ``progress`` by turning
towards the goal's heading line, driving onto it and turning back. The approach error of
a sample is (e + :data:`APPROACH_YAW` x abs(wrap(goal yaw - yaw))) x max(0, 1 - d /
:data:`APPROACH_RADIUS`): e the robot's distance from the line through the goal along its
heading, d its distance to the goal. It is 0 farther than :data:`APPROACH_RADIUS` from
the goal and on the goal's heading line facing the goal's heading (before or past the
goal: ``progress`` tells them apart), and at most pi x :data:`APPROACH_YAW` (about
1.57 m). Summed over an episode the term telescopes to the first sample's error minus the
last's, so it is bounded by the geometry (:data:`EVENT_TERMS`), within +-1.57 whatever
the episode's length; in an episode that starts farther than :data:`APPROACH_RADIUS`
from its goal it is minus the last sample's error (a manoeuvre's first turn costs, and
the drive onto the line pays it back, net).

Each SRPB term is the step's contribution to its metric in the metric's own formula and
parameters, computed by the metric code (:func:`srpb_gym.metrics.episode.entity_values`
and :mod:`srpb_gym.metrics.kernels`): summed over an episode, ``obs`` gives
``m_obs * T / 100``, ``psi`` gives ``m_psi`` times the time with people around over 100,
``chc`` gives ``m_chc``, and so on: exactly so in the ``paper`` semantics. With
``reference`` semantics the per-person and per-group values (psi, fsi, dir) and the motion
predicates use the reference formulas, while ``obs``, ``chc``, ``vsm`` and ``hsm`` keep
the paper's per-step form (the reference tool's run-based ``m_obs``, unwrapped heading
change and extra final aggregation entry have none). Weights come from a preset
(``configs/reward/*.yaml``, packaged as ``srpb_gym.reward_presets``), replaced by the
scenario's weights for that preset (its ``reward`` section), then overridden by name.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.metrics import kernels
from srpb_gym.metrics.episode import TAUBIN_MIN_MEMBERS, group_values
from srpb_gym.metrics.params import MetricParams
from srpb_gym.metrics.record import EpisodeRecord
from srpb_gym.reward_terms import (
    SRPB_TERMS,
    TASK_TERMS,
    TERM_INDEX,
    TERMS,
    check_weights,
    load_preset,
    preset_names,
)

# the term names and presets are part of this module's interface (their home is the
# ground-floor module srpb_gym.reward_terms, which scenario files are checked against)
__all__ = [
    "APPROACH_RADIUS", "APPROACH_YAW", "EVENT_TERMS", "MEASURED_MARGIN", "PRESET_GAMMA",
    "SHAPING_TERMS", "SRPB_TERMS", "TASK_TERMS", "TERMS", "RewardFunction",
    "RewardGameableWarning", "approach_error", "check_weights", "load_preset",
    "preset_names", "resolve_weights", "shaping_bound", "step_bounds",
]  # fmt: skip


def resolve_weights(
    preset: str = "srpb", overrides: Mapping[str, Any] | None = None,
    scenario: Mapping[str, Mapping[str, float]] | None = None,
) -> NDArray[np.float64]:  # fmt: skip
    """Weight vector over :data:`TERMS` (0 for terms named nowhere): the preset's weights,
    replaced by a scenario's weights for that preset (``scenario``: a
    :attr:`~srpb_gym.scenarios.Scenario.reward` mapping), replaced by ``overrides``."""
    weights = load_preset(preset)
    weights |= check_weights((scenario or {}).get(preset) or {}, f"reward.{preset}")
    weights |= check_weights(overrides or {})
    return np.array([weights.get(name, 0.0) for name in TERMS])


#: terms whose sum over an episode is bounded by the geometry, not by its length:
#: ``progress`` telescopes to the start distance minus the end distance, ``approach`` to
#: the start's approach error minus the end's, ``success`` and ``collision`` happen once
EVENT_TERMS: tuple[str, ...] = ("progress", "success", "collision", "approach")
#: every other term: paid per step for as long as the episode runs
SHAPING_TERMS: tuple[str, ...] = tuple(t for t in TERMS if t not in EVENT_TERMS)


#: headroom of the bounds of terms computed from measured (not commanded) velocities
MEASURED_MARGIN = 1.01


def step_bounds(control_dt: float, robot: Any) -> dict[str, float]:
    """The largest value each shaping term can take in one control step of ``control_dt``
    seconds for a robot within its velocity and acceleration limits (``robot``: a
    :class:`~srpb_gym.sim.robot.RobotConfig`). Per-second terms are at most ``dt`` (the
    psi, fsi and dir values are at most 1); ``chc`` at most the yaw change at ``w_max``;
    ``vsm`` and ``hsm`` at most the acceleration limits. These three are measured
    velocities, which the physics tracks to within 0.03 % of the commanded ones on steps
    without a contact: their bounds carry a 1 % margin (:data:`MEASURED_MARGIN`)."""
    lateral = robot.acc_lin if robot.kinematics == "holonomic" else 0.0
    dt, m = float(control_dt), MEASURED_MARGIN
    bounds = dict.fromkeys(("time", "obs", "osc", "bwd", "iprot", "psi", "fsi", "dir"), dt)
    bounds.update(vsm=m * math.hypot(robot.acc_lin, lateral), hsm=m * robot.acc_ang,
                  chc=m * robot.w_max * dt)  # fmt: skip
    return {t: bounds[t] for t in SHAPING_TERMS}


#: the discount factor the reward presets are sized for: that of every configuration in
#: ``configs/train/ppo.yaml`` (``srpb-gym train`` checks the one it trains with)
PRESET_GAMMA = 0.99


def shaping_bound(
    weights: Mapping[str, float] | NDArray[np.float64], time_limit: float, control_dt: float,
    robot: Any, gamma: float = 1.0,
) -> float:  # fmt: skip
    """The most the shaping terms (:data:`SHAPING_TERMS`) can cost from any state: every
    penalised term at its per-step bound (:func:`step_bounds`) on every step, summed with
    weights ``gamma**k`` over all steps to come (a learner bootstraps its value past a
    truncation, so its horizon does not end at the time limit); ``gamma`` = 1: the plain
    sum over the ``time_limit``. A positive weight (a bonus) never adds to the cost. A
    learner that discounts with ``gamma`` never prefers a collision to going on while this
    stays below the collision penalty."""
    if not isinstance(weights, Mapping):
        weights = dict(zip(TERMS, np.asarray(weights, dtype=np.float64).tolist()))
    if not 0.0 < gamma <= 1.0:
        raise ValueError(f"gamma must be in (0, 1], got {gamma!r}")
    horizon = math.ceil(time_limit / control_dt - 1e-9) if gamma == 1.0 else 1.0 / (1.0 - gamma)
    bounds = step_bounds(control_dt, robot)
    return horizon * sum(-min(weights.get(t, 0.0), 0.0) * bounds[t] for t in SHAPING_TERMS)


class RewardGameableWarning(UserWarning):
    """The reward weights let a collision pay: the (discounted) shaping of the rest of an
    episode can cost more than the collision penalty, so a policy may learn to crash."""


class RewardFunction:
    """Computes the term values of each step from the robot's SRPB record.

    ``weights``: (len(TERMS),) as from :func:`resolve_weights`; ``params`` and ``semantics``
    are those of the episode metrics, so terms and metrics agree.
    """

    def __init__(self, weights: NDArray[np.float64], params: MetricParams, semantics: str) -> None:
        self.weights = np.asarray(weights, dtype=np.float64)
        self.params, self.reference = params, semantics == "reference"
        p = params
        self._params = np.array([
            p.osc_vel_lin_x_threshold, p.osc_vel_x_threshold, p.osc_vel_y_threshold,
            p.osc_vel_ang_z_threshold, p.stop_speed_tolerance, p.person_fov,
            p.robot_max_speed, p.robot_circumradius, p.person_occupancy_radius,
            p.safety_distance,
        ])  # fmt: skip
        self.values = np.zeros(len(TERMS))  # unweighted term values of the last step
        self.weighted = np.zeros(len(TERMS))
        self._prev, self._new = np.zeros(SAMPLE), np.zeros(SAMPLE)
        self._taubin_size = TAUBIN_MIN_MEMBERS[semantics == "reference"]
        self._checked: set[tuple[float, float]] = set()

    def check_bound(
        self, time_limit: float, control_dt: float, robot: Any, gamma: float = PRESET_GAMMA
    ) -> None:
        """Warn (:class:`RewardGameableWarning`, once per time limit and step) when the
        shaping from any state, discounted by ``gamma`` (see :func:`shaping_bound`;
        ``time_limit`` matters for ``gamma`` = 1 only), can cost as much as a collision."""
        key = (float(time_limit), float(control_dt))
        if key in self._checked:
            return
        self._checked.add(key)
        penalty = -float(self.weights[TERM_INDEX["collision"]])
        bound = shaping_bound(self.weights, time_limit, control_dt, robot, gamma)
        if bound > 0.0 and bound >= penalty:
            what = (f"the collision penalty {penalty:.3g}" if penalty > 0.0 else
                    f"a collision, which is not penalised (weight {-penalty:g})")  # fmt: skip
            warnings.warn(
                f"reward: the shaping terms can cost up to {bound:.3g} from any state "
                f"(discounted by {gamma:g} per {control_dt:g} s step), more than {what}: a "
                "policy may learn to end episodes by crashing. Raise 'collision' or lower "
                "the shaping weights (see srpb_gym.reward.shaping_bound)",
                RewardGameableWarning, stacklevel=3,
            )  # fmt: skip

    def reset(self, record: EpisodeRecord, goal_distance: float) -> None:
        """Start an episode at the record's first sample."""
        self._sample_values(record, self._prev)
        self._goal_distance = goal_distance
        self.values[:] = 0.0
        self.weighted[:] = 0.0

    def step(
        self, record: EpisodeRecord, goal_distance: float, success: bool, collision: bool
    ) -> float:
        """Term values of the step that appended the record's last sample; the reward."""
        prev, new = self._prev, self._new
        self._sample_values(record, new)
        reward = _step_terms(prev, new, self._goal_distance - goal_distance, float(success),
                             float(collision), self._params[9], self.weights, self.values,
                             self.weighted)  # fmt: skip
        self._prev, self._new = new, prev
        self._goal_distance = goal_distance
        return reward

    def _sample_values(self, record: EpisodeRecord, out: NDArray[np.float64]) -> None:
        """Write the per-sample values (:data:`SAMPLE`) of the record's last sample."""
        robot, people, _, sizes, members = record.latest()
        _sample_terms(robot[0], people, self._params, self.reference, out)
        if sizes.shape[0] == 0:
            return
        if sizes.max() < self._taubin_size:  # every O-space is the fallback ellipse
            out[_S_FSI] = _fallback_fsi(robot[0], people, members, sizes,
                                        self.params.person_occupancy_radius,
                                        self.reference)  # fmt: skip
            return
        g = sizes.shape[0]  # Taubin's fit: the metric code's own group path
        fsi = group_values(robot, people, np.zeros(g, dtype=np.int64), members,
                           np.cumsum(sizes) - sizes, sizes, self.params,
                           self.reference)  # fmt: skip
        out[_S_FSI] = fsi.max()


#: per-sample values: t, obstacle distance, osc, bwd, iprot, vx, vy, omega, yaw, the
#: largest psi, fsi and dir over the people (groups) of the sample (0 when nobody is there)
#: and the approach error
SAMPLE = 13
_S_FSI = 10


#: m, the approach error is 0 this far from the goal and beyond (``approach``)
APPROACH_RADIUS = 1.5
#: m/rad, the weight of the heading error against the distance from the goal's heading line
APPROACH_YAW = 0.5


@njit(cache=True, error_model="numpy")
def approach_error(x: float, y: float, yaw: float, gx: float, gy: float,
                   gyaw: float) -> float:  # fmt: skip
    """The approach error [m] of a robot pose (x, y, yaw) for the goal (gx, gy, gyaw):
    (distance from the goal's heading line + :data:`APPROACH_YAW` x heading error) x
    max(0, 1 - goal distance / :data:`APPROACH_RADIUS`)."""
    dx, dy = x - gx, y - gy
    near = 1.0 - math.hypot(dx, dy) / APPROACH_RADIUS
    if near <= 0.0:
        return 0.0
    off_line = abs(-dx * math.sin(gyaw) + dy * math.cos(gyaw))
    return (off_line + APPROACH_YAW * abs(wrap_angle(gyaw - yaw))) * near


@njit(cache=True, error_model="numpy")
def _sample_terms(row, people, prm, reference, out):  # pragma: no cover - compiled
    """Fill ``out`` (:data:`SAMPLE`) from one robot row and its people rows (fsi left 0)."""
    t, x, y, yaw, vx, vy, w = row[0], row[1], row[2], row[3], row[4], row[5], row[6]
    osc, bwd, iprot = kernels.motion_predicates(vx, vy, w, prm[0], prm[1], prm[2], prm[3],
                                                prm[4], reference)  # fmt: skip
    psi_max, dir_max = -math.inf, -math.inf  # as the metric's aggregation: max() skips NaN
    speed = math.hypot(vx, vy)
    for i in range(people.shape[0]):
        p = people[i]
        psi, dirv = kernels.person_pair(x, y, yaw, speed, p[0], p[1], p[2], p[7], p[8], p[3],
                                        p[4], p[5], p[6], prm[5], prm[6], prm[7], prm[8],
                                        reference)  # fmt: skip
        psi_max, dir_max = max(psi_max, psi), max(dir_max, dirv)
    out[0], out[1] = t, row[10]
    out[2], out[3], out[4] = 1.0 if osc else 0.0, 1.0 if bwd else 0.0, 1.0 if iprot else 0.0
    out[5], out[6], out[7], out[8] = vx, vy, w, yaw
    out[9] = psi_max if psi_max > -math.inf else 0.0  # nobody (with a value) around: 0
    out[10] = 0.0
    out[11] = dir_max if dir_max > -math.inf else 0.0
    out[12] = approach_error(x, y, yaw, row[7], row[8], row[9])


@njit(cache=True, error_model="numpy")
def _fallback_fsi(row, people, members, size, occupancy, reference):  # pragma: no cover
    """The largest fsi of one sample's groups when every O-space is the fallback ellipse
    (the kernels of :func:`srpb_gym.metrics.episode.entity_values`)."""
    g = size.shape[0]
    start = np.empty(g, dtype=np.int64)
    acc = 0
    for k in range(g):
        start[k] = acc
        acc += size[k]
    px, py = people[:, 0].copy(), people[:, 1].copy()
    cxx, cxy, cyx, cyy = (people[:, 3].copy(), people[:, 4].copy(), people[:, 5].copy(),
                          people[:, 6].copy())  # fmt: skip
    taubin = np.zeros(g, dtype=np.bool_)
    cx, cy, a, b, theta = np.empty(g), np.empty(g), np.empty(g), np.empty(g), np.empty(g)
    kernels.fallback_ellipses(px, py, members, start, size, occupancy, reference, taubin, cx, cy,
                              a, b, theta)  # fmt: skip
    sxx, sxy, syy, fsi = np.empty(g), np.empty(g), np.empty(g), np.empty(g)
    kernels.group_covariances(cxx, cxy, cyx, cyy, members, start, size, reference, sxx, sxy,
                              syy)  # fmt: skip
    rx, ry = np.full(1, row[1]), np.full(1, row[2])
    kernels.group_terms(rx, ry, np.zeros(g, dtype=np.int64), cx, cy, a, b, theta, sxx, sxy, syy,
                        fsi)  # fmt: skip
    return fsi.max()


@njit(cache=True, error_model="numpy")
def _step_terms(prev, new, progress, success, collision, safety, weights, v, weighted):
    """Term values (:data:`TERMS` order) of the step from sample ``prev`` to ``new``;
    writes ``v`` and ``weighted``, returns the reward."""  # pragma: no cover - compiled
    dt = new[0] - prev[0]
    v[0], v[1], v[2], v[3] = progress, success, collision, dt
    v[4] = prev[12] - new[12]
    v[5] = dt if prev[1] < safety else 0.0
    moving = dt > 0  # a zero-length step adds nothing (paper semantics)
    v[6] = math.hypot(abs(new[5] - prev[5]) / dt, abs(new[6] - prev[6]) / dt) if moving else 0.0
    v[7] = abs(new[7] - prev[7]) / dt if moving else 0.0
    v[8], v[9], v[10] = dt * prev[2], dt * prev[3], dt * prev[4]
    v[11] = abs(wrap_angle(new[8] - prev[8]))
    v[12], v[13], v[14] = dt * prev[9], dt * prev[10], dt * prev[11]
    total = 0.0
    for k in range(v.shape[0]):
        weighted[k] = v[k] * weights[k]
        total += weighted[k]
    return total
