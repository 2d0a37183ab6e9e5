"""Bad scenario files are refused fast, with one line naming the file, the line and the key."""

from __future__ import annotations

import codecs
import time

import gymnasium as gym
import numpy as np
import pytest

import srpb_gym  # noqa: F401  (registers the environments)
from srpb_gym import yaml_io
from srpb_gym.errors import InputError
from srpb_gym.scenarios import load_scenario, parse_scenario, sample

GOOD = """\
name: test
time_limit: 30.0
bounds: [0.0, 0.0, 10.0, 6.0]
walls:
  - [5.0, 0.0, 5.0, 2.0]
obstacles:
  - rectangle: [7.0, 4.0, 8.0, 5.0]
robot:
  start:
    position: [1.0, 3.0]
  goal:
    position: [9.0, 3.0]
people:
  - route: [[8.0, 2.5], [2.0, 2.5]]
    count: 1
formations:
  - center: [3.0, 4.5]
    members: 2
"""


def _write(tmp_path, content: str | bytes, edits: dict[str, str] | None = None, name="bad.yaml"):
    if isinstance(content, str):
        for old, new in (edits or {}).items():
            assert old in content, old
            content = content.replace(old, new)
        content = content.encode("utf-8")
    path = tmp_path / name
    path.write_bytes(content)
    return path


def _refusal(path) -> str:
    with pytest.raises(InputError) as info:
        load_scenario(path)
    text = str(info.value)
    assert "\n" not in text and "Traceback" not in text
    return text


def test_good_file_loads(tmp_path):
    assert load_scenario(_write(tmp_path, GOOD)).name == "test"


# --- 1. alias bombs, size and nesting limits --------------------------------------------------


def _laughs(levels: int = 9) -> str:
    """The "billion laughs": 9 levels of 9 aliases each expand to 9**9 strings."""
    text = 'lol0: &lol0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]\n'
    for k in range(1, levels + 1):
        text += f"lol{k}: &lol{k} [" + ", ".join([f"*lol{k - 1}"] * 9) + "]\n"
    return text


def test_alias_bomb_is_refused_at_once(tmp_path):
    path = _write(tmp_path, GOOD + _laughs())
    start = time.perf_counter()
    text = _refusal(path)
    assert time.perf_counter() - start < 0.2
    assert text == f"{path}:20: aliases (*lol0) are not supported; write the value out"


def test_alias_bomb_through_gym_make(tmp_path):
    path = _write(tmp_path, GOOD + _laughs())
    start = time.perf_counter()
    with pytest.raises(InputError, match=r"bad\.yaml:20: aliases \(\*lol0\) are not supported"):
        gym.make("SRPB-Custom-v0", scenario=str(path))
    assert time.perf_counter() - start < 1.0  # it hung for over a minute


def test_any_alias_is_refused(tmp_path):
    edits = {"    count: 1\n": "    count: &n 1\n    spacing: *n\n"}
    path = _write(tmp_path, GOOD, edits)
    assert _refusal(path) == f"{path}:16: aliases (*n) are not supported; write the value out"


def test_file_size_limit(tmp_path):
    path = _write(tmp_path, GOOD + "#" * yaml_io.MAX_BYTES)
    assert _refusal(path) == f"{path}: the file is larger than 1048576 bytes"


def test_nesting_limit(tmp_path):
    path = _write(tmp_path, GOOD + "deep: " + "[" * 200 + "]" * 200 + "\n")
    assert _refusal(path) == f"{path}:19: nested more than 32 levels deep"


def test_value_count_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(yaml_io, "MAX_NODES", 20)
    path = _write(tmp_path, GOOD)
    assert _refusal(path) == f"{path}:7: more than 20 values in one file"


# --- 2. every parse error names the file ------------------------------------------------------

UTF16 = codecs.BOM_UTF16_LE + GOOD.encode("utf-16-le")
PARSE_ERRORS = {
    "random bytes": (
        b"\x93\xa7\x10" + bytes(range(256)),
        "{}:1: binary data, not YAML text (a NUL byte)",
    ),
    "png": (
        b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR",
        "{}:3: binary data, not YAML text (a NUL byte)",
    ),
    "utf-16 with BOM": (UTF16, "{}: the file is UTF-16 or UTF-32 text; save it as UTF-8"),
    "utf-16 without BOM": (
        GOOD.encode("utf-16-le"),
        "{}:1: binary data, not YAML text (a NUL byte)",
    ),
    "latin-1": (
        GOOD.replace("name: test", "name: test\ndescription: café").encode("latin-1"),
        "{}:2: not UTF-8 text (byte 0xe9); save the file as UTF-8",
    ),
    "control character": (
        GOOD.replace("name: test", "name: te\x07st"),
        "{}:1: invalid YAML: the character U+0007 is not allowed in YAML text",
    ),
    "empty": ("", "{}: the file is empty (no YAML document)"),
    "only comments": ("# nothing here\n", "{}: the file is empty (no YAML document)"),
    "top-level list": ("- 1\n- 2\n", "{}:1: expected a mapping, got a list [1, 2]"),
    "top-level scalar": ("corridor\n", "{}:1: expected a mapping, got a string 'corridor'"),
    "syntax error": (
        GOOD.replace("  start:\n", "  start: [\n"),
        "{}:11: invalid YAML: while parsing a flow sequence, expected ',' or ']', but got "
        "'<scalar>'",
    ),
    "tab indent": (
        GOOD.replace("    members: 2", "\tmembers: 2"),
        "{}:18: invalid YAML: while scanning for the next token, found character '\\t' that "
        "cannot start any token",
    ),
    "two documents": (
        GOOD + "---\nname: other\n",
        "{}:19: invalid YAML: expected a single document in the stream, but found another document",
    ),
    "python tag": (
        GOOD.replace("time_limit: 30.0", "time_limit: !!python/object/apply:os.system [ls]"),
        "{}:2: time_limit: the tag 'tag:yaml.org,2002:python/object/apply:os.system' is not "
        "supported",
    ),
    "unknown scalar tag": (
        GOOD.replace("name: test", "name: !!python/name:os.system ''"),
        "{}:1: name: cannot read the value: could not determine a constructor for the tag "
        "'tag:yaml.org,2002:python/name:os.system'",
    ),
    "impossible date": (
        GOOD.replace("name: test", "name: 2024-13-45"),
        "{}:1: name: cannot read the value: month must be in 1..12",
    ),
    "bad merge": (
        GOOD.replace("name: test", "name: test\n<<: 3"),
        "{}:2: invalid YAML: while constructing a mapping, expected a mapping or list of "
        "mappings for merging, but found scalar",
    ),
    "list key": (GOOD + "? [a, b]\n: 1\n", "{}:19: top level: keys must be strings"),
}


@pytest.mark.parametrize("case", sorted(PARSE_ERRORS))
def test_parse_errors_name_the_file(tmp_path, case):
    content, expected = PARSE_ERRORS[case]
    path = _write(tmp_path, content)
    assert _refusal(path) == expected.format(path)


def test_utf8_byte_order_mark_is_fine(tmp_path):
    assert load_scenario(_write(tmp_path, codecs.BOM_UTF8 + GOOD.encode())).name == "test"


def test_folders_and_non_paths_are_refused(tmp_path):
    assert _refusal(tmp_path) == f"{tmp_path}: is a folder, not a scenario file"
    with pytest.raises(InputError) as info:
        load_scenario(None)
    assert str(info.value) == "scenario: expected a scenario name or file path, got None"


def test_unreadable_file():
    class Locked:
        def open(self, mode):
            raise PermissionError(13, "Permission denied")

    with pytest.raises(InputError) as info:
        yaml_io.read_file(Locked(), "locked.yaml")
    assert str(info.value) == "locked.yaml: cannot read the file: Permission denied"


def test_parse_scenario_text_errors_name_the_file():
    with pytest.raises(InputError) as info:
        parse_scenario("a: [\n", "given.yaml")
    assert str(info.value).startswith("given.yaml:2: invalid YAML: ")
    with pytest.raises(InputError) as info:
        parse_scenario(b"name: caf\xe9\n", "given.yaml")
    assert str(info.value) == "given.yaml:1: not UTF-8 text (byte 0xe9); save the file as UTF-8"
    assert parse_scenario(GOOD.encode(), "given.yaml").name == "test"


# --- 3. polygons ----------------------------------------------------------------------------

POLYGONS = {
    "bow-tie": (
        "[[0, 0], [2, 2], [2, 0], [0, 2]]",
        "the polygon intersects itself: its edge from point 0 to point 1 meets its edge from "
        "point 2 to point 3",
    ),
    "vertex on an edge": (
        "[[0, 0], [4, 0], [4, 3], [2, 0], [0, 3]]",
        "the polygon intersects itself: its edge from point 0 to point 1 meets its edge from "
        "point 2 to point 3",
    ),
    "folding back": (
        "[[0, 0], [2, 0], [1, 0], [1, 1]]",
        "the polygon intersects itself: its edge from point 0 to point 1 meets its edge from "
        "point 1 to point 2",
    ),
    "one line": (
        "[[0, 0], [1, 1], [2, 2]]",
        "the polygon has zero area: all its points lie on one line",
    ),
    "two distinct points": (
        "[[0, 0], [1, 1], [0, 0], [1, 1]]",
        "the polygon has fewer than 3 distinct points",
    ),
    "repeated point": (
        "[[0, 0], [1, 0], [1, 0], [1, 1]]",
        "the polygon has an edge of zero length: points 1 and 2 are the same point",
    ),
    "closed by hand": (
        "[[0, 0], [1, 0], [1, 1], [0, 0]]",
        "the polygon has an edge of zero length: the last point repeats the first (the ring "
        "closes itself)",
    ),
    "tiny": ("[[0, 0], [1, 0], [1, 1.0e-12]]", "the polygon has zero area"),
    "two points": ("[[0, 0], [1, 0]]", "expected a list of at least 3 points [x, y]"),
}


@pytest.mark.parametrize("case", sorted(POLYGONS))
def test_bad_polygons(tmp_path, case):
    points, message = POLYGONS[case]
    rectangle = "  - rectangle: [7.0, 4.0, 8.0, 5.0]"
    edits = {rectangle: f"{rectangle}\n  - polygon: {points}"}
    path = _write(tmp_path, GOOD, edits)
    assert _refusal(path) == f"{path}:8: obstacles[1].polygon: {message}"


def test_good_polygons_load(tmp_path):
    concave = "[[6.0, 0.5], [9.0, 0.5], [9.0, 2.0], [8.0, 2.0], [8.0, 1.0], [7.0, 1.0], [7.0, 2.0]]"
    edits = {"  - rectangle: [7.0, 4.0, 8.0, 5.0]": f"  - polygon: {concave}"}
    assert len(load_scenario(_write(tmp_path, GOOD, edits)).obstacles) == 1


def test_zero_length_walls(tmp_path):
    path = _write(tmp_path, GOOD, {"[5.0, 0.0, 5.0, 2.0]": "[5.0, 1.0, 5.0, 1.0]"})
    assert _refusal(path) == f"{path}:5: walls[0]: the wall segment has zero length"
    polyline = "polyline: [[5.0, 0.0], [5.0, 1.0], [5.0, 1.0]]"
    path = _write(tmp_path, GOOD, {"[5.0, 0.0, 5.0, 2.0]": polyline})
    assert _refusal(path) == (
        f"{path}:5: walls[0].polyline: a wall of zero length: points 1 and 2 are the same point"
    )


# --- 5. the scenario name names files -------------------------------------------------------


@pytest.mark.parametrize("name", ["../../x", "/tmp/x", ".hidden", "a b", "'a/b'", "''", "x" * 101])
def test_names_that_are_not_file_names(tmp_path, name):
    path = _write(tmp_path, GOOD, {"name: test": f"name: {name}"})
    shown = repr(name.strip("'")) if name.startswith("'") else repr(name)
    assert _refusal(path) == (
        f"{path}:1: name: expected letters, digits, '-', '_' and '.' (not first), at most 100 "
        f"characters, got {shown}"
    )


def test_good_names(tmp_path):
    path = _write(tmp_path, GOOD, {"name: test": "name: hall_2.v-1"})
    assert load_scenario(path).name == "hall_2.v-1"
    path = _write(tmp_path, GOOD.replace("name: test\n", ""), name="my hall (2).yaml")
    scenario = load_scenario(path)
    assert scenario.name == "my_hall__2_"
    assert sample(scenario, np.random.default_rng(0)).metadata["scenario"] == "my_hall__2_"


# --- 6. values that cannot be right ---------------------------------------------------------

VALUES = {
    "time limit nan": (
        {"time_limit: 30.0": "time_limit: .nan"},
        2,
        "time_limit",
        "expected a finite number, got float nan",
    ),
    "time limit inf": (
        {"time_limit: 30.0": "time_limit: .inf"},
        2,
        "time_limit",
        "expected a finite number, got float inf",
    ),
    "time limit huge integer": (
        {"time_limit: 30.0": "time_limit: 1" + "0" * 400},
        2,
        "time_limit",
        "expected a finite number, got int 1000000000000000000000000000000000000...",
    ),
    "quoted number": (
        {"time_limit: 30.0": "time_limit: '3e1'"},
        2,
        "time_limit",
        "expected a number, got a string '3e1' (quoted, a number is text: leave out the quotes)",
    ),
    "goal tolerance inf": (
        {"    position: [9.0, 3.0]": "    position: [9.0, 3.0]\n  goal_tolerance: .inf"},
        13,
        "robot.goal_tolerance",
        "expected a finite number, got float inf",
    ),
    "negative count": (
        {"    count: 1": "    count: -1"},
        15,
        "people[0].count",
        "must be 0 to 500, got -1",
    ),
    "huge count": (
        {"    count: 1": "    count: [1, 100000]"},
        15,
        "people[0].count[1]",
        "must be 0 to 500, got 100000",
    ),
    "running at 50 m/s": (
        {"    count: 1": "    count: 1\n    preferred_speed: [1.0, 50.0]"},
        16,
        "people[0].preferred_speed",
        "must be <= 10, got 50.0",
    ),
    "a body of 3 m": (
        {"    count: 1": "    count: 1\n    radius: 3.0"},
        16,
        "people[0].radius",
        "must be <= 1, got 3.0",
    ),
    "formation jitter of 5 m": (
        {"    members: 2": "    members: 2\n    jitter: 5.0"},
        19,
        "formations[0].jitter",
        "must be <= 1, got 5.0",
    ),
    "a world too large for its grid": (
        {"bounds: [0.0, 0.0, 10.0, 6.0]": "bounds: [0.0, 0.0, 1000.0, 600.0]"},
        3,
        "bounds",
        "a world of 1000 m x 600 m is too large: its 0.05 m grid has over 4000000 cells",
    ),
    "a wall a light-year away": (
        {"[5.0, 0.0, 5.0, 2.0]": "[5.0, 0.0, 5.0, 9.5e+15]"},
        5,
        "walls[0]",
        "coordinates must lie within +-1e+06 m, got [5, 0, 5, 9.5e+15]",
    ),
    "yaw range over a full turn": (
        {"    position: [9.0, 3.0]": "    position: [9.0, 3.0]\n    yaw_deg: [-180.0, 270.0]"},
        13,
        "robot.goal.yaw_deg",
        "the range [-180, 270] spans more than a full turn (360): some headings would be likelier",
    ),
}


@pytest.mark.parametrize("case", sorted(VALUES))
def test_values_that_cannot_be_right(tmp_path, case):
    edits, line, key, message = VALUES[case]
    path = _write(tmp_path, GOOD, edits)
    with pytest.raises(InputError) as info:
        load_scenario(path)
    assert str(info.value) == f"{path}:{line}: {key}: {message}"
    assert (info.value.line, info.value.key) == (line, key)


def test_numbers_with_an_exponent_are_numbers(tmp_path):
    # YAML 1.1 reads 3e1 and 3.0e1 as text; these files read them as Python does
    for text in ("3e1", "3.0e1", "300e-1", ".3e2"):
        edits = {"time_limit: 30.0": f"time_limit: {text}"}
        assert load_scenario(_write(tmp_path, GOOD, edits)).time_limit == 30.0


def test_full_turns_are_fine(tmp_path):
    edits = {"    members: 2": "    members: 2\n    orientation_deg: [0.0, 360.0]"}
    formation = load_scenario(_write(tmp_path, GOOD, edits)).formations[0]
    assert formation.orientation == pytest.approx((0.0, 2.0 * np.pi))
