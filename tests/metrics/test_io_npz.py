"""srpb-gym's .npz record format: bit-exact round trips and refusal of foreign files."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest

from srpb_gym.errors import InputError
from srpb_gym.metrics.io import load_episode
from srpb_gym.metrics.io_native import read_native
from srpb_gym.metrics.io_npz import FORMAT, FORMAT_VERSION, load_record, save_record
from srpb_gym.metrics.record import EpisodeRecord

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
TABLES = ("robot", "people", "people_sample", "people_id", "group_sample", "group_id",
          "group_start", "group_size", "group_members")  # fmt: skip


def _assert_bit_exact(a: EpisodeRecord, b: EpisodeRecord) -> None:
    for name in TABLES:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), name
    assert a.person_labels == b.person_labels
    assert a.group_labels == b.group_labels


def _awkward_record() -> EpisodeRecord:
    """Values that fixed-point text loses: full precision, -0.0, subnormal and huge numbers,
    NaN planning times (no decision timed)."""
    rng = np.random.default_rng(11)
    rec = EpisodeRecord(person_labels=["anna", "bo", "ünïcode"], group_labels=[""])
    for k in range(25):
        robot = rng.normal(size=12) * 10.0 ** rng.integers(-12, 12, size=12)
        robot[0] = k / 3.0
        robot[11] = abs(robot[11]) if k % 5 else np.nan
        if k == 3:
            robot[1:5] = [5e-324, 1e300, -1e-300, -0.0]
        people = rng.normal(size=(3, 9)) / 7.0
        a = rng.normal(size=(3, 2, 2))
        people[:, 3:7] = (a @ a.transpose(0, 2, 1)).reshape(3, 4)  # covariances
        groups = {"group_ids": [0], "group_sizes": [2], "group_members": [2, 0]} if k % 4 else {}
        rec.append(robot, [2, 0, 1], people, **groups)
    return rec


def _episode(path: Path, **arrays) -> Path:
    np.savez(path, **arrays)
    return path


@pytest.mark.parametrize("name", ["e01_forward_no_humans", "e09_fformation_2",
                                  "e17_fformation_5"])  # fmt: skip
def test_round_trip_of_fixtures_is_bit_exact(tmp_path, name):
    log = FIXTURES / name / "srpb_log"
    rec = read_native(log / "log_robot.txt", log / "log_people.txt", log / "log_groups.txt")
    save_record(rec, tmp_path / "e.npz")
    _assert_bit_exact(load_record(tmp_path / "e.npz"), rec)


def test_round_trip_keeps_every_bit_and_the_labels(tmp_path):
    rec = _awkward_record()
    save_record(rec, tmp_path / "e.npz")
    back = load_episode(tmp_path / "e.npz")
    _assert_bit_exact(back, rec)
    assert back.person_labels == ("anna", "bo", "ünïcode") and back.group_labels == ("",)


@pytest.mark.parametrize("labels", [None, ()])
def test_round_trip_of_robot_only_records(tmp_path, labels):
    rec = EpisodeRecord(person_labels=labels, group_labels=labels)
    rec.append(np.arange(12.0))
    save_record(rec, tmp_path / "e.npz")
    back = load_record(tmp_path / "e.npz")
    _assert_bit_exact(back, rec)
    assert back.people.shape == (0, 9) and back.group_start.size == 0


def test_empty_record_round_trips(tmp_path):
    save_record(EpisodeRecord(), tmp_path / "e.npz")
    back = load_record(tmp_path / "e.npz")
    assert back.n_samples == 0 and back.robot.shape == (0, 12)


def test_layout_keys_and_dtypes(tmp_path):
    save_record(_awkward_record(), tmp_path / "e.rec")  # written under exactly this name
    with np.load(tmp_path / "e.rec", allow_pickle=False) as data:
        assert str(data["format"]) == FORMAT and int(data["format_version"]) == FORMAT_VERSION
        assert data["robot"].dtype == np.float64 and data["robot"].shape == (25, 12)
        assert data["people"].dtype == np.float64 and data["people"].shape == (75, 9)
        for key in ("people_sample", "people_id", "group_sample", "group_id", "group_size",
                    "group_members"):  # fmt: skip
            assert data[key].dtype == np.int64 and data[key].ndim == 1
        assert data["person_labels"].dtype.kind == "U"
        assert "group_start" not in data.files


def test_labels_are_absent_when_none(tmp_path):
    rec = EpisodeRecord()
    rec.append(np.zeros(12))
    save_record(rec, tmp_path / "e.npz")
    with np.load(tmp_path / "e.npz") as data:
        assert "person_labels" not in data.files and "group_labels" not in data.files


# ---------------------------------------------------------------------------- refusals
def _saved(tmp_path: Path) -> dict[str, np.ndarray]:
    save_record(_awkward_record(), tmp_path / "good.npz")
    with np.load(tmp_path / "good.npz") as data:
        return {key: data[key] for key in data.files}


@pytest.mark.parametrize("key", ["robot", "people_id", "group_members", "format_version",
                                 "robot_fields"])  # fmt: skip
def test_missing_key(tmp_path, key):
    arrays = _saved(tmp_path)
    del arrays[key]
    path = _episode(tmp_path / "bad.npz", **arrays)
    with pytest.raises(InputError, match="missing key") as info:
        load_record(path)
    assert info.value.path == str(path) and info.value.key == key
    assert str(info.value) == f"{path}: {key}: missing key"


def test_newer_version(tmp_path):
    arrays = _saved(tmp_path)
    arrays["format_version"] = np.array(FORMAT_VERSION + 1, dtype=np.int64)
    with pytest.raises(InputError, match="newer") as info:
        load_record(_episode(tmp_path / "bad.npz", **arrays))
    assert info.value.key == "format_version"


@pytest.mark.parametrize("change", [
    {"format": np.array("something-else")},
    {"robot": np.zeros((3, 11))},
    {"robot": np.zeros((3, 12), dtype=np.float32)},
    {"people_id": np.zeros(75, dtype=np.int32)},
    {"person_fields": np.array(["a", "b"])},
    {"person_labels": np.array([1, 2, 3])},
])  # fmt: skip
def test_foreign_content(tmp_path, change):
    arrays = _saved(tmp_path) | change
    path = _episode(tmp_path / "bad.npz", **arrays)
    with pytest.raises(InputError) as info:
        load_record(path)
    assert info.value.path == str(path) and info.value.key == next(iter(change))


def test_inconsistent_tables(tmp_path):
    arrays = _saved(tmp_path)
    arrays["group_members"] = arrays["group_members"] + 1000
    with pytest.raises(InputError, match="inconsistent"):
        load_record(_episode(tmp_path / "bad.npz", **arrays))


def test_not_one_of_ours(tmp_path):
    path = _episode(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(InputError) as info:
        load_record(path)
    assert str(info.value) == f"{path}: format: not an srpb-gym record (no 'format' key)"
    np.save(tmp_path / "single.npy", np.zeros(3))
    with pytest.raises(InputError) as info:
        load_record(tmp_path / "single.npy")
    assert str(info.value) == (f"{tmp_path}/single.npy: not an srpb-gym record (a single .npy "
                               "array, not an .npz archive)")  # fmt: skip


@pytest.mark.parametrize("data", [b"hello", b"", b"PK\x03\x04garbage", b"\x93NUMPY\x01\x00{",
                                  bytes(range(256)) * 4])  # fmt: skip
def test_garbage_is_not_an_srpb_gym_record(tmp_path, data):
    """Never numpy's message (which suggests allow_pickle), never a traceback."""
    path = tmp_path / "garbage.npz"
    path.write_bytes(data)
    with pytest.raises(InputError) as info:
        load_record(path)
    assert str(info.value) == f"{path}: not an srpb-gym record (not a numpy .npz archive)"


def test_entries_that_are_not_arrays(tmp_path):
    path = tmp_path / "zip.npz"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("format", "srpb-gym-record")
    with pytest.raises(InputError) as info:
        load_record(path)
    assert (
        str(info.value) == f"{path}: format: not an srpb-gym record (the entry is not a "
        "numpy array)"
    )


def test_damaged_archives_give_one_located_line(tmp_path):
    save_record(_awkward_record(), tmp_path / "good.npz")
    good = (tmp_path / "good.npz").read_bytes()
    rng = np.random.default_rng(2)
    path = tmp_path / "bad.npz"
    for trial in range(200):
        data = bytearray(good)
        if trial % 2:
            data = data[: int(rng.integers(0, len(data)))]
        for _ in range(int(rng.integers(1, 6))):
            if data:
                data[int(rng.integers(0, len(data)))] = int(rng.integers(0, 256))
        path.write_bytes(bytes(data))
        try:
            load_record(path)
        except InputError as exc:
            assert exc.path == str(path) and "\n" not in str(exc)
            assert "allow_pickle" not in str(exc)


@pytest.mark.parametrize(("table", "row", "col", "value", "message"), [
    ("robot", 4, 1, np.nan, "sample 4: x is nan, expected a finite number (m)"),
    ("robot", 2, 0, np.nan, "sample 2: t is nan, expected a finite number (s)"),
    ("robot", 7, 10, -np.inf, "sample 7: obstacle_dist is -inf, expected a finite number (m)"),
    ("robot", 1, 11, np.inf,
     "sample 1: planning_time is inf, expected a time >= 0 s (or nan: no decision at this "
     "sample)"),
    ("robot", 3, 0, -5.0,
     "sample 3: t = -5.0 is earlier than the previous sample's t = 0.6666666666666666: robot "
     "times must not decrease"),
    ("people", 5, 8, np.nan, "row 5 (sample 1): vy is nan, expected a finite number (m/s)"),
    ("people", 6, 3, -1.0, "row 6 (sample 2): cov_xx is -1.0: a variance cannot be negative (m^2)"),
    ("people", 0, 5, 100.0,
     "row 0 (sample 0): cov_yx is 100.0, larger in magnitude than sqrt(cov_xx * cov_yy) = "),
])  # fmt: skip
def test_values_that_cannot_be_right_are_refused(tmp_path, table, row, col, value, message):
    arrays = _saved(tmp_path)
    arrays[table] = arrays[table].copy()
    arrays[table][row, col] = value
    path = _episode(tmp_path / "bad.npz", **arrays)
    with pytest.raises(InputError) as info:
        load_record(path)
    assert info.value.path == str(path) and info.value.key == table
    assert info.value.message.startswith(message)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such file") as info:
        load_episode(tmp_path / "nothing.npz")
    assert info.value.path == str(tmp_path / "nothing.npz")


def test_pickled_objects_are_refused(tmp_path):
    arrays = _saved(tmp_path)
    arrays["person_labels"] = np.array(["a", None], dtype=object)
    with pytest.raises(InputError):
        load_record(_episode(tmp_path / "bad.npz", **arrays))
