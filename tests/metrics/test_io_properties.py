"""Properties of the log readers: a valid record always reads back exactly; a log or record
holding a non-finite value where the metrics need a number, a negative variance or a
covariance that is not positive semi-definite is always refused, at its file and line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from srpb_gym.errors import InputError
from srpb_gym.metrics.io_native import (
    PERSON_COLUMNS,
    ROBOT_COLUMNS,
    read_native,
    write_native,
)
from srpb_gym.metrics.io_npz import load_record, save_record
from srpb_gym.metrics.record import PERSON_FIELDS, ROBOT_FIELDS, EpisodeRecord

NON_FINITE = ["nan", "NaN", "-nan", "+nan", "inf", "-inf", "+inf", "Infinity", "-INFINITY",
              "1e999", "-1e400"]  # fmt: skip
NOT_NAN = [tok for tok in NON_FINITE if "nan" not in tok.lower()]
SETTINGS = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip


def _record(seed: int) -> EpisodeRecord:
    """A valid record: 2 to 6 samples, 0 to 3 people each, some in groups, a NaN final
    planning time; values of every magnitude."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 7))
    rec = EpisodeRecord()
    t = float(rng.uniform(-10.0, 10.0))
    for k in range(n):
        robot = rng.normal(size=12) * 10.0 ** rng.integers(-6, 4, size=12)
        t += float(rng.uniform(0.0, 1.0)) if k else 0.0
        robot[0] = t
        robot[11] = abs(robot[11]) if k < n - 1 else np.nan
        count = int(rng.integers(0, 4))
        people = rng.normal(size=(count, 9)) * 10.0 ** rng.integers(-3, 3, size=(count, 9))
        a = rng.normal(size=(count, 2, 2)) * 10.0 ** rng.integers(-3, 2, size=(count, 1, 1))
        people[:, 3:7] = (a @ a.transpose(0, 2, 1)).reshape(count, 4)
        groups = {}
        if count >= 2:
            groups = {"group_ids": [0], "group_sizes": [count], "group_members": range(count)}
        rec.append(robot, range(count), people, **groups)
    return rec


def _finite(token: str) -> bool:
    return bool(np.isfinite(float(token)))


def _written(rec: EpisodeRecord, folder: Path) -> dict[str, Path]:
    paths = {kind: folder / f"e_{kind}.txt" for kind in ("robot", "people", "groups")}
    write_native(rec, paths["robot"], paths["people"], paths["groups"])
    return paths


@st.composite
def corruptions(draw):
    """(kind, which line among those of that kind, token index, bad token, field name)."""
    kind = draw(st.sampled_from(["robot", "people", "groups"]))
    if kind == "robot":
        field = draw(st.sampled_from(ROBOT_FIELDS))
        token = draw(st.sampled_from(NOT_NAN if field == "planning_time" else NON_FINITE))
        return kind, draw(st.integers(0, 99)), ROBOT_COLUMNS.index(field), token, field
    if kind == "groups":
        return kind, draw(st.integers(0, 99)), 0, draw(st.sampled_from(NON_FINITE)), "t"
    field = draw(st.sampled_from(("t", *PERSON_FIELDS, "negative variance")))
    if field == "negative variance":
        field = draw(st.sampled_from(["cov_xx", "cov_yy"]))
        token = repr(-draw(st.floats(1e-6, 1e6)))
    else:
        token = draw(st.sampled_from(NON_FINITE))
    return kind, draw(st.integers(0, 99)), PERSON_COLUMNS.index(field), token, field


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_valid_records_read_back_bit_for_bit(tmp_path, seed):
    rec = _record(seed)
    back = read_native(*_written(rec, tmp_path).values())
    assert back.robot.tobytes() == rec.robot.tobytes()
    assert back.people.tobytes() == rec.people.tobytes()
    assert np.array_equal(back.people_sample, rec.people_sample)
    assert np.array_equal(back.group_members, rec.group_members)
    save_record(rec, tmp_path / "e.npz")
    assert load_record(tmp_path / "e.npz").robot.tobytes() == rec.robot.tobytes()


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), bad=corruptions())
def test_a_log_with_a_value_that_cannot_be_right_is_refused(tmp_path, seed, bad):
    kind, pick, column, token, field = bad
    paths = _written(_record(seed), tmp_path)
    lines = paths[kind].read_text().splitlines()
    width = len(PERSON_COLUMNS) if kind == "people" else None
    candidates = [i for i, line in enumerate(lines) if width is None or len(line.split()) == width]
    if not candidates:  # nobody at any sample: corrupt a bare timestamp line instead
        candidates, column, field = list(range(len(lines))), 0, "t"
        token = token if not _finite(token) else "nan"
    i = candidates[pick % len(candidates)]
    tokens = lines[i].split()
    tokens[column] = token
    lines[i] = " ".join(tokens)
    paths[kind].write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as info:
        read_native(paths["robot"], paths["people"], paths["groups"])
    err = info.value
    assert (err.path, err.line) == (str(paths[kind]), i + 1), str(err)
    assert err.message.startswith(f"{field} is "), str(err)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), data=st.data())
def test_a_record_with_a_value_that_cannot_be_right_is_refused(tmp_path, seed, data):
    rec = _record(seed)
    robot, people = rec.robot.copy(), rec.people.copy()
    if people.shape[0] and data.draw(st.booleans()):
        table, key, fields = people, "people", PERSON_FIELDS
    else:
        table, key, fields = robot, "robot", ROBOT_FIELDS
    row = data.draw(st.integers(0, table.shape[0] - 1))
    col = data.draw(st.integers(0, len(fields) - 1))
    if key == "people" and fields[col] in ("cov_xx", "cov_yy") and data.draw(st.booleans()):
        table[row, col] = -data.draw(st.floats(1e-6, 1e6))
    else:
        choices = NOT_NAN if fields[col] == "planning_time" else NON_FINITE
        table[row, col] = float(data.draw(st.sampled_from(choices)))
    bad = EpisodeRecord.from_arrays(robot, people, rec.people_sample, rec.people_id,
                                    rec.group_sample, rec.group_id, rec.group_size,
                                    rec.group_members)  # fmt: skip
    save_record(bad, tmp_path / "bad.npz")
    with pytest.raises(InputError) as info:
        load_record(tmp_path / "bad.npz")
    assert info.value.key == key and f"{fields[col]} is " in info.value.message
