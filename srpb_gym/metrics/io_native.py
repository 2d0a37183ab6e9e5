"""Reading and writing the SRPB reference logger's native text logs.

An SRPB run is logged as three whitespace-separated text files (see ``METRICS.md``,
"SRPB native text logs"): ``*_robot.txt`` (one line per robot sample), ``*_people.txt``
(one line per tracked person per sample, or a line holding only the timestamp) and
``*_groups.txt`` (one line per F-formation per sample, or a bare timestamp line). Units are
SI (m, s, rad, m/s, rad/s, m^2); velocities of the robot are body-frame, those of people
global-frame.

Reading rules:

- Blank lines are skipped; line numbers in errors are 1-based and count every line.
- Robot lines hold t + 23 values, or t + 26 values (a newer logger inserts ``cmd_vx cmd_vy
  cmd_omega`` before ``obstacle_dist``); both may appear in one file.
- Numbers are read as Python's ``float()`` reads them, so ``nan``, ``inf`` and ``-inf``
  are accepted.
- People and groups are matched to robot samples by equal timestamps (float equality of the
  parsed numbers). When the robot log repeats a timestamp, people and groups at that time
  are attached to the first robot sample carrying it.
- Person and group ids are text; each distinct text gets an integer code in order of first
  appearance in its file, and the texts become the record's ``person_labels`` /
  ``group_labels`` (``None`` when the file holds no id).
- Group members are looked up among the people of the group's own sample (the first person
  row with that id when an id repeats at one sample). The people log's group column is
  checked for presence only: groups come from the groups log alone.

Any malformed input raises :class:`srpb_gym.errors.InputError` naming the file and line.
"""

from __future__ import annotations

import gc
import os
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from srpb_gym.errors import InputError
from srpb_gym.metrics.record import PERSON_FIELDS, ROBOT_FIELDS, EpisodeRecord

PathLike = str | os.PathLike

_POSE_COV = ("cov_xx", "cov_xy", "cov_yx", "cov_yy", "cov_yawyaw")
_VEL_COV = tuple("v" + name for name in _POSE_COV)
ROBOT_COLUMNS: tuple[str, ...] = (
    "t", "x", "y", "z", "yaw", *_POSE_COV, "vx", "vy", "vz", "omega", *_VEL_COV,
    "goal_x", "goal_y", "goal_yaw", "obstacle_dist", "planning_time",
)  # fmt: skip
"""Columns of a robot line, t + 23 values."""
ROBOT_COLUMNS_CMD: tuple[str, ...] = (
    *ROBOT_COLUMNS[:22], "cmd_vx", "cmd_vy", "cmd_omega", *ROBOT_COLUMNS[22:]
)  # fmt: skip
"""Columns of a robot line of the newer logger, t + 26 values."""
PERSON_COLUMNS: tuple[str, ...] = (
    "t", "id", "reliability", "x", "y", "z", "yaw", *_POSE_COV, "vx", "vy", "vz", "omega",
    *_VEL_COV, "detection_id", "track_age", "matched", "occluded", "group",
)  # fmt: skip
"""Columns of a people line (26 tokens)."""
GROUP_HEAD: tuple[str, ...] = ("t", "id", "cog_x", "cog_y", "cog_z", "age")
"""Leading columns of a groups line, followed by member ids, ``/`` and relation triples."""

_PERSON_NUMERIC = (0, *range(2, 25))
_PERSON_TAKE = [_PERSON_NUMERIC.index(PERSON_COLUMNS.index(f)) for f in PERSON_FIELDS]


# ---------------------------------------------------------------------------- reading
def sibling_logs(robot_path: PathLike) -> tuple[Path | None, Path | None]:
    """The ``*_people.txt`` and ``*_groups.txt`` logs beside a ``*_robot.txt`` log.

    Each is ``None`` when the robot log's name does not end in ``_robot.txt`` or when the
    sibling file does not exist.
    """
    path = Path(robot_path)
    if not path.name.endswith("_robot.txt"):
        return None, None
    stem = path.name[: -len("robot.txt")]
    found = [path.with_name(stem + kind + ".txt") for kind in ("people", "groups")]
    people, groups = (p if p.is_file() else None for p in found)
    return people, groups


def read_native(
    robot_path: PathLike, people_path: PathLike | None = None, groups_path: PathLike | None = None
) -> EpisodeRecord:
    """Read an episode from SRPB native logs; people and groups logs are optional.

    Raises :class:`InputError` (file and 1-based line) for any malformed input.
    """
    robot = _read_robot(robot_path)
    t_robot = robot[:, 0]
    people = _People.empty() if people_path is None else _read_people(people_path, t_robot)
    groups, g_labels = _read_groups(groups_path, t_robot, people)
    return EpisodeRecord.from_arrays(
        robot, people.table, people.sample, people.code, *groups,
        person_labels=people.labels, group_labels=g_labels,
    )  # fmt: skip


@contextmanager
def _gc_paused():
    """Pause the cyclic garbage collector while building many small lists (much faster)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _read_text(path: PathLike) -> str:
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except FileNotFoundError:
        raise InputError("no such file", path) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a log file", path) from None
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None


class _Lines:
    """The non-blank lines of a log file: 1-based numbers, texts, tokens and token counts."""

    def __init__(self, path: PathLike) -> None:
        self.path = path
        text = _read_text(path)
        self.ascii = text.isascii()
        self.numbers: list[int] = []
        self.texts: list[str] = []
        self.rows: list[list[str]] = []
        with _gc_paused():
            for i, line in enumerate(text.splitlines(), start=1):
                tokens = line.split()
                if tokens:
                    self.numbers.append(i)
                    self.texts.append(line)
                    self.rows.append(tokens)
        self.widths = np.fromiter(map(len, self.rows), dtype=np.int64, count=len(self.rows))

    def error(self, message: str, i: int) -> InputError:
        """An error located at the ``i``-th non-blank line."""
        return InputError(message, self.path, self.numbers[i])

    def floats(self, sel: Sequence[int], cols: Sequence[int], names: Sequence[str]) -> NDArray:
        """Token columns ``cols`` (named ``names``) of the lines ``sel`` as float64 numbers."""
        if len(sel) == 0:
            return np.zeros((0, len(cols)))
        if self.ascii:  # fast path; its whitespace splitting equals str.split() on ASCII
            try:
                texts = [self.texts[i] for i in sel]
                return np.loadtxt(texts, np.float64, comments=None, usecols=cols, ndmin=2)
            except ValueError:
                pass  # locate the bad token below
        tokens = [[self.rows[i][c] for c in cols] for i in sel]
        for i, row in zip(sel, tokens, strict=True):
            for name, token in zip(names, row, strict=True):
                try:
                    float(token)
                except ValueError:
                    raise self.error(f"column {name} is not a number: {token!r}", i) from None
        return np.array(tokens, dtype=np.float64).reshape(len(sel), len(cols))


def _read_robot(path: PathLike) -> NDArray[np.float64]:
    lines = _Lines(path)
    if not lines.rows:
        raise InputError("the robot log holds no samples", path)
    widths = lines.widths
    bad = np.flatnonzero((widths != len(ROBOT_COLUMNS)) & (widths != len(ROBOT_COLUMNS_CMD)))
    if bad.size:
        msg = (f"expected {len(ROBOT_COLUMNS)} values (t + 23) or {len(ROBOT_COLUMNS_CMD)} "
               f"(t + 26) on a robot line, got {widths[bad[0]]}")  # fmt: skip
        raise lines.error(msg, bad[0])
    robot = np.empty((len(lines.rows), len(ROBOT_FIELDS)))
    for names in (ROBOT_COLUMNS, ROBOT_COLUMNS_CMD):
        sel = np.flatnonzero(widths == len(names))
        if sel.size:
            values = lines.floats(sel, range(len(names)), names)
            robot[sel] = values[:, [names.index(f) for f in ROBOT_FIELDS]]
    return robot


def _check_bare(lines: _Lines) -> None:
    """Bare timestamp lines must hold a number."""
    lines.floats(np.flatnonzero(lines.widths == 1), (0,), ("t",))


def _match_samples(t: NDArray, t_robot: NDArray, tokens, lines: _Lines, sel, what: str) -> NDArray:
    """Index of the first robot sample whose time equals each of ``t`` (lines ``sel``)."""
    order = np.argsort(t_robot, kind="stable")
    t_sorted = t_robot[order]
    pos = np.minimum(np.searchsorted(t_sorted, t, side="left"), t_sorted.size - 1)
    bad = np.flatnonzero(t_sorted[pos] != t)
    if bad.size:
        i = bad[0]
        msg = f"{what} at t = {tokens[i]} matches no robot sample (no robot line has that time)"
        raise lines.error(msg, sel[i])
    return order[pos]


def _codes(texts: Sequence[str]) -> tuple[NDArray[np.int64], tuple[str, ...] | None]:
    """Integer codes of id texts, numbered by first appearance, and the texts in code order."""
    mapping: dict[str, int] = {}
    codes = np.fromiter(
        (mapping.setdefault(s, len(mapping)) for s in texts), dtype=np.int64, count=len(texts)
    )
    return codes, (tuple(mapping) if mapping else None)


class _People:
    """The people table as read, sorted stably by sample, and its ids' texts."""

    def __init__(self, table, sample, code, labels) -> None:
        self.table, self.sample, self.code, self.labels = table, sample, code, labels
        self.code_of = {label: k for k, label in enumerate(labels or ())}

    @classmethod
    def empty(cls) -> _People:
        ints = np.zeros(0, dtype=np.int64)
        return cls(np.zeros((0, len(PERSON_FIELDS))), ints, ints, None)

    def find(self, sample: NDArray, ids: Sequence[str]) -> NDArray[np.int64]:
        """The first people row with each id text at each sample, -1 where there is none."""
        code = np.fromiter((self.code_of.get(s, -1) for s in ids), dtype=np.int64, count=len(ids))
        if not self.sample.size:
            return np.full(code.shape, -1, dtype=np.int64)
        width = len(self.code_of) + 1
        keys = self.sample * width + self.code
        order = np.argsort(keys, kind="stable")  # equal keys keep their row order
        wanted = sample * width + code
        pos = np.minimum(np.searchsorted(keys[order], wanted), keys.size - 1)
        return np.where((keys[order][pos] == wanted) & (code >= 0), order[pos], -1)


def _read_people(path: PathLike, t_robot: NDArray) -> _People:
    lines = _Lines(path)
    widths = lines.widths
    bad = np.flatnonzero((widths != 1) & (widths != len(PERSON_COLUMNS)))
    if bad.size:
        msg = (f"expected {len(PERSON_COLUMNS)} values on a people line (or only the "
               f"timestamp), got {widths[bad[0]]}")  # fmt: skip
        raise lines.error(msg, bad[0])
    _check_bare(lines)
    sel = np.flatnonzero(widths == len(PERSON_COLUMNS))
    if not sel.size:
        return _People.empty()
    values = lines.floats(sel, _PERSON_NUMERIC, [PERSON_COLUMNS[j] for j in _PERSON_NUMERIC])
    t_tokens = [lines.rows[i][0] for i in sel]
    sample = _match_samples(values[:, 0], t_robot, t_tokens, lines, sel, "person")
    code, labels = _codes([lines.rows[i][1] for i in sel])
    order = np.argsort(sample, kind="stable")
    return _People(values[order][:, _PERSON_TAKE], sample[order], code[order], labels)


def _parse_group_line(lines: _Lines, i: int) -> tuple[float, str, list[str]]:
    """Time, id and member ids of the ``i``-th line of a groups log (not a bare line)."""
    row = lines.rows[i]
    try:
        slash = row.index("/")
    except ValueError:
        raise lines.error("group line has no '/' after its member ids", i) from None
    if slash < len(GROUP_HEAD) + 1:
        msg = (f"a group line needs {' '.join(GROUP_HEAD)} and at least one member id "
               f"before '/', got {slash} values")  # fmt: skip
        raise lines.error(msg, i)
    tail = row[slash + 1 :]
    if len(tail) % 3:
        msg = f"expected 'id id strength' triples after '/', got {len(tail)} values"
        raise lines.error(msg, i)
    numbers = [(row[j], name) for j, name in enumerate(GROUP_HEAD) if name != "id"]
    numbers += [(tail[j], "strength") for j in range(2, len(tail), 3)]
    for token, name in numbers:
        try:
            float(token)
        except ValueError:
            raise lines.error(f"column {name} is not a number: {token!r}", i) from None
    return float(row[0]), row[1], row[len(GROUP_HEAD) : slash]


def _read_groups(path: PathLike | None, t_robot: NDArray, people: _People):
    """Group tables (sample, code, size, member rows) sorted by sample, and the labels.

    The tables are ``None`` when there is no group (``EpisodeRecord.from_arrays`` then
    leaves the group tables empty).
    """
    if path is None:
        return (None,) * 4, None
    lines = _Lines(path)
    _check_bare(lines)
    sel = np.flatnonzero(lines.widths > 1)
    if not sel.size:
        return (None,) * 4, None
    with _gc_paused():
        parsed = [_parse_group_line(lines, i) for i in sel]
    t = np.array([p[0] for p in parsed], dtype=np.float64)
    t_tokens = [lines.rows[i][0] for i in sel]
    sample = _match_samples(t, t_robot, t_tokens, lines, sel, "group")
    code, labels = _codes([p[1] for p in parsed])
    sizes = np.array([len(p[2]) for p in parsed], dtype=np.int64)
    rows = people.find(np.repeat(sample, sizes), [m for p in parsed for m in p[2]])
    missing = np.flatnonzero(rows < 0)
    if missing.size:
        g = int(np.searchsorted(np.cumsum(sizes), missing[0], side="right"))
        member = parsed[g][2][missing[0] - int(sizes[:g].sum())]
        msg = f"group member {member!r} is not among the people at this group's timestamp"
        raise lines.error(msg, sel[g])
    order = np.argsort(sample, kind="stable")
    return (sample[order], code[order], sizes[order], rows[_gather(sizes, order)]), labels


def _gather(sizes: NDArray, order: NDArray) -> NDArray:
    """Indices that reorder the concatenated runs of ``sizes`` into the order ``order``."""
    starts = np.cumsum(sizes) - sizes
    new_sizes = sizes[order]
    new_starts = np.cumsum(new_sizes) - new_sizes
    shift = np.repeat(starts[order] - new_starts, new_sizes)
    return np.arange(shift.size) + shift


# ---------------------------------------------------------------------------- writing
_F4, _F6 = " %9.4f", " %9.6f"
_Z4, _Z6 = "    0.0000", "  0.000000"
_ROBOT_FMT = (
    "%9.4f" + _F4 * 2 + _Z4 + _F4 + _Z4 * 5 + _F4 * 2 + _Z4 + _F4 + _Z4 * 5 + _F4 * 5 + "\n"
)
_PERSON_FMT = (
    "%9.4f %6s    1.0000" + _F4 * 2 + _Z4 + _F4 + _F6 * 4 + _Z6 + _F4 * 2 + _Z4 * 2 + _Z6 * 5
    + "      0            0 1 0 %6s"
)  # fmt: skip
_GROUP_FMT = "%9.4f %6s" + _F4 * 2 + _Z4 + "            0 "


def write_native(
    record: EpisodeRecord,
    robot_path: PathLike,
    people_path: PathLike | None,
    groups_path: PathLike | None,
) -> None:
    """Write ``record`` as SRPB native logs (t + 23 robot variant); ``None`` skips a file.

    Fixed point with 4 decimals (person covariances 6). Fields the record does not hold are
    written as zeros (z, the robot pose and velocity covariances, vz, person omega), people
    reliability 1, detection_id 0, track_age 0, matched 1, occluded 0; a person's group
    column names the first group holding it at that sample (else ``none``); a group's cog is
    the mean of its members' positions and its age 0. Ids are written as
    ``record.person_label(id)`` / ``record.group_label(id)`` and must be non-empty and free
    of whitespace (``ValueError`` otherwise). Timestamps closer than 5e-5 s may collapse
    into one on rounding.
    """
    robot = record.robot
    cols = [ROBOT_FIELDS.index(f) for f in ROBOT_COLUMNS if f in ROBOT_FIELDS]
    _write(robot_path, _ROBOT_FMT * robot.shape[0] % tuple(robot[:, cols].ravel().tolist()))
    if people_path is not None:
        _write(people_path, _people_text(record))
    if groups_path is not None:
        _write(groups_path, _groups_text(record))


def _write(path: PathLike, text: str) -> None:
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)


def _labels(ids: NDArray, label: Callable[[int], str], what: str) -> NDArray:
    """Labels of ``ids`` as an object array, checked to be writable tokens."""
    uniq, inverse = np.unique(ids, return_inverse=True)
    texts = [label(int(u)) for u in uniq.tolist()]
    reserved = ("/", "none") if what == "group" else ("/",)
    for text in texts:
        if text.split() != [text] or text in reserved:
            raise ValueError(f"{what} label {text!r} cannot be written to a native log")
    return np.array(texts, dtype=object)[inverse.reshape(-1)]


def _merge_bare(t: NDArray, sample: NDArray, lines: list[str]) -> str:
    """Lines of the entity rows, with a bare timestamp line for every sample without any."""
    empty = np.flatnonzero(np.bincount(sample, minlength=t.size) == 0)
    all_lines = lines + [f"{v:9.4f}" for v in t[empty].tolist()]
    order = np.argsort(np.concatenate([sample, empty]), kind="stable")
    return "".join(all_lines[i] + "\n" for i in order.tolist())


def _people_text(record: EpisodeRecord) -> str:
    t = record.robot[:, 0]
    table, sample = record.people, record.people_sample
    group_of = np.full(sample.size, "none", dtype=object)
    members = record.group_members
    if members.size:
        rows, first = np.unique(members, return_index=True)
        gids = np.repeat(record.group_id, record.group_size)[first]
        group_of[rows] = _labels(gids, record.group_label, "group")
    cells = np.empty((sample.size, 12), dtype=object)
    cells[:, 0] = t[sample]
    cells[:, 1] = _labels(record.people_id, record.person_label, "person")
    cells[:, 2:11] = table
    cells[:, 11] = group_of
    lines = [_PERSON_FMT % tuple(row) for row in cells.tolist()]
    return _merge_bare(t, sample, lines)


def _groups_text(record: EpisodeRecord) -> str:
    t = record.robot[:, 0]
    sample, sizes, members = record.group_sample, record.group_size, record.group_members
    lines: list[str] = []
    if sample.size:
        starts = record.group_start
        xy = record.people[members][:, [PERSON_FIELDS.index("x"), PERSON_FIELDS.index("y")]]
        cog = np.add.reduceat(xy, starts, axis=0) / sizes[:, None]
        names = _labels(record.group_id, record.group_label, "group")
        heads = [
            _GROUP_FMT % row
            for row in zip(t[sample].tolist(), names.tolist(), *cog.T.tolist(), strict=True)
        ]
        member_names = _labels(record.people_id[members], record.person_label, "person")
        cells = [f" {name:>6}" for name in member_names.tolist()]
        lines = [
            head + "".join(cells[s : s + k]) + " / "
            for head, s, k in zip(heads, starts.tolist(), sizes.tolist(), strict=True)
        ]
    return _merge_bare(t, sample, lines)
