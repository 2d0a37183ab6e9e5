"""Strict construction of frozen config dataclasses from plain data (YAML, JSON, kwargs).

``from_dict(LidarConfig, {"fov": 3.14}, path="sensors.lidar")`` builds the dataclass and
raises :class:`~srpb_gym.errors.InputError` naming the dotted key for an unknown key or a
value of the wrong type. ``from_spec`` also accepts the name of a preset.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from typing import Any, TypeVar

from srpb_gym.errors import InputError

T = TypeVar("T")


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
    if isinstance(spec, str):
        if spec not in presets:
            choices = ", ".join(sorted(presets))
            raise InputError(
                f"unknown preset {spec!r}; choose one of: {choices}", file, key=path or None
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
        raise InputError(f"expected a mapping, got {type(data).__name__}", file, key=path or None)
    fields = {f.name for f in dataclasses.fields(cls)}
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for key, value in data.items():
        dotted = f"{path}.{key}" if path else str(key)
        if key not in fields:
            raise InputError(
                f"unknown key; valid keys: {', '.join(sorted(fields))}", file, key=dotted
            )
        kwargs[key] = _convert(hints[key], value, dotted, file)
    return kwargs


def _build(cls: type[T], kwargs: dict[str, Any], path: str, file: str | None) -> T:
    try:
        return cls(**kwargs)
    except InputError:
        raise
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), file, key=path or None) from None


def _convert(hint: Any, value: Any, dotted: str, file: str | None) -> Any:
    origin = typing.get_origin(hint)
    if dataclasses.is_dataclass(hint) and isinstance(value, Mapping):
        return from_dict(hint, value, dotted, file)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"expected a number, got {value!r}", file, key=dotted)
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(f"expected an integer, got {value!r}", file, key=dotted)
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise InputError(f"expected true or false, got {value!r}", file, key=dotted)
        return value
    if hint is str:
        if not isinstance(value, str):
            raise InputError(f"expected a string, got {value!r}", file, key=dotted)
        return value
    if origin is tuple and isinstance(value, (list, tuple)):
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{dotted}[{i}]", file) for i, v in enumerate(value))
        if len(args) != len(value):
            raise InputError(f"expected {len(args)} values, got {len(value)}", file, key=dotted)
        return tuple(
            _convert(a, v, f"{dotted}[{i}]", file) for i, (a, v) in enumerate(zip(args, value))
        )
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(hint)
        if value is None and type(None) in args:
            return None
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, dotted, file)
            except InputError:
                continue
        raise InputError(f"value {value!r} does not fit {hint}", file, key=dotted)
    return value
