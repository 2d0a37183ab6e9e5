"""Metric parameters: presets, overrides and the meaningful range of every parameter."""

from __future__ import annotations

import math

import pytest

from srpb_gym.errors import InputError
from srpb_gym.metrics.params import (
    PARAM_NAMES,
    PARAM_RANGES,
    PRESETS,
    MetricParams,
    resolve_params,
)

# name: (accepted values, refused values, the message's range text)
RANGES = {
    "safety_distance": ([1e-9, 0.55, 100.0], [0.0, -1.0], "> 0 m"),
    "osc_vel_lin_x_threshold": ([1e-6, 0.05], [0.0, -0.05], "> 0 m/s"),
    "osc_vel_x_threshold": ([0.025], [0.0], "> 0 m/s"),
    "osc_vel_y_threshold": ([0.025], [-1e-9], "> 0 m/s"),
    "osc_vel_ang_z_threshold": ([0.15], [0.0], "> 0 rad/s"),
    "person_fov": ([1e-3, math.pi, 2 * math.pi], [0.0, -3.3, 2 * math.pi + 1e-9, 7.0],
                   "in (0, 2 pi] rad"),
    "person_occupancy_radius": ([0.28], [0.0, -0.28], "> 0 m"),
    "robot_circumradius": ([0.0, 0.275], [-0.1], ">= 0 m"),
    "robot_max_speed": ([0.55], [0.0, -0.5], "> 0 m/s"),
    "goal_tolerance_xy": ([0.0, 0.2], [-0.2], ">= 0 m"),
    "goal_tolerance_yaw": ([0.0, 0.2, 10.0], [-0.2], ">= 0 rad"),
    "personal_space_threshold": ([0.0, 0.5, 1.0], [-0.1, 1.5], "in [0, 1]"),
    "group_space_threshold": ([0.0, 1.0], [1.0001], "in [0, 1]"),
    "heading_disturbance_threshold": ([0.2], [-1e-12, 2.0], "in [0, 1]"),
    "stop_speed_tolerance": ([0.0, 0.005], [-0.005], ">= 0 m/s"),
}  # fmt: skip


def test_every_parameter_has_a_range():
    assert set(PARAM_RANGES) == set(PARAM_NAMES) == set(RANGES)


def test_presets_are_within_range():
    for params in PRESETS.values():
        assert resolve_params(params) == params


@pytest.mark.parametrize("name", sorted(RANGES))
def test_values_outside_the_range_are_refused(name):
    accepted, refused, wanted = RANGES[name]
    for value in accepted:
        assert getattr(resolve_params("paper", **{name: value}), name) == value
        assert getattr(resolve_params("srpb-code", **{name: str(value)}), name) == value
    for value in refused:
        with pytest.raises(InputError) as info:
            resolve_params("paper", **{name: value})
        assert str(info.value) == f"{name}: must be {wanted}, got {value!r}"
        assert info.value.key == name
        with pytest.raises(ValueError):  # callers catch ValueError
            MetricParams(**{name: value})


def test_the_command_line_example():
    with pytest.raises(ValueError) as info:
        resolve_params("paper", safety_distance="-1")
    assert str(info.value) == "safety_distance: must be > 0 m, got '-1'"


@pytest.mark.parametrize(("value", "message"), [
    ("abc", "safety_distance: expected a number, got 'abc'"),
    (None, "safety_distance: expected a number, got None"),
    ("nan", "safety_distance: expected a finite number > 0 m, got 'nan'"),
    (float("inf"), "safety_distance: expected a finite number > 0 m, got inf"),
])  # fmt: skip
def test_values_that_are_not_finite_numbers(value, message):
    with pytest.raises(InputError) as info:
        resolve_params("paper", safety_distance=value)
    assert str(info.value) == message


def test_unknown_names_stay_key_errors():
    with pytest.raises(KeyError, match="unknown metric parameter 'speed'"):
        resolve_params("paper", speed=1.0)
    with pytest.raises(KeyError, match="unknown preset"):
        resolve_params("fast")
    with pytest.raises(KeyError):
        MetricParams().replace(speed=1.0)


def test_replace_checks_the_range():
    with pytest.raises(InputError, match="person_fov: must be in"):
        PRESETS["paper"].replace(person_fov=7.0)
