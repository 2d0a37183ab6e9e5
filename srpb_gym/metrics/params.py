"""SRPB metric parameters, their two presets and the two evaluation semantics.

Every parameter has the name the SRPB reference code gives it. Units are SI (m, s, rad),
thresholds of the social metrics are dimensionless (values in [0, 1]).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

from srpb_gym.errors import InputError

Semantics = Literal["paper", "reference"]
SEMANTICS: tuple[str, ...] = ("paper", "reference")


@dataclass(frozen=True)
class MetricParams:
    """Parameters of the SRPB metrics (defaults: preset ``paper``)."""

    safety_distance: float = 0.55  # d_min [m], obstacle safety (m_obs)
    osc_vel_lin_x_threshold: float = 0.025  # v_osc on hypot(vx, vy) [m/s]
    osc_vel_x_threshold: float = 0.025  # v_osc on |vx| [m/s]
    osc_vel_y_threshold: float = 0.025  # v_osc on |vy| [m/s]
    osc_vel_ang_z_threshold: float = 0.05  # w_osc [rad/s]
    person_fov: float = 3.3  # phi_fov, a person's field of view [rad]
    person_occupancy_radius: float = 0.28  # d_ocp [m]
    robot_circumradius: float = 0.275  # d_cr [m]
    robot_max_speed: float = 0.5  # v_max [m/s]
    goal_tolerance_xy: float = 0.2  # [m]
    goal_tolerance_yaw: float = 0.2  # [rad]
    personal_space_threshold: float = 0.5  # m_psi_viol threshold
    group_space_threshold: float = 0.5  # m_fsi_viol threshold
    heading_disturbance_threshold: float = 0.2  # m_dir_viol threshold
    stop_speed_tolerance: float = 0.005  # "linear speed is zero" [m/s]

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            check_param(f.name, getattr(self, f.name))

    def replace(self, **overrides: Any) -> MetricParams:
        """A copy with the named parameters replaced; unknown names raise ``KeyError``."""
        return resolve_params(self, **overrides)

    def as_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)


PARAM_NAMES: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(MetricParams))

_POSITIVE, _NON_NEGATIVE, _UNIT, _ANGLE = "> 0", ">= 0", "in [0, 1]", "in (0, 2 pi]"
PARAM_RANGES: dict[str, tuple[str, str]] = {
    "safety_distance": (_POSITIVE, "m"),
    "osc_vel_lin_x_threshold": (_POSITIVE, "m/s"),
    "osc_vel_x_threshold": (_POSITIVE, "m/s"),
    "osc_vel_y_threshold": (_POSITIVE, "m/s"),
    "osc_vel_ang_z_threshold": (_POSITIVE, "rad/s"),
    "person_fov": (_ANGLE, "rad"),
    "person_occupancy_radius": (_POSITIVE, "m"),
    "robot_circumradius": (_NON_NEGATIVE, "m"),
    "robot_max_speed": (_POSITIVE, "m/s"),
    "goal_tolerance_xy": (_NON_NEGATIVE, "m"),
    "goal_tolerance_yaw": (_NON_NEGATIVE, "rad"),
    "personal_space_threshold": (_UNIT, ""),
    "group_space_threshold": (_UNIT, ""),
    "heading_disturbance_threshold": (_UNIT, ""),
    "stop_speed_tolerance": (_NON_NEGATIVE, "m/s"),
}
"""Meaningful range and unit of every parameter: (range, unit)."""

_IN_RANGE = {
    _POSITIVE: lambda v: v > 0.0,
    _NON_NEGATIVE: lambda v: v >= 0.0,
    _UNIT: lambda v: 0.0 <= v <= 1.0,
    _ANGLE: lambda v: 0.0 < v <= 2.0 * math.pi,
}


def check_param(name: str, value: Any) -> float:
    """``value`` of parameter ``name`` as a float, checked to be a finite number within
    the parameter's range (:data:`PARAM_RANGES`).

    Raises :class:`InputError` (a ``ValueError``; key = the parameter name) naming the
    range otherwise, and ``KeyError`` for an unknown name.
    """
    if name not in PARAM_RANGES:
        raise KeyError(f"unknown metric parameter {name!r}; valid names: {', '.join(PARAM_NAMES)}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"expected a number, got {value!r}", key=name) from None
    where, unit = PARAM_RANGES[name]
    wanted = f"{where} {unit}".rstrip()
    if not math.isfinite(number):
        raise InputError(f"expected a finite number {wanted}, got {value!r}", key=name)
    if not _IN_RANGE[where](number):
        raise InputError(f"must be {wanted}, got {value!r}", key=name)
    return number


PRESETS: dict[str, MetricParams] = {
    "paper": MetricParams(),
    "srpb-code": MetricParams(
        osc_vel_lin_x_threshold=0.05,
        osc_vel_x_threshold=0.05,
        osc_vel_y_threshold=0.05,
        osc_vel_ang_z_threshold=0.15,
        person_fov=3.31612557879,  # 190 deg
        robot_max_speed=0.55,
    ),
}


def resolve_params(preset: str | MetricParams = "paper", **overrides: Any) -> MetricParams:
    """Parameters of ``preset`` (a name in :data:`PRESETS` or a :class:`MetricParams`)
    with ``overrides`` applied by parameter name.

    Raises ``KeyError`` for an unknown preset or parameter name and :class:`InputError`
    (a ``ValueError``, key = the parameter name) for a value that is not a finite number
    within the parameter's range (:data:`PARAM_RANGES`).
    """
    if isinstance(preset, MetricParams):
        base = preset
    elif preset in PRESETS:
        base = PRESETS[preset]
    else:
        raise KeyError(f"unknown preset {preset!r}; choose one of {sorted(PRESETS)}")
    clean = {name: check_param(name, value) for name, value in overrides.items()}
    return dataclasses.replace(base, **clean)


def check_semantics(semantics: str) -> str:
    if semantics not in SEMANTICS:
        raise ValueError(f"unknown semantics {semantics!r}; choose 'paper' or 'reference'")
    return semantics
