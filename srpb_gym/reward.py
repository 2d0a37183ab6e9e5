"""Reward: a weighted sum of named terms, with SRPB per-step terms.

Term values of step k (from sample k to sample k+1, dt = t_{k+1} - t_k), before weights:

| term | value | unit |
| --- | --- | --- |
| ``progress`` | goal distance at k minus goal distance at k+1 | m |
| ``success`` | 1 on reaching the goal | - |
| ``collision`` | 1 if the robot touched a wall, a person or a robot | - |
| ``time`` | dt | s |
| ``obs`` | dt if the obstacle distance at k < ``safety_distance`` | s |
| ``vsm`` | hypot(dvx, dvy) / dt | m/s^2 |
| ``hsm`` | abs(d omega) / dt | rad/s^2 |
| ``osc``, ``bwd``, ``iprot`` | dt if oscillating / moving backward / rotating in place at k | s |
| ``chc`` | abs(wrap(yaw_{k+1} - yaw_k)) | rad |
| ``psi``, ``fsi``, ``dir`` | dt x the largest per-person (per-group) value at k | s |

Each SRPB term is the step's contribution to its metric in the metric's own formula and
parameters, computed by the metric code (:func:`srpb_gym.metrics.episode.entity_values`
and :mod:`srpb_gym.metrics.kernels`): summed over an episode, ``obs`` gives
``m_obs * T / 100``, ``psi`` gives ``m_psi`` times the time with people around over 100,
``chc`` gives ``m_chc``, and so on. Weights come from a preset (``configs/reward/*.yaml``,
packaged as ``srpb_gym.reward_presets``) overridden by name.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from importlib.resources import files
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.errors import InputError
from srpb_gym.metrics import kernels
from srpb_gym.metrics.episode import entity_values
from srpb_gym.metrics.params import MetricParams
from srpb_gym.metrics.record import EpisodeRecord, R

TASK_TERMS: tuple[str, ...] = ("progress", "success", "collision", "time")
SRPB_TERMS: tuple[str, ...] = (
    "obs", "vsm", "hsm", "osc", "bwd", "iprot", "chc", "psi", "fsi", "dir",
)  # fmt: skip
TERMS: tuple[str, ...] = TASK_TERMS + SRPB_TERMS
_T = {name: i for i, name in enumerate(TERMS)}


def preset_names() -> list[str]:
    """Names of the packaged reward presets."""
    return sorted(p.name[:-5] for p in files("srpb_gym.reward_presets").iterdir()
                  if p.name.endswith(".yaml"))  # fmt: skip


def load_preset(name: str) -> dict[str, float]:
    """The weights of a packaged preset (``task`` or ``srpb``)."""
    if name not in preset_names():
        raise InputError(f"unknown reward preset {name!r}; choose one of {preset_names()}",
                         key="reward")  # fmt: skip
    path = files("srpb_gym.reward_presets") / f"{name}.yaml"
    return check_weights(yaml.safe_load(path.read_text()) or {}, str(path))


def check_weights(weights: Mapping[str, Any], where: str = "reward_weights") -> dict[str, float]:
    """Weights by term name, each a finite number; unknown names are errors."""
    out = {}
    for name, value in weights.items():
        if name not in _T:
            raise InputError(f"unknown reward term; valid terms: {', '.join(TERMS)}",
                             key=f"{where}.{name}")  # fmt: skip
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise InputError(f"expected a finite number, got {value!r}", key=f"{where}.{name}")
        out[name] = float(value)
    return out


def resolve_weights(
    preset: str = "srpb", overrides: Mapping[str, Any] | None = None
) -> NDArray[np.float64]:
    """Weight vector over :data:`TERMS` (0 for terms the preset does not name)."""
    weights = load_preset(preset) | check_weights(overrides or {})
    return np.array([weights.get(name, 0.0) for name in TERMS])


class RewardFunction:
    """Computes the term values of each step from the robot's SRPB record.

    ``weights``: (len(TERMS),) as from :func:`resolve_weights`; ``params`` and ``semantics``
    are those of the episode metrics, so terms and metrics agree.
    """

    def __init__(self, weights: NDArray[np.float64], params: MetricParams, semantics: str) -> None:
        self.weights = np.asarray(weights, dtype=np.float64)
        self.params, self.reference = params, semantics == "reference"
        p = params
        self._flag_args = (
            p.osc_vel_lin_x_threshold, p.osc_vel_x_threshold, p.osc_vel_y_threshold,
            p.osc_vel_ang_z_threshold, p.stop_speed_tolerance, self.reference,
        )  # fmt: skip
        self._flags = [np.zeros(1, dtype=np.bool_) for _ in range(3)]
        self.values = np.zeros(len(TERMS))  # unweighted term values of the last step
        self.weighted = np.zeros(len(TERMS))

    def reset(self, record: EpisodeRecord, goal_distance: float) -> None:
        """Start an episode at the record's first sample."""
        self._sample = self._sample_values(record)
        self._goal_distance = goal_distance
        self.values[:] = 0.0
        self.weighted[:] = 0.0

    def step(
        self, record: EpisodeRecord, goal_distance: float, success: bool, collision: bool
    ) -> float:
        """Term values of the step that appended the record's last sample; the reward."""
        v, prev, new = self.values, self._sample, self._sample_values(record)
        dt = new[0] - prev[0]
        v[_T["progress"]] = self._goal_distance - goal_distance
        v[_T["success"]], v[_T["collision"]] = float(success), float(collision)
        v[_T["time"]] = dt
        v[_T["obs"]] = dt * (prev[1] < self.params.safety_distance)
        v[_T["osc"]], v[_T["bwd"]], v[_T["iprot"]] = dt * prev[2], dt * prev[3], dt * prev[4]
        dvx, dvy, dw = new[5] - prev[5], new[6] - prev[6], new[7] - prev[7]
        moving = dt > 0  # a zero-length step adds nothing (paper semantics)
        v[_T["vsm"]] = math.hypot(abs(dvx) / dt, abs(dvy) / dt) if moving else 0.0
        v[_T["hsm"]] = abs(dw) / dt if moving else 0.0
        v[_T["chc"]] = abs(wrap_angle(new[8] - prev[8]))
        v[_T["psi"]], v[_T["fsi"]], v[_T["dir"]] = dt * prev[9], dt * prev[10], dt * prev[11]
        self._sample, self._goal_distance = new, goal_distance
        np.multiply(v, self.weights, out=self.weighted)
        return float(self.weighted.sum())

    def _sample_values(self, record: EpisodeRecord) -> tuple[float, ...]:
        """(t, obstacle distance, osc, bwd, iprot, vx, vy, omega, yaw, max psi, max fsi,
        max dir) of the record's last sample; maxima are 0 when nobody is there."""
        robot, people, _, sizes, members = record.latest()
        row = robot[0]
        vx, vy, w = robot[:, R["vx"]], robot[:, R["vy"]], robot[:, R["omega"]]
        kernels.motion_flags(vx, vy, w, *self._flag_args, *self._flags)
        zeros = np.zeros(people.shape[0], dtype=np.int64)
        g = sizes.shape[0]
        psi, dirv, fsi, _, _ = entity_values(
            robot, people, zeros, np.zeros(g, dtype=np.int64), members,
            np.cumsum(sizes) - sizes, sizes, self.params, self.reference,
        )  # fmt: skip
        return (
            row[R["t"]], row[R["obstacle_dist"]], float(self._flags[0][0]),
            float(self._flags[1][0]), float(self._flags[2][0]), row[R["vx"]], row[R["vy"]],
            row[R["omega"]], row[R["yaw"]], _max(psi), _max(fsi), _max(dirv),
        )  # fmt: skip


def _max(values: NDArray[np.float64]) -> float:
    return float(values.max()) if values.size else 0.0
