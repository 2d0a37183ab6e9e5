"""Planner settings: frozen dataclasses built strictly from plain data, and read from text.

Every planner, and each part of one (its global planner, its recovery behaviour), has a
frozen ``...Config`` dataclass with documented fields, checked when it is built. Build one
with ``XConfig.from_spec(spec, path)``, where ``spec`` is ``None`` (the defaults), an
instance, or a mapping of the fields to change. A mapping given for a nested config changes
only the fields it names, on top of the owner's nested defaults: for the social DWA,
``{"global_planner": {"spacing": 0.2}}`` keeps the other settings of its global planner
(which differ from a standalone global planner's). An unknown key, a value of the wrong type
or out of range raises :class:`~srpb_gym.errors.InputError` naming the dotted key, e.g.
``planner.dwa.horizon: must be a finite number > 0, got -1.0``.

Settings as text (``srpb-gym eval``, ``scripts/tune_planners.py``) are
``{planner name: {field: value}}`` mappings: from a YAML file (:func:`load_settings`) and
``NAME.FIELD=VALUE`` assignments (:func:`parse_assignments`), merged by
:func:`planner_settings`. Values are parsed as Python or YAML literals, never evaluated.
"""

from __future__ import annotations

import ast
import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar

import yaml

from srpb_gym.config import checked_kwargs
from srpb_gym.errors import InputError

__all__ = [
    "PlannerConfig",
    "SettingError",
    "build_config",
    "load_settings",
    "merge_settings",
    "parse_assignments",
    "parse_value",
    "planner_settings",
]

C = TypeVar("C", bound="PlannerConfig")


class SettingError(ValueError):
    """A setting's value is out of range; ``field`` names it, ``message`` says why."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field} {message}")
        self.field, self.message = field, message


class PlannerConfig:
    """Base of the planner config dataclasses: construction from plain data and range
    checks for ``__post_init__``."""

    @classmethod
    def from_spec(
        cls: type[C], spec: C | Mapping[str, Any] | None, path: str = "", file: str | None = None
    ) -> C:
        """A config from ``None`` (the defaults), an instance, or a mapping of the fields to
        change (see :func:`build_config`); errors name ``path.<field>``."""
        return build_config(cls, spec, path, file)

    # ---------------------------------------------------------------- checks
    def _number(self, name: str) -> float:
        value = getattr(self, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SettingError(name, f"must be a number, got {value!r}")
        if not math.isfinite(value):
            raise SettingError(name, f"must be finite, got {value!r}")
        return float(value)

    def _positive(self, *names: str) -> None:
        """Each named field is a finite number > 0."""
        for name in names:
            if not self._number(name) > 0.0:
                raise SettingError(
                    name, f"must be a finite number > 0, got {getattr(self, name)!r}"
                )

    def _nonnegative(self, *names: str) -> None:
        """Each named field is a finite number >= 0."""
        for name in names:
            if not self._number(name) >= 0.0:
                raise SettingError(
                    name, f"must be a finite number >= 0, got {getattr(self, name)!r}"
                )

    def _within(self, name: str, low: float, high: float) -> None:
        """The named field is a number in [low, high]."""
        if not low <= self._number(name) <= high:
            raise SettingError(name, f"must be in [{low}, {high}], got {getattr(self, name)!r}")

    def _count(self, name: str, least: int) -> None:
        """The named field is an integer >= ``least``."""
        value = getattr(self, name)
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise SettingError(name, f"must be an integer >= {least}, got {value!r}")

    def _nested(self, name: str, cls: type) -> None:
        """The named field is an instance of ``cls``."""
        value = getattr(self, name)
        if not isinstance(value, cls):
            raise SettingError(name, f"must be a {cls.__name__} or a mapping, got {value!r}")


def build_config(
    cls: type[C], spec: C | Mapping[str, Any] | None, path: str = "", file: str | None = None,
    base: C | None = None,
) -> C:  # fmt: skip
    """``base`` (default ``cls()``) with the fields named in the mapping ``spec`` replaced.

    ``spec`` may also be ``None`` (``base``) or an instance of ``cls`` (itself). A mapping
    value of a nested config field changes that config the same way, on top of ``base``'s
    nested value. Keys and value types are checked with :func:`srpb_gym.config.checked_kwargs`
    and ranges by the dataclass; every error is an :class:`InputError` naming the dotted key
    under ``path`` (and ``file`` when given).
    """
    if isinstance(spec, cls):
        return spec
    base = cls() if base is None else base
    if spec is None:
        return base
    if not isinstance(spec, Mapping):
        raise InputError(f"expected a mapping of settings, got {spec!r}", file, key=path or None)
    nested, flat = {}, {}
    for key, value in spec.items():
        current = getattr(base, key, None) if isinstance(key, str) else None
        if isinstance(value, Mapping) and isinstance(current, PlannerConfig):
            nested[key] = build_config(type(current), value, _join(path, key), file, current)
        else:
            flat[key] = value
    kwargs = checked_kwargs(cls, flat, path, file) | nested
    try:
        return dataclasses.replace(base, **kwargs)  # type: ignore[type-var]
    except SettingError as exc:
        raise InputError(exc.message, file, key=_join(path, exc.field)) from None
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), file, key=path or None) from None


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


# -------------------------------------------------------------------- settings as text
def parse_value(text: str) -> Any:
    """A value from text: a Python literal (``2.0``, ``1e-3``, ``[1, 2]``, ``None``,
    ``True``), else a YAML scalar or flow collection (``true``, ``null``, ``{a: 1}``), else
    the text itself. Nothing is evaluated."""
    text = text.strip()
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        pass
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def parse_assignments(items: Sequence[str], option: str = "--planner-param") -> dict[str, Any]:
    """``NAME.FIELD=VALUE`` items as a nested mapping, ``{NAME: {FIELD: VALUE}}``.

    ``FIELD`` may be dotted for a nested config (``dwa.global_planner.spacing=0.2``); values
    are read by :func:`parse_value`. Raises :class:`InputError` (key ``option``) for an item
    without ``=`` or without a planner name and a field.
    """
    out: dict[str, Any] = {}
    for item in items:
        dotted, sep, text = item.partition("=")
        keys = [k.strip() for k in dotted.split(".")]
        if not sep or len(keys) < 2 or not all(keys):
            raise InputError(f"expected PLANNER.FIELD=VALUE, got {item!r}", key=option)
        node = out
        for depth, key in enumerate(keys[:-1]):
            child = node.setdefault(key, {})
            if not isinstance(child, dict):
                where = ".".join(keys[: depth + 1])
                raise InputError(f"{where} is set to a value and to fields", key=option)
            node = child
        if isinstance(node.get(keys[-1]), dict):
            raise InputError(f"{dotted.strip()} is set to a value and to fields", key=option)
        node[keys[-1]] = parse_value(text)
    return out


def load_settings(path: str | os.PathLike[str], option: str = "--planner-config") -> dict[str, Any]:
    """The planner settings of a YAML file: a mapping of planner names to mappings of
    settings (an empty file: none). Raises :class:`InputError` for a missing, unreadable or
    malformed file."""
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except OSError as exc:
        raise InputError(f"cannot read the file: {exc.strerror or exc}", path, key=option) from None
    except yaml.YAMLError as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        raise InputError(f"not valid YAML: {getattr(exc, 'problem', None) or exc}", path,
                         None if line is None else line + 1) from None  # fmt: skip
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise InputError("expected a mapping of planner names to settings", path, key=option)
    for name, settings in data.items():
        if settings is not None and not isinstance(settings, Mapping):
            raise InputError(f"expected a mapping of settings, got {settings!r}", path,
                             key=str(name))  # fmt: skip
    return {str(name): dict(settings or {}) for name, settings in data.items()}


def merge_settings(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``over`` on top; mappings present in both are merged key by key."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge_settings(out[key], value)
        else:
            out[key] = value
    return out


def planner_settings(
    config_file: str | os.PathLike[str] | None = None, params: Sequence[str] = ()
) -> dict[str, dict[str, Any]]:
    """``{planner name: settings}`` of a ``--planner-config`` YAML file (or none) with the
    ``--planner-param NAME.FIELD=VALUE`` items on top. Names and fields are checked when the
    planners are built (:func:`srpb_gym.planners.make_planner`)."""
    settings = {} if config_file is None else load_settings(config_file)
    return merge_settings(settings, parse_assignments(params))
