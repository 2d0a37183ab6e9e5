"""srpb-gym's .npz record format: bit-exact round trips and refusal of foreign files."""

from __future__ import annotations

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
    """Values that text formats lose: full precision, -0.0, NaN, infinities, tiny numbers."""
    rng = np.random.default_rng(11)
    rec = EpisodeRecord(person_labels=["anna", "bo", "ünïcode"], group_labels=[""])
    for k in range(25):
        robot = rng.normal(size=12) * 10.0 ** rng.integers(-12, 12, size=12)
        robot[0] = k / 3.0
        if k == 3:
            robot[1:5] = [np.nan, np.inf, -np.inf, -0.0]
        people = rng.normal(size=(3, 9)) / 7.0
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
    with pytest.raises(InputError, match="not an srpb-gym-record file") as info:
        load_record(path)
    assert info.value.key == "format"
    np.save(tmp_path / "single.npy", np.zeros(3))
    with pytest.raises(InputError, match="not an srpb-gym-record"):
        load_record(tmp_path / "single.npy")
    (tmp_path / "text.npz").write_text("hello")
    with pytest.raises(InputError, match="not a readable"):
        load_record(tmp_path / "text.npz")


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such file") as info:
        load_episode(tmp_path / "nothing.npz")
    assert info.value.path == str(tmp_path / "nothing.npz")


def test_pickled_objects_are_refused(tmp_path):
    arrays = _saved(tmp_path)
    arrays["person_labels"] = np.array(["a", None], dtype=object)
    with pytest.raises(InputError):
        load_record(_episode(tmp_path / "bad.npz", **arrays))
