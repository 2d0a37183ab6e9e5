"""SRPB native text logs: reading the fixtures, both robot-line variants, round trips, errors."""

from __future__ import annotations

import csv
import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.errors import InputError
from srpb_gym.metrics import METRIC_NAMES, SRPBMetricWarning, evaluate
from srpb_gym.metrics.io import load_episode
from srpb_gym.metrics.io_native import read_native, sibling_logs, write_native
from srpb_gym.metrics.record import PERSON_FIELDS, ROBOT_FIELDS, EpisodeRecord

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
EPISODES = sorted(p.name for p in FIXTURES.iterdir() if (p / "srpb_log").is_dir())
TABLES = ("robot", "people", "people_sample", "group_sample", "group_size", "group_members")

ROBOT_LINE = "{t} 0 0 0 0 0 0 0 0 0 0.5 0 0 0.1 0 0 0 0 0 6 0 0 2 0.01"  # t + 23
PERSON_LINE = "{t} {id} 1 3 1 0 -1.5 0.02 0 0 0.02 0 0 0 0 0 0 0 0 0 0 0 0 1 0 {g}"  # 26 tokens


def _fixture_logs(name: str) -> tuple[Path, Path, Path]:
    log = FIXTURES / name / "srpb_log"
    return log / "log_robot.txt", log / "log_people.txt", log / "log_groups.txt"


def _csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _write(path: Path, lines: list[str]) -> Path:
    path.write_text("".join(line + "\n" for line in lines))
    return path


def _robot(tmp_path: Path, times=(0.0, 0.1, 0.2)) -> Path:
    return _write(tmp_path / "run_robot.txt", [ROBOT_LINE.format(t=t) for t in times])


def _bare(tmp_path: Path, kind: str, times=(0.0, 0.1, 0.2)) -> Path:
    """A people or groups log holding a bare timestamp line per robot sample."""
    return _write(tmp_path / f"run_{kind}.txt", [str(t) for t in times])


def _same_tables(a: EpisodeRecord, b: EpisodeRecord) -> None:
    for name in TABLES:
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape and x.tobytes() == y.tobytes(), name


def _same_metrics(a: dict[str, float], b: dict[str, float], rtol: float = 1e-9) -> None:
    for name in METRIC_NAMES:
        x, y = a[name], b[name]
        assert (math.isnan(x) and math.isnan(y)) or math.isclose(x, y, rel_tol=rtol,
                                                                 abs_tol=1e-12), name  # fmt: skip


def _metrics(record: EpisodeRecord, semantics: str = "paper") -> dict[str, float]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SRPBMetricWarning)
        return evaluate(record, semantics)


# ---------------------------------------------------------------------------- fixtures
@pytest.mark.parametrize("name", EPISODES)
def test_fixture_logs_equal_csv_tables(name):
    rec = read_native(*_fixture_logs(name))
    robot = _csv(FIXTURES / name / "robot.csv")
    expected = np.array([[float(row[f]) for f in ROBOT_FIELDS] for row in robot])
    assert np.array_equal(rec.robot, expected)

    people = _csv(FIXTURES / name / "people.csv")
    assert rec.people.shape == (len(people), len(PERSON_FIELDS))
    if people:
        expected = np.array([[float(row[f]) for f in PERSON_FIELDS] for row in people])
        assert np.array_equal(rec.people, expected)
        assert rec.robot[rec.people_sample, 0].tolist() == [float(r["t"]) for r in people]
        assert [rec.person_label(i) for i in rec.people_id] == [r["id"] for r in people]

    groups = _csv(FIXTURES / name / "groups.csv")
    assert rec.group_sample.shape == (len(groups),)
    for g, row in enumerate(groups):
        assert rec.robot[rec.group_sample[g], 0] == float(row["t"])
        assert rec.group_label(rec.group_id[g]) == row["group_id"]
        members = rec.group_members[rec.group_start[g] : rec.group_start[g] + rec.group_size[g]]
        assert [rec.person_label(rec.people_id[m]) for m in members] == row["member_ids"].split()
        assert np.all(rec.people_sample[members] == rec.group_sample[g])
        cog = rec.people[members][:, :2].mean(axis=0)
        assert np.allclose(cog, [float(row["cog_x"]), float(row["cog_y"])], atol=1e-4)


@pytest.mark.parametrize("name", EPISODES)
def test_fixture_write_at_precision_4_reproduces_the_logs_byte_for_byte(name, tmp_path):
    logs = _fixture_logs(name)
    out = [tmp_path / f"log_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(read_native(*logs), *out, precision=4)
    for original, written in zip(logs, out, strict=True):
        assert written.read_text() == original.read_text()


@pytest.mark.parametrize("name", EPISODES)
def test_fixture_write_at_full_precision_reads_back_bit_for_bit(name, tmp_path):
    rec = read_native(*_fixture_logs(name))
    out = [tmp_path / f"log_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(rec, *out)
    back = read_native(*out)
    _same_tables(back, rec)
    for semantics in ("paper", "reference"):
        assert _metrics(back, semantics) == pytest.approx(_metrics(rec, semantics), nan_ok=True)


def test_full_precision_keeps_the_reference_layout(tmp_path):
    """Single spaces between fields padded to 9 characters, the same tokens per line, the
    reference logger's constant fields: only the digits of the numbers differ (a group's
    cog is written as the mean of its members, which the reference logger rounds
    differently)."""
    logs = _fixture_logs("e17_fformation_5")
    out = [tmp_path / f"log_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(read_native(*logs), *out)
    for original, written in zip(logs[:2], out[:2], strict=True):
        old, new = original.read_text().splitlines(), written.read_text().splitlines()
        assert len(old) == len(new)
        for a, b in zip(old, new, strict=True):
            ta, tb = a.split(), b.split()
            assert len(ta) == len(tb)
            for x, y in zip(ta, tb, strict=True):
                try:
                    assert float(x) == float(y)
                except ValueError:  # ids, "/", "none"
                    assert x == y
    line = out[0].read_text().splitlines()[1]
    assert line == " ".join(f"{tok:>9}" for tok in line.split())
    assert line.split()[:3] == ["70.1", "0.05", "0.3"]  # the shortest exact text


def test_ids_are_coded_in_order_of_first_appearance():
    rec = read_native(*_fixture_logs("e17_fformation_5"))
    assert rec.person_labels == ("81", "82", "83", "84", "85")
    assert rec.group_labels == ("g1",)
    assert rec.people_id[:5].tolist() == [0, 1, 2, 3, 4]


def test_no_people_no_groups_gives_empty_tables_and_no_labels():
    rec = read_native(*_fixture_logs("e01_forward_no_humans"))
    assert rec.n_samples == 81
    assert rec.people.shape == (0, 9) and rec.group_sample.size == 0
    assert rec.person_labels is None and rec.group_labels is None
    assert rec.group_start.size == 0


def test_load_episode_finds_sibling_logs():
    robot, people, groups = _fixture_logs("e09_fformation_2")
    assert sibling_logs(robot) == (people, groups)
    rec = load_episode(robot)
    assert rec.people.shape[0] == 242 and rec.group_sample.size == 121


def test_sibling_logs_need_the_robot_suffix_and_existing_files(tmp_path):
    assert sibling_logs(tmp_path / "episode.txt") == (None, None)
    robot = _robot(tmp_path)
    assert sibling_logs(robot) == (None, None)
    _write(tmp_path / "run_groups.txt", ["0.0"])
    assert sibling_logs(robot) == (None, tmp_path / "run_groups.txt")


# ---------------------------------------------------------------------------- missing logs
def test_a_missing_people_or_groups_log_is_refused_not_scored_as_empty(tmp_path):
    robot = _robot(tmp_path)
    with pytest.raises(InputError, match="no people log given or found"):
        load_episode(robot)  # no siblings beside it
    with pytest.raises(InputError) as info:
        read_native(robot, None, None)
    assert str(info.value) == (
        f"{robot}: no people log given or found: the social metrics (m_psi, m_dir, m_fsi) "
        "cannot be computed without it (people_path=False reads a run that logged none)"
    )
    people = _bare(tmp_path, "people")
    with pytest.raises(InputError) as info:
        read_native(robot, people, None)
    assert str(info.value) == (
        f"{robot}: no groups log given or found: m_fsi cannot be computed without it "
        "(groups_path=False reads a run that logged none)"
    )
    with pytest.raises(InputError, match="no groups log given or found"):
        load_episode(robot)  # the people log lies beside it, no groups log


def test_false_reads_a_run_that_logged_no_people(tmp_path):
    alone = shutil.copy(_fixture_logs("e05_pass_human_front")[0], tmp_path / "copy.txt")
    rec = read_native(alone, False, False)
    assert rec.n_samples == 121 and rec.people.shape == (0, 9) and rec.group_sample.size == 0
    people = _fixture_logs("e05_pass_human_front")[1]
    assert read_native(alone, people, False).people.shape[0] > 0


# ---------------------------------------------------------------------------- format details
def test_both_robot_line_variants_give_the_same_table(tmp_path):
    robot, people, groups = _fixture_logs("e05_pass_human_front")
    lines = robot.read_text().splitlines()
    newer = []
    for i, line in enumerate(lines):
        tok = line.split()
        cmd = ["0.5", "0.0", "0.0"] if i % 2 else ["nan", "inf", "-inf"]  # unused: any number
        newer.append(" ".join(tok[:22] + cmd + tok[22:]))
    only_new = _write(tmp_path / "new_robot.txt", newer)
    mixed = _write(tmp_path / "mixed_robot.txt", [newer[i] if i % 3 else lines[i] for i in
                                                  range(len(lines))])  # fmt: skip
    expected = read_native(robot, people, groups)
    for variant in (only_new, mixed):
        rec = read_native(variant, people, groups)
        assert np.array_equal(rec.robot, expected.robot)
        assert np.array_equal(rec.people, expected.people)
        assert np.array_equal(rec.people_sample, expected.people_sample)


def test_bare_timestamp_lines_blank_lines_and_none_groups(tmp_path):
    robot = _robot(tmp_path, (0.0, 0.1, 0.2, 0.3))
    people = _write(tmp_path / "run_people.txt", [
        "0.0", "",
        PERSON_LINE.format(t=0.1, id="alice", g="none"),
        PERSON_LINE.format(t=0.1, id="bob", g="none"),
        "   0.2   ", "",
        PERSON_LINE.format(t=0.3, id="bob", g="none"),
    ])  # fmt: skip
    groups = _write(tmp_path / "run_groups.txt", ["0.0", "0.1", "0.2", "", "0.3"])
    rec = read_native(robot, people, groups)
    assert rec.people_sample.tolist() == [1, 1, 3]
    assert rec.person_labels == ("alice", "bob")
    assert rec.people_id.tolist() == [0, 1, 1]
    assert rec.group_sample.size == 0 and rec.group_labels is None


def test_groups_with_relations_and_shared_members(tmp_path):
    robot = _robot(tmp_path, (0.0, 0.1))
    people = _write(tmp_path / "run_people.txt", [
        PERSON_LINE.format(t=0.0, id=pid, g="a") for pid in ("p1", "p2", "p3")
    ] + [PERSON_LINE.format(t=0.1, id="p3", g="none")])  # fmt: skip
    groups = _write(tmp_path / "run_groups.txt", [
        "0.1 b 3 1 0 0 p3 /",
        "0.0 a 3 1 0 5 p1 p2 / p1 p2 0.9",
        "0.0 b 3 1 0 5 p3 p2 / p3 p2 0.5 p2 p3 0.4",
    ])  # fmt: skip
    rec = read_native(robot, people, groups)
    assert rec.group_labels == ("b", "a")
    assert rec.group_sample.tolist() == [0, 0, 1]  # sorted stably by sample
    assert rec.group_id.tolist() == [1, 0, 0]
    assert rec.group_size.tolist() == [2, 2, 1]
    assert rec.group_members.tolist() == [0, 1, 2, 1, 3]


def test_nan_planning_time_means_no_decision(tmp_path):
    line = ROBOT_LINE.format(t=0.2).split()
    line[23] = "nan"
    lines = [ROBOT_LINE.format(t=0.0), ROBOT_LINE.format(t=0.1), " ".join(line)]
    robot = _write(tmp_path / "run_robot.txt", lines)
    rec = read_native(robot, _bare(tmp_path, "people"), _bare(tmp_path, "groups"))
    assert np.isnan(rec.robot[2, -1])
    assert _metrics(rec)["m_cef"] == pytest.approx(10.0)  # the two timed decisions


def test_duplicate_robot_timestamps_attach_to_the_first_sample(tmp_path):
    robot = _robot(tmp_path, (0.0, 0.1, 0.1, 0.2))
    people = _write(tmp_path / "run_people.txt",
                    ["0.0", PERSON_LINE.format(t=0.1, id=1, g="none"), "0.2"])  # fmt: skip
    groups = _write(tmp_path / "run_groups.txt", ["0.0", "0.1 g 0 0 0 0 1 /", "0.2"])
    rec = read_native(robot, people, groups)
    assert rec.people_sample.tolist() == [1] and rec.group_sample.tolist() == [1]


def test_timestamps_match_by_parsed_value(tmp_path):
    robot = _robot(tmp_path, ("0.10", "0.2"))
    people = _write(tmp_path / "run_people.txt",
                    [PERSON_LINE.format(t="0.1000", id=1, g="x"), "2e-1"])  # fmt: skip
    rec = read_native(robot, people, _bare(tmp_path, "groups", ("0.1", "0.20")))
    assert rec.people_sample.tolist() == [0]


# ---------------------------------------------------------------------------- round trip
def _covariance(rng: np.random.Generator) -> list[float]:
    a = rng.normal(scale=0.3, size=(2, 2))
    c = a @ a.T
    return [c[0, 0], c[0, 1], c[1, 0], c[1, 1]]


def _random_record(rng: np.random.Generator, n: int = 40, labels: bool = False) -> EpisodeRecord:
    """A valid record with awkward values: full precision, -0.0, tiny numbers, NaN final
    planning time."""
    rec = EpisodeRecord(person_labels=["walker", "p-2", "x3"] if labels else None,
                        group_labels=["G0", "G1"] if labels else None)  # fmt: skip
    for k in range(n):
        robot = rng.normal(scale=3.0, size=12) * 10.0 ** rng.integers(-9, 4, size=12)
        robot[0] = 10.0 + k / 3.0
        robot[11] = abs(robot[11]) if k < n - 1 else np.nan
        if k == 3:
            robot[1:3] = [-0.0, 5e-324]
        count = int(rng.integers(0, 4))
        people = rng.normal(scale=2.0, size=(count, 9))
        for row in people:
            row[3:7] = _covariance(rng)
        groups = {}
        if count >= 2 and k % 2:
            groups = {"group_ids": [1, 0], "group_sizes": [2, count - 1],
                      "group_members": [0, 1, *range(1, count)]}  # fmt: skip
        rec.append(robot, rng.permutation(3)[:count], people, **groups)
    return rec


def _labels_of(rec: EpisodeRecord) -> tuple[list[str], list[str]]:
    return ([rec.person_label(i) for i in rec.people_id],
            [rec.group_label(i) for i in rec.group_id])  # fmt: skip


@pytest.mark.parametrize("labels", [False, True])
def test_native_round_trip_is_exact_at_full_precision(tmp_path, labels):
    rec = _random_record(np.random.default_rng(7), labels=labels)
    paths = [tmp_path / f"e_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(rec, *paths)
    back = load_episode(paths[0])
    _same_tables(back, rec)
    assert _labels_of(back) == _labels_of(rec)
    for semantics in ("paper", "reference"):
        _same_metrics(_metrics(back, semantics), _metrics(rec, semantics), rtol=0.0)


@pytest.mark.parametrize("labels", [False, True])
def test_native_round_trip_at_precision_4_is_exact_up_to_rounding(tmp_path, labels):
    rec = _random_record(np.random.default_rng(7), labels=labels)
    paths = [tmp_path / f"e_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(rec, *paths, precision=4)
    back = load_episode(paths[0])
    assert np.allclose(back.robot, rec.robot, rtol=0, atol=5e-5 + 1e-12, equal_nan=True)
    cov = [PERSON_FIELDS.index(f) for f in ("cov_xx", "cov_xy", "cov_yx", "cov_yy")]
    other = [i for i in range(len(PERSON_FIELDS)) if i not in cov]
    assert np.allclose(back.people[:, cov], rec.people[:, cov], rtol=0, atol=5e-7 + 1e-12)
    assert np.allclose(back.people[:, other], rec.people[:, other], rtol=0, atol=5e-5 + 1e-12)
    for name in ("people_sample", "group_sample", "group_size", "group_members"):
        assert np.array_equal(getattr(back, name), getattr(rec, name)), name
    assert _labels_of(back) == _labels_of(rec)


def test_written_people_name_their_first_group(tmp_path):
    rec = _random_record(np.random.default_rng(3), labels=True)
    paths = [tmp_path / f"e_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(rec, *paths)
    column = [line.split()[-1] for line in paths[1].read_text().splitlines()
              if len(line.split()) > 1]  # fmt: skip
    expected = ["none"] * rec.people.shape[0]
    for g in range(rec.group_sample.size - 1, -1, -1):
        start, size = rec.group_start[g], rec.group_size[g]
        for m in rec.group_members[start : start + size]:
            expected[m] = rec.group_label(rec.group_id[g])
    assert column == expected


def test_write_rejects_labels_that_are_not_single_tokens(tmp_path):
    rec = EpisodeRecord(person_labels=["two words"])
    rec.append(np.zeros(12), [0], np.zeros((1, 9)))
    with pytest.raises(ValueError, match="two words"):
        write_native(rec, tmp_path / "r.txt", tmp_path / "p.txt", None)


def test_write_refuses_people_a_reader_would_attach_to_another_sample(tmp_path):
    rec = EpisodeRecord()
    for t, people in ((0.0, 0), (1e-5, 1), (0.1, 0)):
        rec.append([t, *[0.0] * 11], [0] * people, np.zeros((people, 9)))
    paths = [tmp_path / f"e_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(rec, *paths)  # exact timestamps: distinct
    assert read_native(*paths).people_sample.tolist() == [1]
    with pytest.raises(ValueError) as info:
        write_native(rec, *paths, precision=4)
    assert str(info.value) == (
        "people at sample 1 cannot be written: its timestamp 0.0000 equals sample 0's, to "
        "which a reader would attach them"
    )


@pytest.mark.parametrize("precision", [-1, 2.5, True, "4"])
def test_write_checks_the_precision(tmp_path, precision):
    with pytest.raises(ValueError, match="precision must be None or a whole number >= 0"):
        write_native(_random_record(np.random.default_rng(1), n=2), tmp_path / "r.txt", None,
                     None, precision=precision)  # fmt: skip


# ---------------------------------------------------------------------------- bad input
def _robot_with(t, **values) -> str:
    tokens = ROBOT_LINE.format(t=t).split()
    columns = {"x": 1, "y": 2, "yaw": 4, "vx": 10, "vy": 11, "omega": 13, "goal_x": 19,
               "goal_y": 20, "goal_yaw": 21, "obstacle_dist": 22, "planning_time": 23}  # fmt: skip
    for name, value in values.items():
        tokens[columns[name]] = value
    return " ".join(tokens)


def _person_with(t, **values) -> str:
    tokens = PERSON_LINE.format(t=t, id=1, g="none").split()
    columns = {"x": 3, "y": 4, "yaw": 6, "cov_xx": 7, "cov_xy": 8, "cov_yx": 9, "cov_yy": 10,
               "vx": 12, "vy": 13}  # fmt: skip
    for name, value in values.items():
        tokens[columns[name]] = value
    return " ".join(tokens)


R0, R1, R2 = (ROBOT_LINE.format(t=t) for t in (0.0, 0.1, 0.2))
P1 = PERSON_LINE.format(t=0.1, id=1, g="none")
BAD_CASES = {
    # name: (file kind, lines of that file, bad line, exact message)
    "robot_columns": ("robot", [R0, "0.1 1 2 3"], 2,
                      "expected 24 values (t + 23) or 27 (t + 26) on a robot line, got 4"),
    "robot_number": ("robot", [R0.replace(" 6 ", " six ")], 1,
                     "column goal_x is not a number: 'six'"),
    "robot_time": ("robot", ["", ROBOT_LINE.format(t="t0")], 2, "column t is not a number: 't0'"),
    "robot_underscore": ("robot", [R0, R1.replace(" 6 ", " 6_0 ")], 2,
                         "column goal_x is not a number: '6_0'"),
    "robot_unicode_digit": ("robot", [R0, R1.replace(" 6 ", " \u0666 ")], 2,
                            "column goal_x is not a number: '\u0666'"),
    "robot_x_nan": ("robot", [R0, _robot_with(0.1, x="nan"), R2], 2,
                    "x is nan, expected a finite number (m)"),
    "robot_y_inf": ("robot", [R0, R1, _robot_with(0.2, y="-inf")], 3,
                    "y is -inf, expected a finite number (m)"),
    "robot_overflow": ("robot", [_robot_with(0.0, vx="1e999"), R1, R2], 1,
                       "vx is inf, expected a finite number (m/s)"),
    "robot_omega": ("robot", [R0, _robot_with(0.1, omega="NaN"), R2], 2,
                    "omega is nan, expected a finite number (rad/s)"),
    "robot_goal": ("robot", [_robot_with(0.0, goal_yaw="inf"), R1, R2], 1,
                   "goal_yaw is inf, expected a finite number (rad)"),
    "robot_obstacle": ("robot", [R0, _robot_with(0.1, obstacle_dist="Infinity"), R2], 2,
                       "obstacle_dist is inf, expected a finite number (m)"),
    "robot_planning_inf": ("robot", [R0, _robot_with(0.1, planning_time="inf"), R2], 2,
                           "planning_time is inf, expected a time >= 0 s (or nan: no decision "
                           "at this sample)"),
    "robot_planning_negative": ("robot", [R0, R1, _robot_with(0.2, planning_time="-0.5")], 3,
                                "planning_time is -0.5, expected a time >= 0 s (or nan: no "
                                "decision at this sample)"),
    "robot_t_nan": ("robot", [R0, ROBOT_LINE.format(t="nan"), R2], 2,
                    "t is nan, expected a finite number (s)"),
    "robot_t_back": ("robot", [R0, R2, ROBOT_LINE.format(t=0.1)], 3,
                     "t = 0.1 is earlier than the previous sample's t = 0.2: robot times must "
                     "not decrease"),
    "robot_truncated_line": ("robot", [R0, R1, R2[:30]], 3,
                             "expected 24 values (t + 23) or 27 (t + 26) on a robot line, got 13"),
    "people_columns": ("people", ["0.0", P1 + " 7", "0.2"], 2,
                       "expected 26 values on a people line (or only the timestamp), got 27"),
    "people_number": ("people", ["0.0", P1.replace("0.02", "x"), "0.2"], 2,
                      "column cov_xx is not a number: 'x'"),
    "people_bare": ("people", ["zero", P1, "0.2"], 1, "column t is not a number: 'zero'"),
    "people_time": ("people", ["0.0", "", PERSON_LINE.format(t=0.15, id=1, g="none"), "0.2"],
                    3, "person at t = 0.15 matches no robot sample (no robot line has that time)"),
    "people_after_robot": ("people", ["0.0", P1, "0.2", "0.3"], 4,
                           "timestamp line at t = 0.3 matches no robot sample (no robot line has "
                           "that time); the robot log ends at t = 0.2 (robot log line 3): "
                           "truncated?"),
    "people_t_nan": ("people", ["0.0", PERSON_LINE.format(t="nan", id=1, g="none"), "0.2"], 2,
                     "t is nan, expected a finite time (s)"),
    "people_bare_t_inf": ("people", ["0.0", P1, "inf"], 3, "t is inf, expected a finite time (s)"),
    "people_x_nan": ("people", ["0.0", _person_with(0.1, x="nan"), "0.2"], 2,
                     "x is nan, expected a finite number (m)"),
    "people_yaw_inf": ("people", ["0.0", _person_with(0.1, yaw="inf"), "0.2"], 2,
                       "yaw is inf, expected a finite number (rad)"),
    "people_vy_inf": ("people", ["0.0", _person_with(0.1, vy="-inf"), "0.2"], 2,
                      "vy is -inf, expected a finite number (m/s)"),
    "people_cov_nan": ("people", ["0.0", _person_with(0.1, cov_yx="nan"), "0.2"], 2,
                       "cov_yx is nan, expected a finite number (m^2)"),
    "people_negative_variance": ("people", ["0.0", _person_with(0.1, cov_yy="-0.5"), "0.2"], 2,
                                 "cov_yy is -0.5: a variance cannot be negative (m^2)"),
    "people_not_psd": ("people", ["0.0", _person_with(0.1, cov_xy="0.05"), "0.2"], 2,
                       "cov_xy is 0.05, larger in magnitude than sqrt(cov_xx * cov_yy) = 0.02: "
                       "not a valid covariance (not positive semi-definite)"),
    "people_truncated": ("people", ["0.0", P1], 2,
                         "the people log ends at t = 0.1 but the robot log goes on to t = 0.2 "
                         "(robot log line 3): truncated? every robot sample needs a line in the "
                         "people log (a bare timestamp line at least)"),
    "people_gap": ("people", ["0.0", "0.2"], 2,
                   "no line for the robot sample at t = 0.1 (robot log line 2) before this "
                   "line; every robot sample needs a line in the people log (a bare timestamp "
                   "line at least)"),
    "group_slash": ("groups", ["0.0", "0.1 g 0 0 0 0 1", "0.2"], 2,
                    "group line has no '/' after its member ids"),
    "group_members": ("groups", ["0.0", "0.1 g 0 0 0 0 /", "0.2"], 2,
                      "a group line needs t id cog_x cog_y cog_z age and at least one member "
                      "id before '/', got 6 values"),
    "group_unknown_member": ("groups", ["0.0", "0.1 g 0 0 0 0 1 7 /", "0.2"], 2,
                             "group member '7' is not among the people at this group's "
                             "timestamp"),
    "group_member_elsewhere": ("groups", ["0.0 g 0 0 0 0 1 /", "0.1", "0.2"], 1,
                               "group member '1' is not among the people at this group's "
                               "timestamp"),
    "group_relations": ("groups", ["0.0", "0.1 g 0 0 0 0 1 / 1 1", "0.2"], 2,
                        "expected 'id id strength' triples after '/', got 2 values"),
    "group_strength": ("groups", ["0.0", "0.1 g 0 0 0 0 1 / 1 1 high", "0.2"], 2,
                       "column strength is not a number: 'high'"),
    "group_cog": ("groups", ["0.0", "0.1 g x 0 0 0 1 /", "0.2"], 2,
                  "column cog_x is not a number: 'x'"),
    "group_time": ("groups", ["0.0", "0.1", "0.2", "0.5 g 0 0 0 0 1 /"], 4,
                   "group at t = 0.5 matches no robot sample (no robot line has that time); the "
                   "robot log ends at t = 0.2 (robot log line 3): truncated?"),
    "group_t_nan": ("groups", ["0.0", "nan g 0 0 0 0 1 /", "0.2"], 2,
                    "t is nan, expected a finite time (s)"),
    "group_truncated": ("groups", ["0.0", "0.1 g 0 0 0 0 1 /"], 2,
                        "the groups log ends at t = 0.1 but the robot log goes on to t = 0.2 "
                        "(robot log line 3): truncated? every robot sample needs a line in the "
                        "groups log (a bare timestamp line at least)"),
}  # fmt: skip


def _case_logs(tmp_path: Path, kind: str | None = None, lines: list[str] | None = None):
    paths = {"robot": _robot(tmp_path)}
    paths["people"] = _write(tmp_path / "run_people.txt", ["0.0", P1, "0.2"])
    paths["groups"] = _bare(tmp_path, "groups")
    if kind is not None:
        _write(paths[kind], lines)
    return paths


def test_the_bad_cases_are_bad_only_where_they_say(tmp_path):
    rec = read_native(*_case_logs(tmp_path).values())
    assert rec.n_samples == 3 and rec.people_sample.tolist() == [1]


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_input_names_file_and_line(tmp_path, case):
    kind, lines, line, message = BAD_CASES[case]
    paths = _case_logs(tmp_path, kind, lines)
    with pytest.raises(InputError) as info:
        read_native(paths["robot"], paths["people"], paths["groups"])
    err = info.value
    assert (err.path, err.line, err.message) == (str(paths[kind]), line, message)
    assert str(err) == f"{paths[kind]}:{line}: {message}"


def test_a_truncated_people_log_is_blamed_not_the_groups_log(tmp_path):
    robot = _robot(tmp_path)
    people = _write(tmp_path / "run_people.txt", [PERSON_LINE.format(t=t, id=1, g="g")
                                                  for t in (0.0, 0.1)])  # fmt: skip
    groups = _write(tmp_path / "run_groups.txt",
                    [f"{t} g 3 1 0 0 1 /" for t in (0.0, 0.1, 0.2)])  # fmt: skip
    with pytest.raises(InputError) as info:
        read_native(robot, people, groups)
    assert info.value.path == str(people) and info.value.line == 2
    assert info.value.message.startswith("the people log ends at t = 0.1 but the robot log")


@pytest.mark.parametrize("kind", ["people", "groups"])
def test_empty_people_or_groups_log(tmp_path, kind):
    paths = _case_logs(tmp_path, kind, [])
    with pytest.raises(InputError) as info:
        read_native(paths["robot"], paths["people"], paths["groups"])
    assert str(info.value) == (
        f"{paths[kind]}: the {kind} log is empty: expected a line (a bare timestamp line at "
        "least) for each of the 3 robot samples"
    )


def test_line_numbers_count_newlines_only(tmp_path):
    """Windows line ends and stray form feeds do not shift the reported line."""
    path = tmp_path / "r_robot.txt"
    text = "\r\n".join([R0, R1.replace(" 0 0 0 ", " 0 \x0c 0 0 ", 1), _robot_with(0.2, x="nan")])
    path.write_bytes(text.encode())
    with pytest.raises(InputError) as info:
        read_native(path, False, False)
    assert (info.value.line, info.value.message) == (3, "x is nan, expected a finite number (m)")


@pytest.mark.parametrize("lines", [[], ["", "  ", "\t"]])
def test_empty_robot_log(tmp_path, lines):
    path = _write(tmp_path / "r_robot.txt", lines)
    with pytest.raises(InputError, match="no samples") as info:
        read_native(path, False, False)
    assert info.value.path == str(path) and info.value.line is None


@pytest.mark.parametrize("missing", ["robot", "people", "groups"])
def test_missing_file(tmp_path, missing):
    robot, people, groups = _fixture_logs("e09_fformation_2")
    paths = {"robot": tmp_path / "robot.txt", "people": tmp_path / "people.txt",
             "groups": tmp_path / "groups.txt"}  # fmt: skip
    for kind, src in (("robot", robot), ("people", people), ("groups", groups)):
        if kind != missing:
            shutil.copy(src, paths[kind])
    with pytest.raises(InputError, match="no such file") as info:
        read_native(paths["robot"], paths["people"], paths["groups"])
    assert info.value.path == str(paths[missing])


@pytest.mark.parametrize(("data", "line", "message"), [
    (b"\xff\xfe\x00binary", 1, "not a UTF-8 text file (byte 0xff): a binary file?"),
    (b"0.0 1 2\n0.1 \x89PNG\n", 2, "not a UTF-8 text file (byte 0x89): a binary file?"),
    (b"0.0 1\n\n0.1\x00\x00 2\n", 3, "not a text file (NUL byte): a binary file?"),
])  # fmt: skip
def test_binary_files_are_refused_with_their_line(tmp_path, data, line, message):
    path = tmp_path / "r_robot.txt"
    path.write_bytes(data)
    with pytest.raises(InputError) as info:
        read_native(path, False, False)
    assert (info.value.path, info.value.line, info.value.message) == (str(path), line, message)


def test_random_bytes_never_escape_as_another_error(tmp_path):
    rng = np.random.default_rng(5)
    good = _case_logs(tmp_path)
    texts = {kind: path.read_bytes() for kind, path in good.items()}
    for trial in range(300):
        kind = ("robot", "people", "groups")[trial % 3]
        data = bytearray(texts[kind])
        if trial % 2:  # truncate
            data = data[: int(rng.integers(0, len(data)))]
        for _ in range(int(rng.integers(1, 4))):  # and flip a few bytes
            if data:
                data[int(rng.integers(0, len(data)))] = int(rng.integers(0, 256))
        good[kind].write_bytes(bytes(data))
        try:
            read_native(good["robot"], good["people"], good["groups"])
        except InputError as exc:
            assert exc.path is not None and "\n" not in str(exc)
        good[kind].write_bytes(texts[kind])
