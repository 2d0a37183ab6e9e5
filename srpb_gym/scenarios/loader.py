"""Reading scenario files: YAML with line numbers, strict typed parsing, packaged scenarios.

``load_scenario("corridor")`` loads the packaged ``corridor.yaml``; a path loads that file.
Every key is checked: an unknown key, a value of the wrong type or out of range raises
:class:`~srpb_gym.errors.InputError` as ``file:line: dotted.key: what is wrong``. The loaded
scenario is then checked geometrically by :func:`~srpb_gym.scenarios.validate.validate`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from srpb_gym.errors import InputError
from srpb_gym.resources import scenarios_dir
from srpb_gym.scenarios.schema import (
    DEFAULT_ROBOT_RADIUS,
    MAX_FORMATION_MEMBERS,
    MAX_GROUP_SIZE,
    MIN_FORMATION_MEMBERS,
    FormationSpec,
    IntRange,
    Place,
    Point,
    PoseSpec,
    Range,
    RobotSpec,
    Scenario,
    SensorSpecs,
    WalkerEntry,
    WalkerParams,
    YawSpec,
    checked_robot_radius,
    located_error,
)
from srpb_gym.scenarios.space import polygon_area, rectangle_corners, ring_segments
from srpb_gym.scenarios.validate import validate

SUFFIXES = (".yaml", ".yml")
TOP_KEYS = (
    "name", "description", "time_limit", "bounds", "enclose", "walls", "obstacles", "robot",
    "people", "formations", "sensors",
)  # fmt: skip
COMMON_PEOPLE_KEYS = (
    "count", "start_delay", "loop", "group_size", "preferred_speed", "radius", "relaxation_time",
    "robot_reaction",
)  # fmt: skip
ROUTE_KEYS = ("route", "spacing", "headway", "waypoint_jitter", *COMMON_PEOPLE_KEYS)
SPAWN_KEYS = ("spawn", "goal", "via", *COMMON_PEOPLE_KEYS)
FORMATION_KEYS = (
    "center", "members", "radius", "orientation", "orientation_deg", "jitter", "body_radius",
)  # fmt: skip


# --- finding files ---------------------------------------------------------------------


def list_scenarios() -> list[str]:
    """The names of the packaged scenarios, sorted."""
    folder = scenarios_dir()
    if not folder.is_dir():
        return []
    names = (entry.name for entry in folder.iterdir() if entry.is_file())
    return sorted(name.rsplit(".", 1)[0] for name in names if name.endswith(SUFFIXES))


def _resolve(path_or_name: str | os.PathLike[str]) -> Any:
    """The file at a path, else the packaged file for a bare name (``"corridor"`` or
    ``"corridor.yaml"``)."""
    text = os.fspath(path_or_name)
    if Path(text).is_file():
        return Path(text)
    if os.sep in text or "/" in text:
        raise InputError("no such scenario file", text)
    folder = scenarios_dir()
    stem = text.rsplit(".", 1)[0] if text.endswith(SUFFIXES) else text
    for suffix in SUFFIXES:
        if (folder / f"{stem}{suffix}").is_file():
            return folder / f"{stem}{suffix}"
    names = ", ".join(list_scenarios()) or "none found"
    raise InputError(f"unknown scenario {text!r}; packaged scenarios: {names}")


def load_scenario(
    path_or_name: str | os.PathLike[str], robot_radius: float = DEFAULT_ROBOT_RADIUS
) -> Scenario:
    """Load, check and prepare a scenario (a YAML file or a packaged scenario's name) for a
    robot of ``robot_radius`` [m], which ``scenario.robot_radius`` keeps for sampling."""
    source = _resolve(path_or_name)
    text = source.read_text(encoding="utf-8")
    return validate(parse_scenario(text, str(source), robot_radius=robot_radius))


# --- YAML with line numbers --------------------------------------------------------------


def read_yaml(text: str, file: str | None = None) -> tuple[Any, dict[str, int]]:
    """Plain data from YAML text and the 1-based line of every dotted key in it."""
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = None if mark is None else mark.line + 1
        raise InputError(f"invalid YAML: {exc.problem or exc}", file, line=line) from None
    if root is None:
        raise InputError("the scenario file is empty", file)
    lines: dict[str, int] = {}
    data = _node_data(root, "", lines, yaml.constructor.SafeConstructor(), file)
    return data, lines


def _node_data(node: yaml.Node, key: str, lines: dict[str, int], cons: Any, file: Any) -> Any:
    lines.setdefault(key, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        cons.flatten_mapping(node)
        out: dict[str, Any] = {}
        for key_node, value_node in node.value:
            name = cons.construct_object(key_node, deep=True)
            line = key_node.start_mark.line + 1
            if not isinstance(name, str):
                raise InputError(f"{key or 'top level'}: keys must be strings", file, line=line)
            dotted = f"{key}.{name}" if key else name
            if name in out:
                raise InputError(f"{dotted}: duplicate key", file, line=line, key=dotted)
            lines[dotted] = line
            out[name] = _node_data(value_node, dotted, lines, cons, file)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [
            _node_data(item, f"{key}[{i}]", lines, cons, file) for i, item in enumerate(node.value)
        ]
    return cons.construct_object(node, deep=True)


# --- typed values ------------------------------------------------------------------------


def _describe(value: Any) -> str:
    kind = {dict: "a mapping", list: "a list", str: "a string", bool: "a boolean"}
    text = repr(value)
    text = text if len(text) <= 40 else text[:37] + "..."
    return f"{kind.get(type(value), type(value).__name__)} {text}"


class _Reader:
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
            raise self.error(key, f"expected a mapping, got {_describe(value)}")
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
        self, value: Any, key: str, low: float | None = None, positive: bool = False
    ) -> float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if not (ok and math.isfinite(value)):
            raise self.error(key, f"expected a number, got {_describe(value)}")
        if positive and value <= 0:
            raise self.error(key, f"must be > 0, got {value}")
        if low is not None and value < low:
            raise self.error(key, f"must be >= {low}, got {value}")
        return float(value)

    def integer(self, value: Any, key: str, low: int, high: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected an integer, got {_describe(value)}")
        if value < low or (high is not None and value > high):
            bounds = f"{low} to {high}" if high is not None else f">= {low}"
            raise self.error(key, f"must be {bounds}, got {value}")
        return value

    def boolean(self, value: Any, key: str) -> bool:
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {_describe(value)}")
        return value

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str):
            raise self.error(key, f"expected a string, got {_describe(value)}")
        return value

    def numbers(self, value: Any, key: str, sizes: tuple[int, ...]) -> tuple[float, ...]:
        if not isinstance(value, (list, tuple)) or len(value) not in sizes:
            want = " or ".join(str(n) for n in sizes)
            raise self.error(key, f"expected a list of {want} numbers, got {_describe(value)}")
        return tuple(self.number(v, f"{key}[{i}]") for i, v in enumerate(value))

    def range(
        self, value: Any, key: str, low: float | None = None, positive: bool = False
    ) -> Range:
        """A number (fixed) or ``[low, high]`` (uniform)."""
        if isinstance(value, (list, tuple)):
            lo, hi = self.numbers(value, key, (2,))
            if lo > hi:
                raise self.error(key, f"range [{lo}, {hi}] has low > high")
        else:
            lo = hi = self.number(value, key)
        self.number(lo, key, low, positive)
        return (lo, hi)

    def field_range(
        self, spec: dict, key: str, name: str, default: Range, positive: bool = False
    ) -> Range:
        """``spec[name]`` as a range (>= 0, or > 0 with ``positive``), else ``default``."""
        low = None if positive else 0.0
        return self.range(spec.get(name, default), f"{key}.{name}", low, positive)

    def int_range(self, value: Any, key: str, low: int, high: int | None = None) -> IntRange:
        """An integer (fixed) or ``[low, high]`` (uniform, inclusive)."""
        if not isinstance(value, (list, tuple)):
            n = self.integer(value, key, low, high)
            return (n, n)
        if len(value) != 2:
            raise self.error(key, f"expected an integer or [low, high], got {_describe(value)}")
        lo, hi = (self.integer(v, f"{key}[{i}]", low, high) for i, v in enumerate(value))
        if lo > hi:
            raise self.error(key, f"range [{lo}, {hi}] has low > high")
        return (lo, hi)

    def point(self, value: Any, key: str) -> Point:
        x, y = self.numbers(value, key, (2,))
        return (x, y)

    def points(self, value: Any, key: str, at_least: int) -> tuple[Point, ...]:
        if not isinstance(value, list) or len(value) < at_least:
            raise self.error(key, f"expected a list of at least {at_least} points [x, y]")
        return tuple(self.point(v, f"{key}[{i}]") for i, v in enumerate(value))

    def rect(self, value: Any, key: str) -> tuple[float, float, float, float]:
        xmin, ymin, xmax, ymax = self.numbers(value, key, (4,))
        if xmin >= xmax or ymin >= ymax:
            raise self.error(key, "expected [xmin, ymin, xmax, ymax] with xmin < xmax, ymin < ymax")
        return (xmin, ymin, xmax, ymax)

    def place(self, value: Any, key: str) -> Place:
        """A point ``[x, y]`` or a rectangle ``[xmin, ymin, xmax, ymax]``."""
        if isinstance(value, list) and len(value) == 2:
            return Place.point(*self.point(value, key))
        if isinstance(value, list) and len(value) == 4:
            return Place(*self.rect(value, key))
        raise self.error(
            key, f"expected [x, y] or [xmin, ymin, xmax, ymax], got {_describe(value)}"
        )

    def angle(self, data: dict, key: str, name: str, default: Range) -> Range:
        """An angle range given as ``name`` [rad] or ``name_deg`` [deg], not both."""
        if name in data and f"{name}_deg" in data:
            raise self.error(f"{key}.{name}_deg", f"give either {name} or {name}_deg, not both")
        if f"{name}_deg" in data:
            lo, hi = self.range(data[f"{name}_deg"], f"{key}.{name}_deg")
            return (math.radians(lo), math.radians(hi))
        if name in data:
            return self.range(data[name], f"{key}.{name}")
        return default


# --- sections ------------------------------------------------------------------------------


def parse_scenario(
    text: str, file: str | None = None, default_name: str | None = None,
    *, robot_radius: float = DEFAULT_ROBOT_RADIUS,
) -> Scenario:  # fmt: skip
    """A :class:`Scenario` for a robot of ``robot_radius`` [m] from YAML text (types and
    ranges checked, geometry not yet: see :func:`~srpb_gym.scenarios.validate.validate`).

    ``default_name`` (default: the file's name without suffix) names a file without ``name``.
    """
    robot_radius = checked_robot_radius(robot_radius, file)
    if default_name is None:
        default_name = Path(file).name.rsplit(".", 1)[0] if file else "scenario"
    data, lines = read_yaml(text, file)
    r = _Reader(file, lines)
    top = r.mapping(data, "", TOP_KEYS, required=("bounds", "robot"))
    bounds = r.rect(top["bounds"], "bounds")
    segments, polygons = _walls(r, top.get("walls", [])), _obstacles(r, top.get("obstacles", []))
    for poly in polygons:
        segments.extend(ring_segments(poly))
    if r.boolean(top.get("enclose", True), "enclose"):
        xmin, ymin, xmax, ymax = bounds
        segments.extend(ring_segments([(xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)]))
    walls = np.array(segments, dtype=np.float64).reshape(-1, 4)
    walls.setflags(write=False)
    time_limit = r.number(top.get("time_limit", 60.0), "time_limit", positive=True)
    return Scenario(
        name=r.string(top.get("name", default_name), "name"),
        description=r.string(top.get("description", ""), "description").strip(),
        time_limit=time_limit,
        bounds=bounds,
        walls=walls,
        obstacles=tuple(np.array(p, dtype=np.float64) for p in polygons),
        robot=_robot(r, top["robot"]),
        people=tuple(_people(r, top.get("people", []))),
        formations=tuple(_formations(r, top.get("formations", []))),
        sensors=_sensors(r, top.get("sensors", {})),
        robot_radius=robot_radius,
        source=file,
        lines=lines,
    )


def _list(r: _Reader, value: Any, key: str) -> list[Any]:
    if not isinstance(value, list):
        raise r.error(key, f"expected a list, got {_describe(value)}")
    return value


def _walls(r: _Reader, value: Any) -> list[tuple[float, ...]]:
    segments: list[tuple[float, ...]] = []
    for i, item in enumerate(_list(r, value, "walls")):
        key = f"walls[{i}]"
        if isinstance(item, list):
            segments.append(r.numbers(item, key, (4,)))
            continue
        spec = r.mapping(item, key, ("polyline", "closed"), required=("polyline",))
        points = r.points(spec["polyline"], f"{key}.polyline", 2)
        chain = ring_segments(points)
        segments.extend(
            chain if r.boolean(spec.get("closed", False), f"{key}.closed") else chain[1:]
        )
    return segments


def _obstacles(r: _Reader, value: Any) -> list[tuple[Point, ...]]:
    polygons = []
    for i, item in enumerate(_list(r, value, "obstacles")):
        key = f"obstacles[{i}]"
        spec = r.mapping(item, key, ("polygon", "rectangle"))
        if len(spec) != 1:
            raise r.error(key, "give exactly one of 'polygon' or 'rectangle'")
        if "polygon" in spec:
            poly = r.points(spec["polygon"], f"{key}.polygon", 3)
            if abs(polygon_area(poly)) < 1e-9:
                raise r.error(f"{key}.polygon", "the polygon has no area")
        else:
            poly = _rectangle(r, spec["rectangle"], f"{key}.rectangle")
        polygons.append(poly)
    return polygons


def _rectangle(r: _Reader, value: Any, key: str) -> tuple[Point, ...]:
    """An axis-aligned ``[xmin, ymin, xmax, ymax]`` or ``{center, size, yaw|yaw_deg}``."""
    if isinstance(value, list):
        xmin, ymin, xmax, ymax = r.rect(value, key)
        return ((xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax))
    spec = r.mapping(value, key, ("center", "size", "yaw", "yaw_deg"), required=("center", "size"))
    cx, cy = r.point(spec["center"], f"{key}.center")
    w, h = (
        r.number(v, f"{key}.size", positive=True)
        for v in r.numbers(spec["size"], f"{key}.size", (2,))
    )
    yaw_lo, yaw_hi = r.angle(spec, key, "yaw", (0.0, 0.0))
    if yaw_lo != yaw_hi:
        raise r.error(f"{key}.yaw", "a rectangle's yaw must be a single number")
    return rectangle_corners((cx, cy), (w, h), yaw_lo)


def _robot(r: _Reader, value: Any) -> RobotSpec:
    spec = r.mapping(
        value, "robot", ("start", "goal", "goal_tolerance"), required=("start", "goal")
    )
    tolerance = r.number(spec.get("goal_tolerance", 0.2), "robot.goal_tolerance", positive=True)
    return RobotSpec(
        _pose(r, spec["start"], "robot.start"), _pose(r, spec["goal"], "robot.goal"), tolerance
    )


def _pose(r: _Reader, value: Any, key: str) -> PoseSpec:
    spec = r.mapping(value, key, ("position", "yaw", "yaw_deg"), required=("position",))
    place = r.place(spec["position"], f"{key}.position")
    yaw = spec.get("yaw")
    if isinstance(yaw, str) and yaw != "towards_goal":
        raise r.error(f"{key}.yaw", f"expected a number, [low, high] or towards_goal, got {yaw!r}")
    if yaw == "towards_goal" and "yaw_deg" not in spec:
        return PoseSpec(place, YawSpec(towards_goal=True))
    if "yaw" not in spec and "yaw_deg" not in spec:
        return PoseSpec(place, YawSpec(towards_goal=True))
    return PoseSpec(place, YawSpec(towards_goal=False, range=r.angle(spec, key, "yaw", (0.0, 0.0))))


def _params(r: _Reader, spec: dict, key: str) -> WalkerParams:
    d = WalkerParams()
    return WalkerParams(
        preferred_speed=r.field_range(spec, key, "preferred_speed", d.preferred_speed, True),
        radius=r.field_range(spec, key, "radius", d.radius, True),
        relaxation_time=r.field_range(spec, key, "relaxation_time", d.relaxation_time, True),
        robot_reaction=r.field_range(spec, key, "robot_reaction", d.robot_reaction),
    )


def _people(r: _Reader, value: Any) -> list[WalkerEntry]:
    entries = []
    for i, item in enumerate(_list(r, value, "people")):
        key = f"people[{i}]"
        if isinstance(item, dict) and ("route" in item) == ("spawn" in item):
            raise r.error(key, "give exactly one of 'route' (fixed path) or 'spawn' (random start)")
        spec = r.mapping(
            item, key, ROUTE_KEYS if isinstance(item, dict) and "route" in item else SPAWN_KEYS
        )
        if "spawn" in spec and "goal" not in spec:
            raise r.error(key, "a spawn entry needs a 'goal' place")
        common = {
            "index": i,
            "count": r.int_range(spec.get("count", 1), f"{key}.count", 0),
            "start_delay": r.field_range(spec, key, "start_delay", (0.0, 0.0)),
            "loop": r.boolean(spec.get("loop", False), f"{key}.loop"),
            "group_size": r.int_range(
                spec.get("group_size", 1), f"{key}.group_size", 1, MAX_GROUP_SIZE
            ),
            "params": _params(r, spec, key),
        }
        entries.append(
            _route(r, spec, key, common) if "route" in spec else _spawn(r, spec, key, common)
        )
    return entries


def _route(r: _Reader, spec: dict, key: str, common: dict[str, Any]) -> WalkerEntry:
    jitter = r.number(spec.get("waypoint_jitter", 0.0), f"{key}.waypoint_jitter", low=0.0)
    return WalkerEntry(
        route=r.points(spec["route"], f"{key}.route", 2),
        spacing=r.field_range(spec, key, "spacing", (1.0, 1.0)),
        headway=r.field_range(spec, key, "headway", (0.0, 0.0)),
        waypoint_jitter=jitter,
        **common,
    )


def _spawn(r: _Reader, spec: dict, key: str, common: dict[str, Any]) -> WalkerEntry:
    return WalkerEntry(
        spawn=r.place(spec["spawn"], f"{key}.spawn"),
        goal=r.place(spec["goal"], f"{key}.goal"),
        via=r.points(spec["via"], f"{key}.via", 1) if "via" in spec else (),
        **common,
    )


def _formations(r: _Reader, value: Any) -> list[FormationSpec]:
    out = []
    for i, item in enumerate(_list(r, value, "formations")):
        key = f"formations[{i}]"
        spec = r.mapping(item, key, FORMATION_KEYS, required=("center",))
        default = FormationSpec(index=i, center=Place.point(0.0, 0.0))
        members = r.int_range(spec.get("members", 2), f"{key}.members", 0)
        if members[0] < MIN_FORMATION_MEMBERS or members[1] > MAX_FORMATION_MEMBERS:
            raise r.error(
                f"{key}.members",
                f"an F-formation has {MIN_FORMATION_MEMBERS} to {MAX_FORMATION_MEMBERS} members, "
                f"got {members[0]}..{members[1]}",
            )
        out.append(
            FormationSpec(
                index=i,
                center=r.place(spec["center"], f"{key}.center"),
                members=members,
                radius=r.field_range(spec, key, "radius", default.radius, True),
                orientation=r.angle(spec, key, "orientation", default.orientation),
                jitter=r.number(spec.get("jitter", default.jitter), f"{key}.jitter", low=0.0),
                body_radius=r.field_range(spec, key, "body_radius", default.body_radius, True),
            )
        )
    return out


def _sensors(r: _Reader, value: Any) -> SensorSpecs:
    spec = r.mapping(
        value if value is not None else {}, "sensors", ("lidar", "detector", "tracker")
    )
    raw = {}
    for name, item in spec.items():
        if item is not None and not isinstance(item, (str, dict)):
            raise r.error(
                f"sensors.{name}", f"expected a preset name or a mapping, got {_describe(item)}"
            )
        raw[name] = item
    return SensorSpecs(**raw)
