"""SRPB native text logs: reading the fixtures, both robot-line variants, round trips, errors."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.errors import InputError
from srpb_gym.metrics.io import load_episode
from srpb_gym.metrics.io_native import read_native, sibling_logs, write_native
from srpb_gym.metrics.record import PERSON_FIELDS, ROBOT_FIELDS, EpisodeRecord

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
EPISODES = sorted(p.name for p in FIXTURES.iterdir() if (p / "srpb_log").is_dir())

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
def test_fixture_write_reproduces_the_logs_byte_for_byte(name, tmp_path):
    logs = _fixture_logs(name)
    out = [tmp_path / f"log_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(read_native(*logs), *out)
    for original, written in zip(logs, out, strict=True):
        assert written.read_text() == original.read_text()


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


# ---------------------------------------------------------------------------- format details
def test_both_robot_line_variants_give_the_same_table(tmp_path):
    robot, people, groups = _fixture_logs("e05_pass_human_front")
    lines = robot.read_text().splitlines()
    newer = []
    for i, line in enumerate(lines):
        tok = line.split()
        cmd = ["0.5", "0.0", "0.0"] if i % 2 else ["nan", "inf", "-inf"]
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


def test_non_finite_numbers_are_read(tmp_path):
    line = ROBOT_LINE.format(t=0.0).split()
    line[1], line[2], line[22] = "nan", "-inf", "inf"
    rec = read_native(_write(tmp_path / "r_robot.txt", [" ".join(line)]))
    x, y, dist = rec.robot[0, [1, 2, 10]]
    assert np.isnan(x) and y == -np.inf and dist == np.inf


def test_duplicate_robot_timestamps_attach_to_the_first_sample(tmp_path):
    robot = _robot(tmp_path, (0.0, 0.1, 0.1, 0.2))
    people = _write(tmp_path / "run_people.txt", [PERSON_LINE.format(t=0.1, id=1, g="none")])
    groups = _write(tmp_path / "run_groups.txt", ["0.1 g 0 0 0 0 1 /"])
    rec = read_native(robot, people, groups)
    assert rec.people_sample.tolist() == [1] and rec.group_sample.tolist() == [1]


def test_timestamps_match_by_parsed_value(tmp_path):
    robot = _robot(tmp_path, ("0.10", "0.2"))
    people = _write(tmp_path / "run_people.txt", [PERSON_LINE.format(t="0.1000", id=1, g="x")])
    assert read_native(robot, people).people_sample.tolist() == [0]


# ---------------------------------------------------------------------------- round trip
def _random_record(rng: np.random.Generator, n: int = 40, labels: bool = False) -> EpisodeRecord:
    rec = EpisodeRecord(person_labels=["walker", "p-2", "x3"] if labels else None,
                        group_labels=["G0", "G1"] if labels else None)  # fmt: skip
    for k in range(n):
        robot = rng.normal(scale=3.0, size=12)
        robot[0] = 10.0 + 0.1 * k
        count = int(rng.integers(0, 4))
        people = rng.normal(scale=2.0, size=(count, 9))
        groups = {}
        if count >= 2 and k % 2:
            groups = {"group_ids": [1, 0], "group_sizes": [2, count - 1],
                      "group_members": [0, 1, *range(1, count)]}  # fmt: skip
        rec.append(robot, rng.permutation(3)[:count], people, **groups)
    return rec


@pytest.mark.parametrize("labels", [False, True])
def test_native_round_trip_up_to_rounding(tmp_path, labels):
    rec = _random_record(np.random.default_rng(7), labels=labels)
    paths = [tmp_path / f"e_{kind}.txt" for kind in ("robot", "people", "groups")]
    write_native(rec, *paths)
    back = load_episode(paths[0])
    assert np.allclose(back.robot, rec.robot, rtol=0, atol=5e-5 + 1e-12)
    cov = [PERSON_FIELDS.index(f) for f in ("cov_xx", "cov_xy", "cov_yx", "cov_yy")]
    other = [i for i in range(len(PERSON_FIELDS)) if i not in cov]
    assert np.allclose(back.people[:, cov], rec.people[:, cov], rtol=0, atol=5e-7 + 1e-12)
    assert np.allclose(back.people[:, other], rec.people[:, other], rtol=0, atol=5e-5 + 1e-12)
    for name in ("people_sample", "group_sample", "group_size", "group_members"):
        assert np.array_equal(getattr(back, name), getattr(rec, name)), name
    assert [back.person_label(i) for i in back.people_id] == [
        rec.person_label(i) for i in rec.people_id
    ]
    assert [back.group_label(i) for i in back.group_id] == [
        rec.group_label(i) for i in rec.group_id
    ]


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


# ---------------------------------------------------------------------------- bad input
BAD_CASES = {
    # name: (file kind, lines of that file, bad line, fragment of the message)
    "robot_columns": ("robot", [ROBOT_LINE.format(t=0), "0.1 1 2 3"], 2, "expected 24"),
    "robot_number": ("robot", [ROBOT_LINE.format(t=0).replace(" 6 ", " six ")], 1,
                     "goal_x is not a number"),
    "robot_time": ("robot", ["", ROBOT_LINE.format(t="t0")], 2, "column t is not a number"),
    "people_columns": ("people", ["0.0", PERSON_LINE.format(t=0.1, id=1, g="none") + " 7"], 2,
                       "expected 26 values on a people line (or only the timestamp), got 27"),
    "people_number": ("people", [PERSON_LINE.format(t=0.1, id=1, g="none").replace("0.02", "x")],
                      1, "column cov_xx is not a number"),
    "people_bare": ("people", ["zero"], 1, "column t is not a number"),
    "people_time": ("people", ["", "", PERSON_LINE.format(t=0.15, id=1, g="none")], 3,
                    "person at t = 0.15 matches no robot sample"),
    "group_slash": ("groups", ["0.0", "0.1 g 0 0 0 0 1"], 2, "no '/'"),
    "group_members": ("groups", ["0.1 g 0 0 0 0 /"], 1, "at least one member id"),
    "group_unknown_member": ("groups", ["0.1 g 0 0 0 0 1 7 /"], 1, "group member '7'"),
    "group_member_elsewhere": ("groups", ["0.0 g 0 0 0 0 1 /"], 1, "group member '1'"),
    "group_relations": ("groups", ["0.1 g 0 0 0 0 1 / 1 1"], 1, "triples"),
    "group_strength": ("groups", ["0.1 g 0 0 0 0 1 / 1 1 high"], 1, "strength is not a number"),
    "group_cog": ("groups", ["0.1 g x 0 0 0 1 /"], 1, "cog_x is not a number"),
    "group_time": ("groups", ["0.5 g 0 0 0 0 1 /"], 1, "group at t = 0.5 matches no robot"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_input_names_file_and_line(tmp_path, case):
    kind, lines, line, fragment = BAD_CASES[case]
    paths = {"robot": _robot(tmp_path)}
    paths["people"] = _write(tmp_path / "run_people.txt",
                             [PERSON_LINE.format(t=0.1, id=1, g="none")])  # fmt: skip
    paths["groups"] = _write(tmp_path / "run_groups.txt", ["0.1"])
    _write(paths[kind], lines)
    with pytest.raises(InputError) as info:
        read_native(paths["robot"], paths["people"], paths["groups"])
    err = info.value
    assert err.path == str(paths[kind]) and err.line == line
    assert fragment in err.message
    assert str(err).startswith(f"{paths[kind]}:{line}: ")


@pytest.mark.parametrize("lines", [[], ["", "  ", "\t"]])
def test_empty_robot_log(tmp_path, lines):
    path = _write(tmp_path / "r_robot.txt", lines)
    with pytest.raises(InputError, match="no samples") as info:
        read_native(path)
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


def test_not_text(tmp_path):
    path = tmp_path / "r_robot.txt"
    path.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(InputError, match="UTF-8"):
        read_native(path)
