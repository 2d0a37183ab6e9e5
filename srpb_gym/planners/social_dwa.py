"""A human-aware DWA: the :class:`~srpb_gym.planners.dwa.DWA` plus the SRPB social costs.

Along every sampled trajectory the robot's poses are scored with the SRPB metric kernels
themselves, against the tracked people predicted at constant velocity:

* personal space (``psi``) and heading disturbance (``dir``) of each tracked person, from
  :func:`srpb_gym.metrics.kernels.person_terms` (Kirby's asymmetric Gaussian plus the
  tracking covariance; the heading-into-person value of the robot's pose and speed);
* F-formation O-space intrusion (``fsi``) of the groups the robot detects among its tracks
  (standing people close to each other), with the O-space ellipse of
  :func:`srpb_gym.metrics.episode.group_ellipses` and
  :func:`srpb_gym.metrics.kernels.group_terms`.

Like the metrics, each cost is the time average of the largest per-person (per-group) value
at each pose. The global planner gets the same Gaussians as cost layers, so the path already
keeps out of personal spaces and O-spaces.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numba import njit
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.knowledge import Knowledge
from srpb_gym.metrics import kernels
from srpb_gym.metrics.kernels import gauss
from srpb_gym.metrics.params import MetricParams
from srpb_gym.perception.groups import detect_groups, ospace_gaussians
from srpb_gym.perception.tracker import Tracks
from srpb_gym.planners.config import SettingError
from srpb_gym.planners.dwa import DWA, DWAConfig
from srpb_gym.planners.global_planner import GlobalPlannerConfig


@njit(cache=True, error_model="numpy")
def personal_space_layer(
    cost, x0, y0, res, px, py, pyaw, speed, cxx, cxy, cyy, weight, spread, reach
):  # fmt: skip
    """Add the SRPB personal-space Gaussian of each person p (Kirby's asymmetric Gaussian
    plus the tracking covariance, the formula of
    :func:`srpb_gym.metrics.kernels.person_terms`) times ``weight[p]``, widened
    ``spread[p]`` times, to the grid ``cost`` (origin x0, y0, cell ``res`` [m]) within
    ``reach`` [m] of the person; evaluated once per block of 2 x 2 cells."""
    ny, nx = cost.shape
    for p in range(px.shape[0]):
        f = spread[p]
        var_front = max(2.0 * speed[p], 0.5)
        var_side = var_front * 2.0 / 3.0
        ch, sh = math.cos(pyaw[p]), math.sin(pyaw[p])
        i0 = max(int((px[p] - reach - x0) / res), 0)
        i1 = min(int((px[p] + reach - x0) / res) + 1, nx)
        j0 = max(int((py[p] - reach - y0) / res), 0)
        j1 = min(int((py[p] + reach - y0) / res) + 1, ny)
        for j in range(j0, j1, 2):
            dy = y0 + (j + 1.0) * res - py[p]
            for i in range(i0, i1, 2):
                dx = x0 + (i + 1.0) * res - px[p]
                front = abs(wrap_angle(math.atan2(dy, dx) - pyaw[p])) <= 0.5 * math.pi
                var_head = var_front if front else 0.5 * var_front
                off = ch * sh * (var_head - var_side) + cxy[p]
                sxx = ch * ch * var_head + sh * sh * var_side + cxx[p]
                syy = sh * sh * var_head + ch * ch * var_side + cyy[p]
                value = weight[p] * gauss(dx / f, dy / f, sxx, off, off, syy)
                for jj in range(j, min(j + 2, j1)):
                    for ii in range(i, min(i + 2, i1)):
                        cost[jj, ii] += value


@njit(cache=True, error_model="numpy")
def ospace_layer(cost, x0, y0, res, ell, cov, weight, spread, reach):
    """Add ``weight`` times the SRPB O-space Gaussian of each ellipse row (cx, cy, a, b,
    theta) with covariance row (sxx, sxy, syy), the formula of
    :func:`srpb_gym.metrics.kernels.group_terms`, widened ``spread`` times, to the grid
    ``cost`` within ``reach`` [m] of the ellipse."""
    ny, nx = cost.shape
    for g in range(ell.shape[0]):
        cx, cy, a, b, th = ell[g, 0], ell[g, 1], ell[g, 2], ell[g, 3], ell[g, 4]
        va, vb = (0.5 * a) ** 2, (0.5 * b) ** 2
        c, s = math.cos(th), math.sin(th)
        off = c * s * (va - vb) + cov[g, 1]
        sxx = c * c * va + s * s * vb + cov[g, 0]
        syy = s * s * va + c * c * vb + cov[g, 2]
        r = max(a, b) + reach
        i0 = max(int((cx - r - x0) / res), 0)
        i1 = min(int((cx + r - x0) / res) + 1, nx)
        j0 = max(int((cy - r - y0) / res), 0)
        j1 = min(int((cy + r - y0) / res) + 1, ny)
        for j in range(j0, j1):
            dy = y0 + (j + 0.5) * res - cy
            for i in range(i0, i1):
                dx = x0 + (i + 0.5) * res - cx
                cost[j, i] += weight * gauss(dx / spread, dy / spread, sxx, off, off, syy)


@dataclass(frozen=True)
class SocialDWAConfig(DWAConfig):
    """Settings of the :class:`SocialDWA`: those of :class:`DWAConfig` and the social ones
    (lengths in m, times in s, speeds in m/s). Its global planner searches with a weaker
    heuristic and replans less often than the DWA's (the social layers make searches
    costlier)."""

    # trajectory costs: time averages of SRPB values in [0, 1]
    w_psi: float = 8.0  # personal space
    w_fsi: float = 6.0  # O-space of groups
    w_dir: float = 2.0  # heading disturbance
    social_stride: int = 4  # every how many trajectory steps the poses are scored
    social_range: float = 5.0  # m, only people this close to the robot count, ...
    social_people: int = 6  # ... at most this many, the nearest
    # groups: standing tracks (slower than group_speed) within group_distance of another
    group_distance: float = 2.0  # m, standing tracks this close to another form a group
    group_speed: float = 0.3  # m/s, group members are slower than this
    group_memory: float = 10.0  # s, a group stays known this long after it was seen ...
    group_match: float = 1.0  # m, ... unless one is seen this close to it
    # cost layers of the global planner (per metre)
    psi_layer: float = 3.0  # personal spaces of standing people
    walking_layer: float = 10.0  # personal spaces of people walking at the robot
    fsi_layer: float = 30.0  # O-spaces
    layer_spread: float = 1.5  # standing people's and groups' Gaussians this much wider
    layer_reach: float = 2.5  # m, personal spaces reach this far
    # impatience
    patience: float = 4.0  # s, no progress this long: the social costs fade over another
    min_scale: float = 0.25  # ... patience to this fraction of their weight
    global_planner: GlobalPlannerConfig = field(
        default_factory=lambda: GlobalPlannerConfig(
            person_margin=0.1, heuristic_weight=1.5, replan_period=3.0, min_replan_interval=1.0
        )
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        self._count("social_stride", 1)
        if self.social_stride > max(round(self.horizon / self.sim_dt), 1):
            raise SettingError("social_stride", "must not exceed the steps of a trajectory "
                               f"(horizon / sim_dt), got {self.social_stride}")  # fmt: skip
        self._count("social_people", 0)
        self._positive("layer_spread", "patience")
        self._nonnegative("w_psi", "w_fsi", "w_dir", "social_range", "group_distance",
                          "group_speed", "group_memory", "group_match", "psi_layer",
                          "walking_layer", "fsi_layer", "layer_reach")  # fmt: skip
        self._within("min_scale", 0.0, 1.0)


class SocialDWA(DWA):
    """:class:`DWA` with the SRPB social costs (see the module docstring).

    Weights (costs are time averages of values in [0, 1]): ``w_psi`` personal space,
    ``w_fsi`` O-space, ``w_dir`` heading disturbance. ``social_stride``: every how many
    trajectory steps the poses are scored; only the ``social_people`` nearest people within
    ``social_range`` [m] of the robot count. ``group_distance`` [m] and ``group_speed``
    [m/s]: standing tracks closer than this form a group; a group stays known
    ``group_memory`` [s] after it was last seen (one seen within ``group_match`` [m] of it
    replaces it). Cost layers of the global planner (per metre): ``psi_layer`` and
    ``walking_layer`` weigh the personal spaces of standing people and of people walking at
    the robot, ``fsi_layer`` the O-spaces; the Gaussians of standing people and groups are
    ``layer_spread`` times wider than the metric's (the path keeps a margin); personal
    spaces reach ``layer_reach`` [m].
    Impatience: when the robot has not come 0.2 m closer to the goal (static cost-to-go)
    for ``patience`` [s], the social costs fade linearly over another ``patience`` seconds
    to ``min_scale`` times their weight (so it does not wait forever in a crowd).
    The metric parameters of the costs are the ``paper`` preset's with the robot's
    circumradius and largest speed (as the environment scores them).

    ``config``: the settings (:class:`SocialDWAConfig`, a mapping of the fields to change,
    or ``None``: the defaults).
    """

    name = "social-dwa"
    config_class: ClassVar[type[SocialDWAConfig]] = SocialDWAConfig
    config: SocialDWAConfig

    def __init__(self, config: SocialDWAConfig | Mapping[str, Any] | None = None) -> None:
        super().__init__(config)
        self._best_c2g, self._progress_t, self._social_scale = math.inf, 0.0, 1.0
        self.params = MetricParams()
        self.planner.layers.append(self._layers)
        self._memory = np.zeros((0, 9))
        self._ellipses, self._gcov = np.zeros((0, 5)), np.zeros((0, 3))

    def reset(self, knowledge: Knowledge) -> None:
        super().reset(knowledge)
        robot = knowledge.robot
        self.params = MetricParams().replace(
            robot_circumradius=robot.radius, robot_max_speed=robot.max_speed
        )
        self._memory = np.zeros((0, 9))  # remembered groups: ellipse (5), cov (3), time seen
        self._best_c2g, self._progress_t, self._social_scale = math.inf, knowledge.t, 1.0
        self._ellipses, self._gcov = np.zeros((0, 5)), np.zeros((0, 3))

    def decide(self, knowledge: Knowledge) -> tuple[float, float]:
        k = knowledge
        self._perceive_groups(k.tracks, k.t)
        if self.planner.path.shape[0]:  # impatience: time since the last progress
            c2g = self.planner.cost_to_go(float(k.pose[0]), float(k.pose[1]))
            if c2g < self._best_c2g - 0.2:
                self._best_c2g, self._progress_t = c2g, k.t
        cfg = self.config
        idle = k.t - self._progress_t - cfg.patience
        self._social_scale = float(np.clip(1.0 - idle / cfg.patience, cfg.min_scale, 1.0))
        return super().decide(k)

    def _perceive_groups(self, tracks: Tracks, t: float) -> None:
        """O-space ellipses (G, 5) and covariances (G, 3) of the groups seen now and of
        those seen within ``group_memory`` seconds (standing groups stay where they are)."""
        seen = self._detect(tracks)
        mem = self._memory
        if seen.shape[0] and mem.shape[0]:
            d = np.hypot(mem[:, None, 0] - seen[None, :, 0], mem[:, None, 1] - seen[None, :, 1])
            mem = mem[d.min(axis=1) > self.config.group_match]
        mem = np.vstack([mem[t - mem[:, 8] <= self.config.group_memory], np.column_stack(
            [seen, np.full(seen.shape[0], t)])])  # fmt: skip
        self._memory = mem
        self._ellipses, self._gcov = mem[:, :5].copy(), mem[:, 5:8].copy()

    def _detect(self, tracks: Tracks) -> NDArray[np.float64]:
        """(G, 8) O-space ellipse and covariance (sxx, sxy, syy) of each group seen now."""
        cfg = self.config
        members, start, size = detect_groups(tracks, cfg.group_speed, cfg.group_distance)
        return ospace_gaussians(tracks, members, start, size, self.params)

    def _layers(self, knowledge: Knowledge, cost: NDArray[np.float64]) -> None:
        """The personal-space and O-space layers of the global planner's cost grid."""
        cfg, gp, tr = self.config, self.planner, knowledge.tracks
        rel = knowledge.pose[:2] - tr.xy
        dist, speed = np.hypot(*rel.T), np.hypot(*tr.velocity.T)
        still = speed < cfg.group_speed
        oncoming = (tr.velocity * rel).sum(axis=1) > gp.config.oncoming_cos * speed * dist
        near = np.flatnonzero((dist < cfg.social_range) & (still | oncoming))
        if near.size:  # standing people and people walking at the robot
            cov = tr.covariance[near]
            speed, still = speed[near], still[near]
            personal_space_layer(
                cost, gp.x0, gp.y0, gp.res, np.ascontiguousarray(tr.xy[near, 0]),
                np.ascontiguousarray(tr.xy[near, 1]), np.ascontiguousarray(tr.yaw[near]), speed,
                np.ascontiguousarray(cov[:, 0, 0]), 0.5 * (cov[:, 0, 1] + cov[:, 1, 0]),
                np.ascontiguousarray(cov[:, 1, 1]),
                np.where(still, cfg.psi_layer, cfg.walking_layer),
                np.where(still, cfg.layer_spread, 1.0), cfg.layer_reach,
            )  # fmt: skip
        if cfg.fsi_layer > 0 and self._ellipses.shape[0]:
            ospace_layer(cost, gp.x0, gp.y0, gp.res, np.ascontiguousarray(self._ellipses),
                         self._gcov, cfg.fsi_layer, cfg.layer_spread,
                         1.5 * cfg.layer_spread)  # fmt: skip

    def _social_costs(self, k: Knowledge, traj: NDArray[np.float64]) -> NDArray[np.float64]:
        """w_psi psi + w_dir dir + w_fsi fsi of each trajectory: time averages over its
        poses (every ``social_stride`` steps) of the largest per-person (per-group) value,
        people predicted at constant velocity."""
        cfg, tr, p = self.config, k.tracks, self.params
        n_s = traj.shape[0]
        social = np.zeros(n_s)
        poses = traj[:, cfg.social_stride - 1 :: cfg.social_stride, :]
        n_k = poses.shape[1]
        n_r = n_s * n_k  # robot poses
        rx, ry = poses[..., 0].ravel(), poses[..., 1].ravel()
        dist = np.hypot(*(tr.xy - k.pose[:2]).T)
        near = np.argsort(dist)[: cfg.social_people]
        near = near[dist[near] < cfg.social_range]
        if near.size:
            t = (np.arange(n_k) + 1) * cfg.social_stride * cfg.sim_dt
            vel = tr.velocity[near]
            moving = np.where(np.hypot(*vel.T)[:, None] >= cfg.standing_speed, vel, 0.0)
            pxy = tr.xy[near][None, :, :] + t[:, None, None] * moving[None, :, :]  # (K, P, 2)
            n_p = near.size
            cov = tr.covariance[near]
            per_person = [np.ascontiguousarray(np.tile(a, n_r)) for a in (
                tr.yaw[near], vel[:, 0], vel[:, 1], cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 0],
                cov[:, 1, 1])]  # fmt: skip
            psi, dirv = np.empty(n_r * n_p), np.empty(n_r * n_p)
            kernels.person_terms(
                rx, ry, poses[..., 2].ravel(), np.abs(poses[..., 3]).ravel(),
                np.repeat(np.arange(n_r), n_p), np.tile(pxy[..., 0].ravel(), n_s),
                np.tile(pxy[..., 1].ravel(), n_s), *per_person, p.person_fov,
                p.robot_max_speed, p.robot_circumradius, p.person_occupancy_radius, False,
                psi, dirv,
            )  # fmt: skip
            social += cfg.w_psi * psi.reshape(n_s, n_k, n_p).max(axis=2).mean(axis=1)
            social += cfg.w_dir * dirv.reshape(n_s, n_k, n_p).max(axis=2).mean(axis=1)
        g = self._ellipses.shape[0]
        if g and cfg.w_fsi > 0:
            e, c = self._ellipses, self._gcov
            fsi = np.empty(n_r * g)
            kernels.group_terms(
                rx, ry, np.repeat(np.arange(n_r), g), *(
                    np.ascontiguousarray(np.tile(a, n_r)) for a in (
                        e[:, 0], e[:, 1], e[:, 2], e[:, 3], e[:, 4], c[:, 0], c[:, 1], c[:, 2])),
                fsi,
            )  # fmt: skip
            social += cfg.w_fsi * fsi.reshape(n_s, n_k, g).max(axis=2).mean(axis=1)
        return self._social_scale * social
