"""Typed access to parsed scenario YAML: every value checked, every error located.

:class:`Reader` reads numbers, ranges, points, places and angles from the plain data of
:func:`~srpb_gym.yaml_io.read_yaml` and raises
:class:`~srpb_gym.errors.InputError` as ``file:line: dotted.key: what is wrong``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from typing import Any

from srpb_gym.errors import InputError
from srpb_gym.scenarios.schema import IntRange, Place, Point, Range, located_error

EXPONENT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")  # a number, if not quoted
MAX_COORDINATE = 1e6  # m, largest absolute coordinate


def describe(value: Any) -> str:
    """What ``value`` is, for an error message (with a hint for a quoted number like ``'1e-3'``)."""
    kind = {dict: "a mapping", list: "a list", str: "a string", bool: "a boolean"}
    text = repr(value)
    text = text if len(text) <= 40 else text[:37] + "..."
    hint = isinstance(value, str) and EXPONENT.fullmatch(value.strip()) is not None
    hint *= " (quoted, a number is text: leave out the quotes)"
    return f"{kind.get(type(value), type(value).__name__)} {text}{hint}"


class Reader:
    """Typed access to parsed YAML, raising located errors."""

    def __init__(self, file: str | None, lines: dict[str, int]) -> None:
        self.file = file
        self.lines = lines

    def error(self, key: str, message: str) -> InputError:
        return located_error(message, self.file, self.lines, key)

    def mapping(
        self, value: Any, key: str, allowed: Iterable[str], required: Iterable[str] = ()
    ) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.error(key, f"expected a mapping, got {describe(value)}")
        allowed = tuple(allowed)
        for name in value:
            if name not in allowed:
                where = f"{key}.{name}" if key else name
                raise self.error(where, f"unknown key; valid keys: {', '.join(allowed)}")
        for name in required:
            if name not in value:
                raise self.error(key, f"missing required key {name!r}")
        return value

    def number(
        self, value: Any, key: str, low: float | None = None, positive: bool = False,
        high: float | None = None,
    ) -> float:  # fmt: skip
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, f"expected a number, got {describe(value)}")
        number = float(value) if isinstance(value, float) or abs(value) < 2**1000 else math.inf
        if not math.isfinite(number):
            raise self.error(key, f"expected a finite number, got {describe(value)}")
        if positive and number <= 0:
            raise self.error(key, f"must be > 0, got {value}")
        if low is not None and number < low:
            raise self.error(key, f"must be >= {low}, got {value}")
        if high is not None and number > high:
            raise self.error(key, f"must be <= {high:g}, got {value}")
        return number

    def integer(self, value: Any, key: str, low: int, high: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected an integer, got {describe(value)}")
        if value < low or (high is not None and value > high):
            bounds = f"{low} to {high}" if high is not None else f">= {low}"
            raise self.error(key, f"must be {bounds}, got {value}")
        return value

    def boolean(self, value: Any, key: str) -> bool:
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {describe(value)}")
        return value

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str):
            raise self.error(key, f"expected a string, got {describe(value)}")
        return value

    def numbers(self, value: Any, key: str, sizes: tuple[int, ...]) -> tuple[float, ...]:
        if not isinstance(value, (list, tuple)) or len(value) not in sizes:
            want = " or ".join(str(n) for n in sizes)
            raise self.error(key, f"expected a list of {want} numbers, got {describe(value)}")
        return tuple(self.number(v, f"{key}[{i}]") for i, v in enumerate(value))

    def coordinates(self, value: Any, key: str, sizes: tuple[int, ...]) -> tuple[float, ...]:
        values = self.numbers(value, key, sizes)
        if max(map(abs, values)) > MAX_COORDINATE:
            shown = ", ".join(f"{v:g}" for v in values)
            raise self.error(key, f"coordinates must lie within +-{MAX_COORDINATE:g} m, got "
                             f"[{shown}]")  # fmt: skip
        return values

    def range(
        self, value: Any, key: str, low: float | None = None, positive: bool = False,
        high: float | None = None,
    ) -> Range:  # fmt: skip
        """A number (fixed) or ``[low, high]`` (uniform)."""
        if isinstance(value, (list, tuple)):
            lo, hi = self.numbers(value, key, (2,))
            if lo > hi:
                raise self.error(key, f"range [{lo}, {hi}] has low > high")
        else:
            lo = hi = self.number(value, key)
        self.number(lo, key, low, positive)
        self.number(hi, key, high=high)
        return (lo, hi)

    def field_range(
        self, spec: dict, key: str, name: str, default: Range, positive: bool = False,
        high: float | None = None,
    ) -> Range:  # fmt: skip
        """``spec[name]`` as a range (>= 0, or > 0 with ``positive``; <= ``high``), else
        ``default``."""
        low = None if positive else 0.0
        return self.range(spec.get(name, default), f"{key}.{name}", low, positive, high)

    def int_range(self, value: Any, key: str, low: int, high: int | None = None) -> IntRange:
        """An integer (fixed) or ``[low, high]`` (uniform, inclusive)."""
        if not isinstance(value, (list, tuple)):
            n = self.integer(value, key, low, high)
            return (n, n)
        if len(value) != 2:
            raise self.error(key, f"expected an integer or [low, high], got {describe(value)}")
        lo, hi = (self.integer(v, f"{key}[{i}]", low, high) for i, v in enumerate(value))
        if lo > hi:
            raise self.error(key, f"range [{lo}, {hi}] has low > high")
        return (lo, hi)

    def point(self, value: Any, key: str) -> Point:
        x, y = self.coordinates(value, key, (2,))
        return (x, y)

    def points(self, value: Any, key: str, at_least: int) -> tuple[Point, ...]:
        if not isinstance(value, list) or len(value) < at_least:
            raise self.error(key, f"expected a list of at least {at_least} points [x, y]")
        return tuple(self.point(v, f"{key}[{i}]") for i, v in enumerate(value))

    def rect(self, value: Any, key: str) -> tuple[float, float, float, float]:
        xmin, ymin, xmax, ymax = self.coordinates(value, key, (4,))
        if xmin >= xmax or ymin >= ymax:
            raise self.error(key, "expected [xmin, ymin, xmax, ymax] with xmin < xmax, ymin < ymax")
        return (xmin, ymin, xmax, ymax)

    def place(self, value: Any, key: str) -> Place:
        """A point ``[x, y]`` or a rectangle ``[xmin, ymin, xmax, ymax]``."""
        if isinstance(value, list) and len(value) == 2:
            return Place.point(*self.point(value, key))
        if isinstance(value, list) and len(value) == 4:
            return Place(*self.rect(value, key))
        raise self.error(key, f"expected [x, y] or [xmin, ymin, xmax, ymax], got {describe(value)}")

    def angle(self, data: dict, key: str, name: str, default: Range) -> Range:
        """An angle range given as ``name`` [rad] or ``name_deg`` [deg], not both."""
        if name in data and f"{name}_deg" in data:
            raise self.error(f"{key}.{name}_deg", f"give either {name} or {name}_deg, not both")
        deg = f"{name}_deg" in data
        if not deg and name not in data:
            return default
        field, turn = (f"{name}_deg", 360.0) if deg else (name, 2.0 * math.pi)
        lo, hi = self.range(data[field], f"{key}.{field}")
        if hi - lo > turn * (1.0 + 1e-12):
            raise self.error(
                f"{key}.{field}",
                f"the range [{lo:g}, {hi:g}] spans more "
                f"than a full turn ({turn:g}): some headings would be likelier",
            )
        return (math.radians(lo), math.radians(hi)) if deg else (lo, hi)
