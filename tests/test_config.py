"""Strict construction of config dataclasses from plain data."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401  (registers the environments)
from srpb_gym.config import from_dict, from_spec
from srpb_gym.errors import InputError
from srpb_gym.reward import TERMS, check_weights, load_preset


@dataclass(frozen=True)
class Inner:
    gain: float = 1.0


@dataclass(frozen=True)
class Demo:
    a: float = 1.0
    b: tuple[float, float] = (0.0, 1.0)
    n: int = 3
    on: bool = False
    name: str = "x"
    inner: Inner = Inner()
    maybe: float | None = None

    def __post_init__(self) -> None:
        if self.a < 0:
            raise ValueError("a must be >= 0")


def test_values_are_converted():
    d = from_dict(Demo, {"a": 2, "b": [1, 2], "inner": {"gain": 3}, "maybe": 4})
    assert d == Demo(a=2.0, b=(1.0, 2.0), inner=Inner(3.0), maybe=4.0)
    assert isinstance(d.a, float) and from_dict(Demo, None) == Demo()


@pytest.mark.parametrize(
    ("data", "where", "what"),
    [
        ({"z": 1}, "f.yaml: sensors.z", "unknown key; valid keys: a, b, inner, maybe, n, name, on"),
        ({"a": "q"}, "f.yaml: sensors.a", "expected a number"),
        ({"a": True}, "f.yaml: sensors.a", "expected a number"),
        ({"n": 1.5}, "f.yaml: sensors.n", "expected an integer"),
        ({"on": 1}, "f.yaml: sensors.on", "expected true or false"),
        ({"name": 3}, "f.yaml: sensors.name", "expected a string"),
        ({"b": [1]}, "f.yaml: sensors.b", "expected 2 values, got 1"),
        ({"inner": {"gian": 1}}, "f.yaml: sensors.inner.gian", "unknown key"),
        ({"a": -1}, "f.yaml: sensors", "a must be >= 0"),
        ([1, 2], "f.yaml: sensors", "expected a mapping"),
    ],
)
def test_errors_name_the_key(data, where, what):
    with pytest.raises(InputError) as info:
        from_dict(Demo, data, "sensors", "f.yaml")
    assert str(info.value).startswith(where) and what in str(info.value)


def test_from_spec_presets():
    presets = {"default": Demo(a=5.0), "fast": Demo(a=9.0, n=1)}
    assert from_spec(Demo, None, presets) == Demo(a=5.0)
    assert from_spec(Demo, None, {}) == Demo()
    assert from_spec(Demo, "fast", presets) == Demo(a=9.0, n=1)
    assert from_spec(Demo, {"preset": "fast", "n": 7}, presets) == Demo(a=9.0, n=7)
    assert from_spec(Demo, {"a": 2.0}, presets) == Demo(a=2.0)
    inst = Demo(a=4.0)
    assert from_spec(Demo, inst, presets) is inst
    with pytest.raises(InputError, match="unknown preset 'slow'; choose one of: default, fast"):
        from_spec(Demo, "slow", presets, "lidar")
    with pytest.raises(InputError, match=r"lidar\.preset: unknown preset"):
        from_spec(Demo, {"preset": "slow"}, presets, "lidar")


# --- values that cannot be right --------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        ({"a": float("nan")}, "f.yaml: sensors.a: must be finite, got nan"),
        ({"a": float("inf")}, "f.yaml: sensors.a: must be finite, got inf"),
        ({"a": -float("inf")}, "f.yaml: sensors.a: must be finite, got -inf"),
        (
            {"a": 10**400},
            "f.yaml: sensors.a: must be finite, got " + "1" + "0" * 56 + "...",
        ),
        ({"b": [0.0, float("nan")]}, "f.yaml: sensors.b[1]: must be finite, got nan"),
        ({"b": "ab"}, "f.yaml: sensors.b: expected a list, got 'ab'"),
        ({"maybe": float("nan")}, "f.yaml: sensors.maybe: must be finite, got nan"),
        ({"inner": 3}, "f.yaml: sensors.inner: must be a Inner or a mapping, got 3"),
        ({"inner": {"gain": float("inf")}}, "f.yaml: sensors.inner.gain: must be finite, got inf"),
        ({"far": float("nan")}, "f.yaml: sensors.far: must be finite or inf, got nan"),
        ({"far": -float("inf")}, "f.yaml: sensors.far: must be finite or inf, got -inf"),
        ({"n": np.float64(2.0)}, "f.yaml: sensors.n: expected an integer, got np.float64(2.0)"),
        ({"on": np.int64(1)}, "f.yaml: sensors.on: expected true or false, got np.int64(1)"),
    ],
)
def test_values_that_cannot_be_right(data, expected):
    with pytest.raises(InputError) as info:
        from_dict(Wide, data, "sensors", "f.yaml")
    assert str(info.value) == expected


@dataclass(frozen=True)
class Wide(Demo):
    far: float = field(default=1.0, metadata={"infinite": True})


def test_numpy_scalars_and_declared_infinity_are_fine():
    d = from_dict(Wide, {"a": np.float32(0.5), "n": np.int64(4), "on": np.bool_(True),
                         "far": float("inf")})  # fmt: skip
    assert (d.a, d.n, d.on, d.far) == (0.5, 4, True, math.inf)
    assert type(d.a) is float and type(d.n) is int and type(d.on) is bool
    assert from_dict(Demo, {"inner": Inner(2.0)}).inner == Inner(2.0)


def test_documented_infinite_fields_accept_inf():
    from srpb_gym.perception.detector import DetectorConfig
    from srpb_gym.perception.tracker import TrackerConfig

    assert DetectorConfig.from_spec({"range_max": math.inf}).range_max == math.inf
    assert TrackerConfig.from_spec({"max_distance": math.inf}).max_distance == math.inf
    with pytest.raises(InputError, match=r"^detector\.fov: must be finite, got inf$"):
        DetectorConfig.from_spec({"fov": math.inf}, "detector")


def test_spec_of_the_wrong_kind_names_the_key():
    presets = {"default": Demo(a=5.0), "fast": Demo(a=9.0)}
    with pytest.raises(InputError) as info:
        from_spec(Demo, [1, 2], presets, "lidar", "f.yaml")
    assert str(info.value) == (
        "f.yaml: lidar: expected a preset name (default, fast) or a mapping, got [1, 2]"
    )


# --- reward weights --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("weights", "expected"),
    [
        ([1, 2], "reward_weights: expected a mapping of term names to weights, got [1, 2]"),
        ({"time": float("nan")}, "reward_weights.time: expected a finite number, got nan"),
        (
            {"time": 10**400},
            "reward_weights.time: expected a finite number, got " + "1" + "0" * 400,
        ),
        ({"time": True}, "reward_weights.time: expected a finite number, got True"),
        (
            {"speed": 1.0},
            "reward_weights.speed: unknown reward term; valid terms: " + ", ".join(TERMS),
        ),
    ],
)
def test_check_weights_refusals(weights, expected):
    with pytest.raises(InputError) as info:
        check_weights(weights)
    assert str(info.value) == expected and info.value.key.startswith("reward_weights")


def test_check_weights_and_presets():
    assert check_weights({"time": np.float32(-0.5), "obs": 2}) == {"time": -0.5, "obs": 2.0}
    assert load_preset("task") == {"progress": 1.0, "success": 10.0, "collision": -25.0,
                                   "time": -0.1}  # fmt: skip
    with pytest.raises(InputError, match=r"^reward: unknown reward preset 'fast'"):
        load_preset("fast")


# --- through gym.make --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({"robot": {"radius": float("nan")}}, "robot.radius: must be finite, got nan"),
        ({"robot": {"v_max": float("inf")}}, "robot.v_max: must be finite, got inf"),
        ({"sim": [1, 2]}, "sim: expected a preset name (default) or a mapping, got [1, 2]"),
        ({"crowd": {"wall_range": float("nan")}}, "crowd.wall_range: must be finite, got nan"),
        (
            {"sensors": {"lidar": {"range_max": float("inf")}}},
            "sensors.lidar.range_max: must be finite, got inf",
        ),
        (
            {"reward_weights": [1, 2]},
            "reward_weights: expected a mapping of term names to weights, got [1, 2]",
        ),
        ({"observation": {"lidar_bins": 1000}}, "observation.lidar_bins: "),
        (
            {"observation": {"goal_scale": float("nan")}},
            "observation.goal_scale: must be finite, got nan",
        ),
    ],
)
def test_gym_make_refuses_bad_settings(kwargs, expected):
    with pytest.raises(InputError) as info:
        gym.make("SRPB-Corridor-v0", **kwargs)
    assert str(info.value).startswith(expected), str(info.value)
