"""Reading scenario files: strict typed parsing of each section, packaged scenarios.

``load_scenario("corridor")`` loads the packaged ``corridor.yaml``; a path loads that file.
The file is read by :mod:`~srpb_gym.yaml_io` (size, encoding, aliases, syntax)
and its values by :class:`~srpb_gym.scenarios.reader.Reader`. Every key is checked: an
unknown key, a value of the wrong type or out of range raises
:class:`~srpb_gym.errors.InputError` as ``file:line: dotted.key: what is wrong``. The loaded
scenario is then checked geometrically by :func:`~srpb_gym.scenarios.validate.validate`.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.resources import scenarios_dir
from srpb_gym.reward_terms import TERMS, preset_names
from srpb_gym.scenarios.reader import MAX_COORDINATE, Reader, describe
from srpb_gym.scenarios.schema import (
    DEFAULT_ROBOT_RADIUS,
    MAX_FORMATION_MEMBERS,
    MAX_GROUP_SIZE,
    MAX_ROBOTS,
    MIN_FORMATION_MEMBERS,
    FormationSpec,
    Place,
    Point,
    PoseSpec,
    RobotSpec,
    Scenario,
    SensorSpecs,
    WalkerEntry,
    WalkerParams,
    YawSpec,
    checked_robot_radius,
)
from srpb_gym.scenarios.space import (
    RESOLUTION,
    polygon_problem,
    rectangle_corners,
    repeated_point,
    ring_segments,
)
from srpb_gym.scenarios.validate import validate
from srpb_gym.yaml_io import read_file, read_yaml

SUFFIXES = (".yaml", ".yml")
TOP_KEYS = (
    "name", "description", "time_limit", "bounds", "enclose", "walls", "obstacles", "robot",
    "robots", "people", "formations", "sensors", "reward",
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
NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,99}")  # names episode files: no paths
MAX_GRID_CELLS = 4_000_000  # cells of the free-space grid over the bounds (100 m x 100 m)
MAX_UNITS = 500  # units (people or walking groups) of one people entry
MAX_SPEED = 10.0  # m/s, fastest preferred walking speed
MAX_BODY_RADIUS = 1.0  # m, largest body circle (also the largest formation jitter)


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
    if not isinstance(path_or_name, (str, os.PathLike)):
        raise InputError(f"expected a scenario name or file path, got {path_or_name!r}",
                         key="scenario")  # fmt: skip
    text = os.fspath(path_or_name)
    if Path(text).is_dir():
        raise InputError("is a folder, not a scenario file", text)
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
    text = read_file(source, str(source))
    return validate(parse_scenario(text, str(source), robot_radius=robot_radius))


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
    if default_name is None:  # the file's name, made a valid scenario name
        stem = Path(file).name.rsplit(".", 1)[0] if file else ""
        default_name = re.sub(r"[^A-Za-z0-9_.-]", "_", stem).lstrip(".")[:100] or "scenario"
    data, lines = read_yaml(text, file)
    r = Reader(file, lines)
    top = r.mapping(data, "", TOP_KEYS, required=("bounds", "robot"))
    bounds = r.rect(top["bounds"], "bounds")
    width, height = bounds[2] - bounds[0], bounds[3] - bounds[1]
    if math.ceil(width / RESOLUTION) * math.ceil(height / RESOLUTION) > MAX_GRID_CELLS:
        raise r.error("bounds", f"a world of {width:g} m x {height:g} m is too large: "
                      f"its {RESOLUTION:g} m grid has over {MAX_GRID_CELLS} cells")  # fmt: skip
    name = r.string(top.get("name", default_name), "name")
    if not NAME.fullmatch(name):
        raise r.error("name", "expected letters, digits, '-', '_' and '.' (not first), at most "
                      f"100 characters, got {name!r}")  # fmt: skip
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
        name=name,
        description=r.string(top.get("description", ""), "description").strip(),
        time_limit=time_limit,
        bounds=bounds,
        walls=walls,
        obstacles=tuple(np.array(p, dtype=np.float64) for p in polygons),
        robot=_robot(r, top["robot"], "robot"),
        robots=_robots(r, top.get("robots", [])),
        people=tuple(_people(r, top.get("people", []))),
        formations=tuple(_formations(r, top.get("formations", []))),
        sensors=_sensors(r, top.get("sensors", {})),
        reward=_reward(r, top.get("reward", {})),
        robot_radius=robot_radius,
        source=file,
        lines=lines,
    )


def _list(r: Reader, value: Any, key: str) -> list[Any]:
    if not isinstance(value, list):
        raise r.error(key, f"expected a list, got {describe(value)}")
    return value


def _walls(r: Reader, value: Any) -> list[tuple[float, ...]]:
    segments: list[tuple[float, ...]] = []
    for i, item in enumerate(_list(r, value, "walls")):
        key = f"walls[{i}]"
        if isinstance(item, list):
            segment = r.coordinates(item, key, (4,))
            if segment[:2] == segment[2:]:
                raise r.error(key, "the wall segment has zero length")
            segments.append(segment)
            continue
        spec = r.mapping(item, key, ("polyline", "closed"), required=("polyline",))
        points = r.points(spec["polyline"], f"{key}.polyline", 2)
        closed = r.boolean(spec.get("closed", False), f"{key}.closed")
        problem = repeated_point(points, closed)
        if problem is not None:
            raise r.error(f"{key}.polyline", f"a wall of zero length: {problem}")
        chain = ring_segments(points)
        segments.extend(chain if closed else chain[1:])
    return segments


def _obstacles(r: Reader, value: Any) -> list[tuple[Point, ...]]:
    polygons = []
    for i, item in enumerate(_list(r, value, "obstacles")):
        key = f"obstacles[{i}]"
        spec = r.mapping(item, key, ("polygon", "rectangle"))
        if len(spec) != 1:
            raise r.error(key, "give exactly one of 'polygon' or 'rectangle'")
        if "polygon" in spec:
            poly = r.points(spec["polygon"], f"{key}.polygon", 3)
            problem = polygon_problem(poly)
            if problem is not None:
                raise r.error(f"{key}.polygon", problem)
        else:
            poly = _rectangle(r, spec["rectangle"], f"{key}.rectangle")
        polygons.append(poly)
    return polygons


def _rectangle(r: Reader, value: Any, key: str) -> tuple[Point, ...]:
    """An axis-aligned ``[xmin, ymin, xmax, ymax]`` or ``{center, size, yaw|yaw_deg}``."""
    if isinstance(value, list):
        xmin, ymin, xmax, ymax = r.rect(value, key)
        return ((xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax))
    spec = r.mapping(value, key, ("center", "size", "yaw", "yaw_deg"), required=("center", "size"))
    cx, cy = r.point(spec["center"], f"{key}.center")
    w, h = (
        r.number(v, f"{key}.size", positive=True, high=MAX_COORDINATE)
        for v in r.numbers(spec["size"], f"{key}.size", (2,))
    )
    yaw_lo, yaw_hi = r.angle(spec, key, "yaw", (0.0, 0.0))
    if yaw_lo != yaw_hi:
        raise r.error(f"{key}.yaw", "a rectangle's yaw must be a single number")
    return rectangle_corners((cx, cy), (w, h), yaw_lo)


def _robot(r: Reader, value: Any, key: str) -> RobotSpec:
    spec = r.mapping(value, key, ("start", "goal", "goal_tolerance"), required=("start", "goal"))
    tolerance = r.number(spec.get("goal_tolerance", 0.2), f"{key}.goal_tolerance", positive=True)
    return RobotSpec(
        _pose(r, spec["start"], f"{key}.start"), _pose(r, spec["goal"], f"{key}.goal"), tolerance
    )


def _robots(r: Reader, value: Any) -> tuple[RobotSpec, ...]:
    """The multi-robot entries: each like ``robot``, robot i starting from entry i."""
    items = _list(r, value, "robots")
    if len(items) > MAX_ROBOTS:
        raise r.error("robots", f"at most {MAX_ROBOTS} robots, got {len(items)}")
    return tuple(_robot(r, item, f"robots[{i}]") for i, item in enumerate(items))


def _pose(r: Reader, value: Any, key: str) -> PoseSpec:
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


def _params(r: Reader, spec: dict, key: str) -> WalkerParams:
    d = WalkerParams()
    return WalkerParams(
        preferred_speed=r.field_range(
            spec, key, "preferred_speed", d.preferred_speed, True, MAX_SPEED
        ),
        radius=r.field_range(spec, key, "radius", d.radius, True, MAX_BODY_RADIUS),
        relaxation_time=r.field_range(spec, key, "relaxation_time", d.relaxation_time, True),
        robot_reaction=r.field_range(spec, key, "robot_reaction", d.robot_reaction),
    )


def _people(r: Reader, value: Any) -> list[WalkerEntry]:
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
            "count": r.int_range(spec.get("count", 1), f"{key}.count", 0, MAX_UNITS),
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


def _route(r: Reader, spec: dict, key: str, common: dict[str, Any]) -> WalkerEntry:
    jitter = r.number(spec.get("waypoint_jitter", 0.0), f"{key}.waypoint_jitter", low=0.0)
    return WalkerEntry(
        route=r.points(spec["route"], f"{key}.route", 2),
        spacing=r.field_range(spec, key, "spacing", (1.0, 1.0)),
        headway=r.field_range(spec, key, "headway", (0.0, 0.0)),
        waypoint_jitter=jitter,
        **common,
    )


def _spawn(r: Reader, spec: dict, key: str, common: dict[str, Any]) -> WalkerEntry:
    return WalkerEntry(
        spawn=r.place(spec["spawn"], f"{key}.spawn"),
        goal=r.place(spec["goal"], f"{key}.goal"),
        via=r.points(spec["via"], f"{key}.via", 1) if "via" in spec else (),
        **common,
    )


def _formations(r: Reader, value: Any) -> list[FormationSpec]:
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
                jitter=r.number(
                    spec.get("jitter", default.jitter), f"{key}.jitter", 0.0, high=MAX_BODY_RADIUS
                ),
                body_radius=r.field_range(
                    spec, key, "body_radius", default.body_radius, True, MAX_BODY_RADIUS
                ),
            )
        )
    return out


def _sensors(r: Reader, value: Any) -> SensorSpecs:
    spec = r.mapping(
        value if value is not None else {}, "sensors", ("lidar", "detector", "tracker")
    )
    raw = {}
    for name, item in spec.items():
        if item is not None and not isinstance(item, (str, dict)):
            raise r.error(
                f"sensors.{name}", f"expected a preset name or a mapping, got {describe(item)}"
            )
        raw[name] = item
    return SensorSpecs(**raw)


def _reward(r: Reader, value: Any) -> dict[str, dict[str, float]]:
    presets = r.mapping(value if value is not None else {}, "reward", preset_names())
    out = {}
    for preset, weights in presets.items():
        key = f"reward.{preset}"
        spec = r.mapping(weights if weights is not None else {}, key, TERMS)
        out[preset] = {term: r.number(w, f"{key}.{term}") for term, w in spec.items()}
    return out
