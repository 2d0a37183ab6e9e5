"""srpb-gym's own episode format: one ``.npz`` file holding an :class:`EpisodeRecord` exactly.

The record is stored bit for bit (as are native logs written at full precision), so a
record read back evaluates to bit-identical metrics. The file is a plain
(uncompressed) numpy ``.npz`` archive, readable with ``numpy.load(path, allow_pickle=False)``.

Layout (N robot samples, P people rows, G group rows, M group memberships; units are SI:
m, s, rad, m/s, rad/s, m^2):

======================  =======  ==========  ================================================
key                     dtype    shape       content
======================  =======  ==========  ================================================
``format``              unicode  ()          ``"srpb-gym-record"``
``format_version``      int64    ()          ``1``; readers refuse newer versions
``robot_fields``        unicode  (12,)       column names of ``robot`` (``ROBOT_FIELDS``)
``person_fields``       unicode  (9,)        column names of ``people`` (``PERSON_FIELDS``)
``robot``               float64  (N, 12)     t [s], x, y [m], yaw [rad], body-frame vx, vy
                                             [m/s], omega [rad/s], goal_x, goal_y [m],
                                             goal_yaw [rad], obstacle_dist [m],
                                             planning_time [s]
``people``              float64  (P, 9)      x, y [m], yaw [rad], cov_xx, cov_xy, cov_yx,
                                             cov_yy [m^2], global-frame vx, vy [m/s]
``people_sample``       int64    (P,)        robot sample of each people row (non-decreasing)
``people_id``           int64    (P,)        person id of each people row
``group_sample``        int64    (G,)        robot sample of each group row (non-decreasing)
``group_id``            int64    (G,)        group id of each group row
``group_size``          int64    (G,)        number of members of each group row (>= 1)
``group_members``       int64    (M,)        people rows of the members, group after group
``person_labels``       unicode  (L,)        text of person id k at index k; absent if none
``group_labels``        unicode  (K,)        text of group id k at index k; absent if none
======================  =======  ==========  ================================================

``group_start`` (where each group's members begin in ``group_members``) is not stored: it is
the exclusive cumulative sum of ``group_size``. ``planning_time`` is NaN at a sample where
no decision was timed (the final sample of a simulated run); every other value is finite,
and :func:`load_record` refuses a file with a value that cannot be right.
"""

from __future__ import annotations

import os
import struct
import zipfile
import zlib

import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.metrics.record import (
    PERSON_FIELDS,
    ROBOT_FIELDS,
    EpisodeRecord,
    invalid_person_row,
    invalid_robot_row,
)

FORMAT = "srpb-gym-record"
FORMAT_VERSION = 1

_INT_KEYS = ("people_sample", "people_id", "group_sample", "group_id", "group_size",
             "group_members")  # fmt: skip
_LABEL_KEYS = ("person_labels", "group_labels")


def save_record(record: EpisodeRecord, path: str | os.PathLike) -> None:
    """Write ``record`` to ``path`` (exactly that name; ``.npz`` is the customary suffix)."""
    arrays: dict[str, np.ndarray] = {
        "format": np.array(FORMAT),
        "format_version": np.array(FORMAT_VERSION, dtype=np.int64),
        "robot_fields": np.array(ROBOT_FIELDS),
        "person_fields": np.array(PERSON_FIELDS),
        "robot": np.ascontiguousarray(record.robot, dtype=np.float64),
        "people": np.ascontiguousarray(record.people, dtype=np.float64),
    }
    for key in _INT_KEYS:
        arrays[key] = np.ascontiguousarray(getattr(record, key), dtype=np.int64)
    for key in _LABEL_KEYS:
        labels = getattr(record, key)
        if labels is not None:
            arrays[key] = np.array(list(labels), dtype=np.str_).reshape(len(labels))
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def load_record(path: str | os.PathLike) -> EpisodeRecord:
    """Read a record written by :func:`save_record`.

    Raises :class:`InputError` naming the file (and the key) when the file is missing, is
    not an srpb-gym record (not an ``.npz`` archive, damaged, holding pickled objects or
    foreign arrays), has a newer format version, lacks a key, holds inconsistent tables or
    a value that cannot be right: the rules of the native logs
    (:func:`~srpb_gym.metrics.record.invalid_robot_row`,
    :func:`~srpb_gym.metrics.record.invalid_person_row`): finite values, times that do not
    decrease, valid covariances; ``planning_time`` may be NaN (no decision timed at that
    sample, as in the final sample of a simulated run).
    """
    arrays = _read_arrays(path)
    if "format" not in arrays:
        raise InputError(f"{_NOT_OURS} (no 'format' key)", path, key="format")
    _check_header(arrays, path)
    tables = {key: _get(arrays, key, path, np.float64, 2) for key in ("robot", "people")}
    tables.update({key: _get(arrays, key, path, np.int64, 1) for key in _INT_KEYS})
    group_keys = _INT_KEYS[2:]
    if not any(tables[key].size for key in group_keys):
        tables.update(dict.fromkeys(group_keys))  # no groups: keep the record's tables empty
    labels = {key: _labels(arrays, key, path) for key in _LABEL_KEYS}
    try:
        record = EpisodeRecord.from_arrays(**tables, **labels)
    except ValueError as exc:
        raise InputError(f"inconsistent tables: {exc}", path) from None
    problem = invalid_robot_row(record.robot)
    if problem is not None:
        raise InputError(f"sample {problem[0]}: {problem[1]}", path, key="robot")
    problem = invalid_person_row(record.people)
    if problem is not None:
        row, why = problem
        msg = f"row {row} (sample {int(record.people_sample[row])}): {why}"
        raise InputError(msg, path, key="people")
    return record


_NOT_OURS = f"not an {FORMAT.replace('-record', ' record')}"  # "not an srpb-gym record"
_DAMAGED = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, KeyError,
            UnicodeDecodeError, SyntaxError, struct.error, NotImplementedError)  # fmt: skip


def _read_arrays(path) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` file ``path``; :class:`InputError` for anything else."""
    try:
        data = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise InputError("no such file", path) from None
    except IsADirectoryError:
        raise InputError("is a directory, not an .npz file", path) from None
    except PermissionError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path) from None
    except _DAMAGED:
        raise InputError(f"{_NOT_OURS} (not a numpy .npz archive)", path) from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise InputError(f"{_NOT_OURS} (a single .npy array, not an .npz archive)", path)
    arrays: dict[str, np.ndarray] = {}
    with data:
        try:
            names = list(data.files)
        except _DAMAGED:
            raise InputError(f"{_NOT_OURS} (a damaged .npz archive)", path) from None
        for key in names:
            try:
                value = data[key]
            except ValueError as exc:
                why = "pickled objects" if "pickle" in str(exc) else "no readable array"
                raise InputError(f"{_NOT_OURS} (the entry holds {why})", path, key=key) from None
            except _DAMAGED:
                msg = f"{_NOT_OURS} (a damaged .npz archive)"
                raise InputError(msg, path, key=key) from None
            if not isinstance(value, np.ndarray):
                msg = f"{_NOT_OURS} (the entry is not a numpy array)"
                raise InputError(msg, path, key=key)
            arrays[key] = value
    return arrays


def _check_header(arrays: dict[str, np.ndarray], path) -> None:
    fmt = arrays["format"]
    if fmt.shape != () or fmt.dtype.kind != "U" or str(fmt) != FORMAT:
        raise InputError(f"{_NOT_OURS} (format is not {FORMAT!r})", path, key="format")
    version = _get(arrays, "format_version", path, np.int64, 0)
    if int(version) > FORMAT_VERSION:
        msg = f"format version {int(version)} is newer than this reader's {FORMAT_VERSION}"
        raise InputError(msg, path, key="format_version")
    if int(version) < 1:
        raise InputError(f"invalid format version {int(version)}", path, key="format_version")
    for key, expected in (("robot_fields", ROBOT_FIELDS), ("person_fields", PERSON_FIELDS)):
        names = arrays.get(key)
        if names is None:
            raise InputError("missing key", path, key=key)
        if names.ndim != 1 or tuple(names.tolist()) != expected:
            raise InputError(f"columns differ from {', '.join(expected)}", path, key=key)


def _get(arrays: dict[str, np.ndarray], key: str, path, dtype, ndim: int) -> np.ndarray:
    """The array ``key``, checked for dtype, number of dimensions and column count."""
    if key not in arrays:
        raise InputError("missing key", path, key=key)
    value = arrays[key]
    if value.dtype != dtype or value.ndim != ndim:
        msg = f"expected {np.dtype(dtype).name} with {ndim} dimension(s), got {value.dtype}"
        raise InputError(f"{msg} with {value.ndim}", path, key=key)
    width = {"robot": len(ROBOT_FIELDS), "people": len(PERSON_FIELDS)}.get(key)
    if width is not None and value.shape[1] != width:
        raise InputError(f"expected {width} columns, got {value.shape[1]}", path, key=key)
    return value


def _labels(arrays: dict[str, np.ndarray], key: str, path) -> tuple[str, ...] | None:
    if key not in arrays:
        return None
    value = arrays[key]
    if value.dtype.kind != "U" or value.ndim != 1:
        raise InputError(f"expected a 1-D unicode array, got {value.dtype}", path, key=key)
    return tuple(value.tolist())
