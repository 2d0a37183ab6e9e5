"""Episode-level SRPB metrics of an :class:`~srpb_gym.metrics.record.EpisodeRecord`."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.angles import wrap_angle
from srpb_gym.metrics import kernels
from srpb_gym.metrics.ellipse import accept_fit, taubin_fit
from srpb_gym.metrics.params import MetricParams, check_semantics, resolve_params
from srpb_gym.metrics.record import EpisodeRecord, R, invalid_person_row, invalid_robot_row

MOTION_METRICS: tuple[str, ...] = (
    "m_goal", "m_obs", "m_mef", "m_plin", "m_chc", "m_cef", "m_cre",
    "m_vsm", "m_hsm", "m_osc", "m_bwd", "m_iprot",
)  # fmt: skip
SOCIAL_METRICS: tuple[str, ...] = ("m_psi", "m_fsi", "m_dir")
METRIC_NAMES: tuple[str, ...] = MOTION_METRICS + tuple(
    f"{m}{suffix}" for m in SOCIAL_METRICS for suffix in ("", "_min", "_max", "_viol")
)
METRIC_UNITS: dict[str, str] = {
    "m_goal": "0/1", "m_obs": "%", "m_mef": "s", "m_plin": "m", "m_chc": "rad",
    "m_cef": "ms", "m_cre": "ms", "m_vsm": "m/s^2", "m_hsm": "rad/s^2",
    "m_osc": "%", "m_bwd": "%", "m_iprot": "%",
    **{f"{m}{s}": "%" for m in SOCIAL_METRICS for s in ("", "_min", "_max", "_viol")},
}  # fmt: skip
METRIC_DESCRIPTIONS: dict[str, str] = {
    "m_goal": "goal reached (last sample within tolerance)",
    "m_obs": "time closer than safety_distance to an obstacle",
    "m_mef": "time to goal (episode duration)",
    "m_plin": "path length",
    "m_chc": "cumulative heading change",
    "m_cef": "mean planner computation time",
    "m_cre": "std. dev. of planner computation time",
    "m_vsm": "mean linear acceleration (velocity smoothness)",
    "m_hsm": "mean angular acceleration (heading smoothness)",
    "m_osc": "time oscillating (almost standing still)",
    "m_bwd": "time moving backward",
    "m_iprot": "time rotating in place",
    "m_psi": "personal space intrusion",
    "m_fsi": "F-formation O-space intrusion",
    "m_dir": "heading straight into people",
    **{f"{m}_min": "smallest per-entity value" for m in SOCIAL_METRICS},
    **{f"{m}_max": "largest per-entity value" for m in SOCIAL_METRICS},
    **{f"{m}_viol": "share of per-entity values above the threshold" for m in SOCIAL_METRICS},
}
METRIC_RANGES: dict[str, tuple[float, float]] = {
    name: (0.0, 1.0) if unit == "0/1" else (0.0, 100.0) if unit == "%" else (0.0, math.inf)
    for name, unit in METRIC_UNITS.items()
}
"""The values each metric can take, inclusive: ``m_goal`` 0 or 1, a share in % from 0 to
100, the others (durations, lengths, heading changes, accelerations, computation times)
not below 0; a metric that is computed is finite (NaN: not computed)."""
_THRESHOLD = {
    "m_psi": "personal_space_threshold",
    "m_fsi": "group_space_threshold",
    "m_dir": "heading_disturbance_threshold",
}


class SRPBMetricWarning(RuntimeWarning):
    """A metric is undefined for this episode (too short, zero duration) and is NaN."""


@dataclass
class EpisodeEvaluation:
    """Metrics plus the per-entity values they aggregate.

    ``psi``/``dir``: one value per people row of the record (in [0, 1] under ``paper``).
    ``fsi``: one value per group row; ``ellipses``: (G, 5) O-space ellipse per group row
    (centre x, y [m], semi-axes a, b [m], orientation [rad]); ``fit_taubin``: whether the
    ellipse came from Taubin's fit (else the small-sample fallback).
    """

    metrics: dict[str, float]
    psi: NDArray[np.float64]
    dir: NDArray[np.float64]
    fsi: NDArray[np.float64]
    ellipses: NDArray[np.float64]
    fit_taubin: NDArray[np.bool_]
    params: MetricParams = field(default_factory=MetricParams)
    semantics: str = "paper"


def evaluate(
    record: EpisodeRecord,
    semantics: str = "paper",
    preset: str | MetricParams = "paper",
    **overrides: Any,
) -> dict[str, float]:
    """Every SRPB metric of one episode, keyed by :data:`METRIC_NAMES` (units in
    :data:`METRIC_UNITS`).

    ``semantics``: ``"paper"`` (the paper's equations) or ``"reference"`` (the reference
    tool's numbers, quirks included). ``preset``: ``"paper"`` or ``"srpb-code"`` parameters;
    ``overrides`` replace single parameters by name (see :class:`MetricParams`).
    """
    return evaluate_detailed(record, semantics, preset, **overrides).metrics


def evaluate_detailed(
    record: EpisodeRecord,
    semantics: str = "paper",
    preset: str | MetricParams = "paper",
    **overrides: Any,
) -> EpisodeEvaluation:
    """Like :func:`evaluate`, also returning the per-person and per-group values."""
    reference = check_semantics(semantics) == "reference"
    params = resolve_params(preset, **overrides)
    n = record.n_samples
    if n == 0:
        raise ValueError("the episode has no robot sample: nothing to evaluate")
    for table, check, name in ((record.robot, invalid_robot_row, "robot"),
                               (record.people, invalid_person_row, "people")):  # fmt: skip
        found = check(table)
        if found is not None:  # never a number from a value that cannot be right
            raise ValueError(f"{name} row {found[0]}: {found[1]}")
    t = record.robot_col("t")
    dt = np.diff(t)
    overflows: list[str] = []
    with np.errstate(over="call", call=lambda kind, flag: overflows.append(kind)):
        metrics = motion_metrics(record, params, reference)
        ev = social_values(record, params, reference)
        for name, values, sample in (
            ("m_psi", ev.psi, record.people_sample),
            ("m_dir", ev.dir, record.people_sample),
            ("m_fsi", ev.fsi, record.group_sample),
        ):
            threshold = getattr(params, _THRESHOLD[name])
            metrics.update(aggregate_social(name, values, sample, dt, n, threshold, reference))
    _drop_overflows(metrics, reference, bool(overflows))
    ev.metrics = {key: metrics[key] for key in METRIC_NAMES}
    ev.params, ev.semantics = params, semantics
    return ev


def _drop_overflows(metrics: dict[str, float], reference: bool, overflowed: bool) -> None:
    """Report an infinite metric as not computable (NaN, with a warning) where it can only
    come from an overflow (a value of the log too large): in the paper's semantics, whose
    every division is guarded, any infinite metric; in ``reference`` semantics, whose
    quirks divide by zero as the reference tool does (a time step of zero, a person at
    the robot's centre), only when a computation overflowed (``overflowed``)."""
    over = [k for k, v in metrics.items() if math.isinf(v)]
    if over and (overflowed or not reference):
        _warn_nan(", ".join(over), "a value of the log is too large: the computation overflows")
        metrics.update(dict.fromkeys(over, math.nan))


def _warn_nan(names: str, why: str) -> None:
    warnings.warn(f"{names} undefined ({why}): reported as NaN", SRPBMetricWarning, stacklevel=4)


def motion_metrics(
    record: EpisodeRecord, params: MetricParams, reference: bool
) -> dict[str, float]:
    """The task and motion metrics (everything but the social ones)."""
    col = record.robot_col
    n = record.n_samples
    pt = col("planning_time")
    out = {"m_goal": float(goal_reached(record, params)) if (n > 1 or not reference) else 1.0}
    # NaN marks a sample without a timed decision (the final one of a simulated run); the
    # reference tool's own logs never hold one, so skipping it leaves their numbers as they are
    pt = pt[~np.isnan(pt)]
    if pt.size == 0 and not reference:
        _warn_nan("m_cef, m_cre", "no planning time recorded")
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # mean of nothing: NaN, warned above
        out["m_cef"] = 1000.0 * float(pt.mean())
        out["m_cre"] = 1000.0 * float(pt.std())
    if n < 2:
        out.update(m_mef=0.0, m_plin=0.0, m_chc=0.0)
        undefined = ("m_obs", "m_vsm", "m_hsm", "m_osc", "m_bwd", "m_iprot")
        if reference:
            out.update(m_cef=0.0, m_cre=math.nan)
        else:
            _warn_nan(", ".join(undefined), "fewer than two samples")
        out.update(dict.fromkeys(undefined, math.nan))
        return out
    t, x, y, yaw = col("t"), col("x"), col("y"), col("yaw")
    dt = np.diff(t)
    total = float(t[-1] - t[0])
    out["m_mef"] = total
    out["m_plin"] = float(np.hypot(np.diff(x), np.diff(y)).sum())
    dyaw = np.diff(yaw)
    out["m_chc"] = float(np.abs(dyaw if reference else wrap_angle(dyaw)).sum())
    flags = _flags(col("vx"), col("vy"), col("omega"), params, reference)
    with np.errstate(divide="ignore", invalid="ignore"):
        if reference:
            obs = kernels.reference_obstacle_time(t, col("obstacle_dist") < params.safety_distance)
        else:
            obs = math.fsum(dt[col("obstacle_dist")[:-1] < params.safety_distance])
        # exactly rounded sums (math.fsum), not BLAS dot products, whose summation order
        # depends on the processor: the same episode scores the same on every CPU
        shares = {"m_obs": obs} | {k: math.fsum(dt[f[:-1].astype(bool)]) for k, f in flags.items()}
        if total == 0.0 and not reference:
            _warn_nan("m_obs, m_osc, m_bwd, m_iprot", "zero episode duration")
        for key, value in shares.items():
            out[key] = float(np.float64(100.0 * value) / total)
        out.update(_smoothness(col("vx"), col("vy"), col("omega"), dt, reference))
    return out


def goal_reached(record: EpisodeRecord, params: MetricParams) -> bool:
    """Whether the last sample is within the goal tolerances (position and yaw)."""
    row = record.robot[-1]
    return at_goal(row[R["x"]], row[R["y"]], row[R["yaw"]], row[R["goal_x"]], row[R["goal_y"]],
                   row[R["goal_yaw"]], params.goal_tolerance_xy,
                   params.goal_tolerance_yaw)  # fmt: skip


def at_goal(
    x: float, y: float, yaw: float, goal_x: float, goal_y: float, goal_yaw: float,
    tolerance_xy: float, tolerance_yaw: float,
) -> bool:  # fmt: skip
    """The SRPB goal rule: the position within ``tolerance_xy`` [m] of the goal and the
    heading within ``tolerance_yaw`` [rad] of the goal's (``m_goal``, and the end of an
    episode in the environments)."""
    return bool(math.hypot(goal_x - x, goal_y - y) <= tolerance_xy
                and abs(wrap_angle(float(goal_yaw - yaw))) <= tolerance_yaw)  # fmt: skip


def _flags(vx, vy, omega, params: MetricParams, reference: bool) -> dict[str, NDArray[np.bool_]]:
    n = vx.shape[0]
    osc, bwd, iprot = (np.empty(n, dtype=np.bool_) for _ in range(3))
    kernels.motion_flags(
        vx, vy, omega, params.osc_vel_lin_x_threshold, params.osc_vel_x_threshold,
        params.osc_vel_y_threshold, params.osc_vel_ang_z_threshold,
        params.stop_speed_tolerance, reference, osc, bwd, iprot,
    )  # fmt: skip
    return {"m_osc": osc, "m_bwd": bwd, "m_iprot": iprot}


def _smoothness(vx, vy, omega, dt, reference: bool) -> dict[str, float]:
    lin = np.hypot(np.abs(np.diff(vx)) / dt, np.abs(np.diff(vy)) / dt)
    ang = np.abs(np.diff(omega)) / dt
    if reference:
        return {"m_vsm": float(lin.sum() / lin.shape[0]), "m_hsm": float(ang.sum() / ang.shape[0])}
    moving = dt > 0
    if not moving.any():
        _warn_nan("m_vsm, m_hsm", "no time step longer than zero")
        return {"m_vsm": math.nan, "m_hsm": math.nan}
    return {"m_vsm": float(lin[moving].mean()), "m_hsm": float(ang[moving].mean())}


def social_values(
    record: EpisodeRecord, params: MetricParams, reference: bool
) -> EpisodeEvaluation:
    """Per-person psi and dir, per-group fsi and O-space ellipses of every sample."""
    groups = (record.group_sample, record.group_members, record.group_start, record.group_size)
    psi, dirv, fsi, ellipses, taubin = entity_values(
        record.robot, record.people, record.people_sample, *groups, params, reference
    )
    return EpisodeEvaluation({}, psi, dirv, fsi, ellipses, taubin)


def entity_values(
    robot: NDArray[np.float64],
    people: NDArray[np.float64],
    people_sample: NDArray[np.int64],
    group_sample: NDArray[np.int64],
    group_members: NDArray[np.int64],
    group_start: NDArray[np.int64],
    group_size: NDArray[np.int64],
    params: MetricParams,
    reference: bool,
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """psi and dir of every people row, fsi, O-space ellipse and fit kind of every group row.

    Tables as in :class:`EpisodeRecord` (``robot`` (N, 12), ``people`` (P, 9); samples index
    ``robot`` rows, members index ``people`` rows), so this serves a whole episode as well
    as the latest sample of a running one.
    """
    g = group_sample.shape[0]
    psi, dirv, fsi = np.empty(people.shape[0]), np.empty(people.shape[0]), np.empty(g)
    no_groups = np.empty((0, 5)), np.zeros(0, dtype=np.bool_)
    if people.shape[0] == 0:
        return psi, dirv, fsi, *no_groups
    _, rx, ry, ryaw, vx, vy = np.ascontiguousarray(robot[:, :6].T)  # R: t, x, y, yaw, vx, vy
    px, py, pyaw, cxx, cxy, cyx, cyy, pvx, pvy = np.ascontiguousarray(people.T)
    kernels.person_terms(
        rx, ry, ryaw, np.hypot(vx, vy), people_sample, px, py, pyaw, pvx, pvy, cxx, cxy, cyx,
        cyy, params.person_fov, params.robot_max_speed, params.robot_circumradius,
        params.person_occupancy_radius, reference, psi, dirv,
    )  # fmt: skip
    if g == 0:
        return psi, dirv, fsi, *no_groups
    ellipses, taubin = _group_terms(
        rx, ry, px, py, cxx, cxy, cyx, cyy, group_sample, group_members, group_start,
        group_size, params, reference, fsi,
    )  # fmt: skip
    return psi, dirv, fsi, ellipses, taubin


def group_values(
    robot: NDArray[np.float64],
    people: NDArray[np.float64],
    group_sample: NDArray[np.int64],
    group_members: NDArray[np.int64],
    group_start: NDArray[np.int64],
    group_size: NDArray[np.int64],
    params: MetricParams,
    reference: bool,
) -> NDArray[np.float64]:
    """fsi of every group row (tables as in :func:`entity_values`, at least one group)."""
    _, rx, ry = np.ascontiguousarray(robot[:, :3].T)
    px, py, _, cxx, cxy, cyx, cyy = np.ascontiguousarray(people[:, :7].T)
    fsi = np.empty(group_sample.shape[0])
    _group_terms(rx, ry, px, py, cxx, cxy, cyx, cyy, group_sample, group_members, group_start,
                 group_size, params, reference, fsi)  # fmt: skip
    return fsi


def _group_terms(rx, ry, px, py, cxx, cxy, cyx, cyy, group_sample, members, start, size,
                 params, reference, fsi):  # fmt: skip
    ellipses, taubin = group_ellipses(px, py, members, start, size, params, reference)
    g = size.shape[0]
    sxx, sxy, syy = np.empty(g), np.empty(g), np.empty(g)
    kernels.group_covariances(cxx, cxy, cyx, cyy, members, start, size, reference, sxx, sxy,
                              syy)  # fmt: skip
    e = np.ascontiguousarray(ellipses.T)
    kernels.group_terms(rx, ry, group_sample, e[0], e[1], e[2], e[3], e[4], sxx, sxy, syy, fsi)
    return ellipses, taubin


#: the smallest group fit with Taubin's method, by semantics (paper, reference)
TAUBIN_MIN_MEMBERS = (5, 2)


def group_ellipses(
    px, py, members, start, size, params: MetricParams, reference: bool
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """O-space ellipse of every group row: Taubin's fit where it applies and is accepted
    (``paper``: 5 or more members; ``reference``: 2 or more), else the fallback."""
    out = np.empty((size.shape[0], 5))
    taubin = size >= TAUBIN_MIN_MEMBERS[reference]
    rows = np.flatnonzero(taubin)
    if rows.size:
        fits = taubin_fit(px, py, members, start[rows], size[rows])
        accepted = accept_fit(fits, px, py, members, start[rows], size[rows], reference)
        out[rows[accepted]] = fits[accepted]
        taubin[rows[~accepted]] = False
    e = np.empty((5, size.shape[0]))
    kernels.fallback_ellipses(
        px, py, members, start, size, params.person_occupancy_radius, reference, taubin,
        e[0], e[1], e[2], e[3], e[4],
    )  # fmt: skip
    out[~taubin] = e.T[~taubin]
    return out, taubin


def aggregate_social(
    name: str, values, sample, dt, n: int, threshold: float, reference: bool
) -> dict[str, float]:
    """``name`` and its ``_min``, ``_max``, ``_viol`` from per-entity values [%]."""
    stats = np.array([np.inf, -np.inf, 0.0, 0.0])
    num, den, used = kernels.aggregate(values, sample, dt, n, threshold, reference, stats)
    if used == 0:
        return {name: 0.0, f"{name}_min": 0.0, f"{name}_max": 0.0, f"{name}_viol": 0.0}
    with np.errstate(divide="ignore", invalid="ignore"):
        if den == 0.0 and not reference:
            _warn_nan(name, "people present only during zero-length steps")
        value = float(np.float64(100.0 * num) / den)
    return {
        name: value,
        f"{name}_min": float(100.0 * stats[0]),
        f"{name}_max": float(100.0 * stats[1]),
        f"{name}_viol": float(100.0 * stats[3] / stats[2]),
    }
