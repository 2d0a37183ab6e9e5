"""Strict construction of frozen config dataclasses from plain data (YAML, JSON, kwargs).

``from_dict(LidarConfig, {"fov": 3.14}, path="sensors.lidar")`` builds the dataclass and
raises :class:`~srpb_gym.errors.InputError` naming the dotted key for an unknown key, a
value of the wrong type or a number that is not finite (NaN, inf). ``from_spec`` also
accepts the name of a preset.

A ``float`` field whose value may be ``inf`` says so in its metadata:
``range_max: float = field(default=8.0, metadata={"infinite": True})``.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import types
import typing
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar

import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.yaml_io import read_yaml

T = TypeVar("T")
#: ``module.Class.field`` of the float fields documented as possibly ``inf`` that do not yet
#: carry ``metadata={"infinite": True}``
INFINITE_FIELDS = frozenset({
    "srpb_gym.perception.detector.DetectorConfig.range_max",
    "srpb_gym.perception.tracker.TrackerConfig.max_distance",
})  # fmt: skip


def from_dict(
    cls: type[T], data: Mapping[str, Any] | None, path: str = "", file: str | None = None
) -> T:
    """``cls(**data)`` with every key checked; nested dataclass fields recurse."""
    return _build(cls, checked_kwargs(cls, data, path, file), path, file)


def from_spec(
    cls: type[T], spec: str | Mapping[str, Any] | T | None, presets: Mapping[str, T],
    path: str = "", file: str | None = None,
) -> T:  # fmt: skip
    """A config from a preset name, a mapping (optionally with ``preset: NAME`` as its base),
    an instance, or ``None`` (the ``"default"`` preset, else the class defaults)."""
    if isinstance(spec, cls):
        return spec
    if spec is None:
        return presets["default"] if "default" in presets else cls()  # type: ignore[call-arg]
    if not isinstance(spec, (str, Mapping)):
        choices = ", ".join(sorted(presets)) or "none"
        raise InputError(f"expected a preset name ({choices}) or a mapping, got {_short(spec)}",
                         file, key=path or None)  # fmt: skip
    if isinstance(spec, str):
        if spec not in presets:
            choices = ", ".join(sorted(presets))
            raise InputError(
                f"unknown preset {_short(spec)}; choose one of: {choices}", file, key=path or None
            )
        return presets[spec]
    if isinstance(spec, Mapping) and "preset" in spec:
        base = from_spec(cls, spec["preset"], presets, f"{path}.preset", file)
        rest = {k: v for k, v in spec.items() if k != "preset"}
        shallow = {f.name: getattr(base, f.name) for f in dataclasses.fields(base)}
        return _build(cls, shallow | checked_kwargs(cls, rest, path, file), path, file)
    return from_dict(cls, spec, path, file)


def checked_kwargs(
    cls: type, data: Mapping[str, Any] | None, path: str = "", file: str | None = None
) -> dict[str, Any]:
    """``data`` with every key checked against the fields of ``cls`` and values converted."""
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise InputError(f"expected a mapping, got {type(data).__name__} {_short(data)}", file,
                         key=path or None)  # fmt: skip
    fields = {f.name: f for f in dataclasses.fields(cls)}
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for key, value in data.items():
        dotted = f"{path}.{key}" if path else str(key)
        if key not in fields:
            raise InputError(
                f"unknown key; valid keys: {', '.join(sorted(fields))}", file, key=dotted
            )
        infinite = fields[key].metadata.get("infinite", False) or (
            f"{cls.__module__}.{cls.__qualname__}.{key}" in INFINITE_FIELDS
        )
        kwargs[key] = _convert(hints[key], value, dotted, file, infinite)
    return kwargs


def _short(value: Any) -> str:
    """``repr(value)``, cut to 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _build(cls: type[T], kwargs: dict[str, Any], path: str, file: str | None) -> T:
    try:
        return cls(**kwargs)
    except InputError:
        raise
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), file, key=path or None) from None


def _convert(hint: Any, value: Any, dotted: str, file: str | None, infinite: bool = False) -> Any:
    """``value`` checked against the type ``hint``; ``infinite``: a float may be ``inf``."""
    origin = typing.get_origin(hint)
    if dataclasses.is_dataclass(hint):
        if isinstance(value, Mapping):
            return from_dict(hint, value, dotted, file)
        if not isinstance(value, hint):
            raise InputError(f"must be a {hint.__name__} or a mapping, got {_short(value)}", file,
                             key=dotted)  # fmt: skip
        return value
    is_bool = isinstance(value, (bool, np.bool_))
    if hint is float:
        if is_bool or not isinstance(value, numbers.Real):
            raise InputError(f"expected a number, got {_short(value)}", file, key=dotted)
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        if not (math.isfinite(number) or (infinite and number == math.inf)):
            raise InputError(f"must be finite{' or inf' * infinite}, got {_short(value)}",
                             file, key=dotted)  # fmt: skip
        return number
    if hint is int:
        if is_bool or not isinstance(value, numbers.Integral):
            raise InputError(f"expected an integer, got {_short(value)}", file, key=dotted)
        return int(value)
    if hint is bool:
        if not is_bool:
            raise InputError(f"expected true or false, got {_short(value)}", file, key=dotted)
        return bool(value)
    if hint is str:
        if not isinstance(value, str):
            raise InputError(f"expected a string, got {_short(value)}", file, key=dotted)
        return value
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise InputError(f"expected a list, got {_short(value)}", file, key=dotted)
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(
                _convert(args[0], v, f"{dotted}[{i}]", file, infinite) for i, v in enumerate(value)
            )
        if len(args) != len(value):
            raise InputError(f"expected {len(args)} values, got {len(value)}", file, key=dotted)
        return tuple(
            _convert(a, v, f"{dotted}[{i}]", file, infinite)
            for i, (a, v) in enumerate(zip(args, value))
        )
    if origin is dict:
        if not isinstance(value, Mapping):
            raise InputError(f"expected a mapping, got {_short(value)}", file, key=dotted)
        key_hint, value_hint = typing.get_args(hint)
        return {
            _convert(key_hint, k, dotted, file): _convert(value_hint, v, f"{dotted}.{k}", file,
                                                          infinite)
            for k, v in value.items()
        }  # fmt: skip
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(hint)
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, dotted, file, infinite)
            except InputError as exc:
                errors.append(exc)
        if len(errors) == 1:  # X | None: say what X needs
            raise errors[0]
        raise InputError(f"value {_short(value)} does not fit {hint}", file, key=dotted)
    return value


def parse_overrides(items: Sequence[str], option: str = "--hyperparams") -> dict[str, Any]:
    """``["n_steps=1024", "net_arch=[64, 64]"]`` -> ``{"n_steps": 1024, "net_arch": [64, 64]}``
    (values read as YAML by the safe reader: plain data only)."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise InputError(f"expected KEY=VALUE, got {item!r}", key=option)
        try:
            value, _ = read_yaml(text, f"{option} {key}")
        except InputError as exc:
            raise InputError(exc.message, key=f"{option}: {key}") from None
        out[key] = value
    return out
