"""Strict construction of config dataclasses from plain data."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from srpb_gym.config import from_dict, from_spec
from srpb_gym.errors import InputError


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
