"""Reading and writing the SRPB reference logger's native text logs.

An SRPB run is logged as three whitespace-separated text files (see ``METRICS.md``,
"SRPB native text logs"): ``*_robot.txt`` (one line per robot sample), ``*_people.txt``
(one line per tracked person per sample, or a line holding only the timestamp) and
``*_groups.txt`` (one line per F-formation per sample, or a bare timestamp line). Units are
SI (m, s, rad, m/s, rad/s, m^2); velocities of the robot are body-frame, those of people
global-frame.

Reading rules ("no silent wrong numbers": what cannot be right is refused):

- Lines end at ``\n`` (a ``\r`` before it is whitespace); blank lines are skipped; line
  numbers in errors are 1-based and count every line.
- Robot lines hold t + 23 values, or t + 26 values (a newer logger inserts ``cmd_vx cmd_vy
  cmd_omega`` before ``obstacle_dist``); both may appear in one file.
- Numbers have the standard decimal syntax (``1.5``, ``-2e-3``, ``nan``, ``inf``; no
  underscores, no non-ASCII digits), as the reference reader's ``std::stod`` reads them.
- Values the metrics use must be right (see :func:`~srpb_gym.metrics.record.
  invalid_robot_row` and :func:`~srpb_gym.metrics.record.invalid_person_row`): every
  timestamp, robot pose, velocity, goal and obstacle distance and every person's pose,
  velocity and position covariance is finite; robot times do not decrease; a covariance
  is a covariance (no negative variance, positive semi-definite up to 5e-7 m^2, the
  rounding of the logs' 6 decimals). The one legitimately missing value is a robot
  ``planning_time`` of ``nan``: no decision was timed at that sample (srpb-gym writes it
  for the final sample of a run); the metrics skip it. Columns the metrics do not use
  (z, the robot's pose and velocity covariances, vz, ``cmd_*``, a person's reliability,
  z, ``cov_yawyaw``, vz, omega and velocity covariances, group cog, age and relation
  strengths) need only be numbers.
- People and groups are matched to robot samples by equal timestamps (float equality of the
  parsed numbers). When the robot log repeats a timestamp, people and groups at that time
  are attached to the first robot sample carrying it. Every line of the people and groups
  logs (bare lines included) must match a robot sample, and every robot sample must have
  at least one line in each (a person or group line, or a bare timestamp line): a log that
  misses samples (a truncated one, typically) is refused, naming that log.
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
import re
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from srpb_gym.errors import InputError
from srpb_gym.metrics.record import (
    PERSON_FIELDS,
    ROBOT_FIELDS,
    EpisodeRecord,
    invalid_person_row,
    invalid_robot_row,
)

PathLike = str | os.PathLike
LogPath = PathLike | Literal[False] | None
"""A people or groups log argument: a path, ``False`` (the run has no such log) or ``None``
(not given: refused)."""

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
_NUMBER = re.compile(
    r"[+-]?(?:[0-9]+\.?[0-9]*(?:[eE][+-]?[0-9]+)?|\.[0-9]+(?:[eE][+-]?[0-9]+)?|inf(?:inity)?"
    r"|nan)",
    re.IGNORECASE,
)


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


def read_native(robot_path: PathLike, people_path: LogPath, groups_path: LogPath) -> EpisodeRecord:
    """Read an episode from SRPB native logs (see the module docstring for the rules).

    ``people_path`` / ``groups_path``: the run's people and groups logs. ``False`` says the
    run has no such log: the record then holds no people (no groups), and the social
    metrics evaluate as for a run in which nobody was tracked (0); a caller that only lost
    the log should report them as not computed instead. ``None`` (not given) is refused,
    so that a missing log never passes for an empty scene.

    Raises :class:`InputError` (file and 1-based line) for any malformed input.
    """
    robot = _Robot(robot_path)
    _check_given(people_path, "people", robot_path)
    people = _People.empty() if people_path is False else _read_people(people_path, robot)
    _check_given(groups_path, "groups", robot_path)
    groups, g_labels = (None,) * 4, None
    if groups_path is not False:
        groups, g_labels = _read_groups(groups_path, robot, people)
    return EpisodeRecord.from_arrays(
        robot.table, people.table, people.sample, people.code, *groups,
        person_labels=people.labels, group_labels=g_labels,
    )  # fmt: skip


def _check_given(path: LogPath, kind: str, robot_path: PathLike) -> None:
    """Refuse a people or groups log that was not given (``None``)."""
    if path is None:
        needs = "the social metrics (m_psi, m_dir, m_fsi)" if kind == "people" else "m_fsi"
        msg = (f"no {kind} log given or found: {needs} cannot be computed without it "
               f"({kind}_path=False reads a run that logged none)")  # fmt: skip
        raise InputError(msg, robot_path)


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


def read_text(path: PathLike) -> str:
    """The text of a UTF-8 file; :class:`InputError` naming the file (and the line) when it
    cannot be read or is binary (not UTF-8, NUL bytes)."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except FileNotFoundError:
        raise InputError("no such file", path) from None
    except IsADirectoryError:
        raise InputError("is a folder, not a file", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        msg = f"not a UTF-8 text file (byte 0x{data[exc.start]:02x}): a binary file?"
        raise InputError(msg, path, line) from None
    nul = text.find("\0")
    if nul >= 0:
        raise InputError("not a text file (NUL byte): a binary file?", path,
                         text.count("\n", 0, nul) + 1)  # fmt: skip
    return text


class _Lines:
    """The non-blank lines of a log file: 1-based numbers, texts, tokens and token counts."""

    def __init__(self, path: PathLike) -> None:
        self.path = path
        text = read_text(path)
        self.ascii = text.isascii()
        self.numbers: list[int] = []
        self.texts: list[str] = []
        self.rows: list[list[str]] = []
        with _gc_paused():
            for i, line in enumerate(text.split("\n"), start=1):
                tokens = line.split()
                if tokens:
                    self.numbers.append(i)
                    self.texts.append(line)
                    self.rows.append(tokens)
        self.widths = np.fromiter(map(len, self.rows), dtype=np.int64, count=len(self.rows))

    def error(self, message: str, i: int) -> InputError:
        """An error located at the ``i``-th non-blank line."""
        return InputError(message, self.path, self.numbers[i])

    def number(self, token: str, name: str, i: int) -> float:
        """``token`` (column ``name`` of the ``i``-th line) as a float."""
        if not _NUMBER.fullmatch(token):
            raise self.error(f"column {name} is not a number: {token!r}", i)
        return float(token)

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
        with _gc_paused():
            values = [
                [self.number(self.rows[i][c], name, i) for c, name in zip(cols, names, strict=True)]
                for i in sel
            ]
        return np.array(values, dtype=np.float64).reshape(len(sel), len(cols))


class _Robot:
    """The robot log: its table (N, 12; ``ROBOT_FIELDS``), checked, and its lines."""

    def __init__(self, path: PathLike) -> None:
        lines = _Lines(path)
        if not lines.rows:
            raise InputError("the robot log holds no samples", path)
        widths = lines.widths
        bad = np.flatnonzero((widths != len(ROBOT_COLUMNS)) & (widths != len(ROBOT_COLUMNS_CMD)))
        if bad.size:
            msg = (f"expected {len(ROBOT_COLUMNS)} values (t + 23) or {len(ROBOT_COLUMNS_CMD)} "
                   f"(t + 26) on a robot line, got {widths[bad[0]]}")  # fmt: skip
            raise lines.error(msg, bad[0])
        table = np.empty((len(lines.rows), len(ROBOT_FIELDS)))
        for names in (ROBOT_COLUMNS, ROBOT_COLUMNS_CMD):
            sel = np.flatnonzero(widths == len(names))
            if sel.size:
                values = lines.floats(sel, range(len(names)), names)
                table[sel] = values[:, [names.index(f) for f in ROBOT_FIELDS]]
        problem = invalid_robot_row(table)
        if problem is not None:
            raise lines.error(problem[1], problem[0])
        self.table, self.lines = table, lines
        self.t = table[:, 0]
        order = np.argsort(self.t, kind="stable")
        self._order, self._sorted = order, self.t[order]
        # first sample carrying the time of each sample (times do not decrease)
        self.first = np.searchsorted(self.t, self.t, side="left")

    def where(self, sample: int) -> str:
        """``t = ... (robot line L)`` of a sample, for messages."""
        return f"t = {_fmt(self.t[sample])} (robot log line {self.lines.numbers[sample]})"

    def match(self, t: NDArray, lines: _Lines, sel: NDArray, what: Sequence[str]) -> NDArray:
        """Index of the first robot sample whose time equals each of ``t`` (lines ``sel``
        of another log, holding a ``what[k]`` each)."""
        pos = np.minimum(np.searchsorted(self._sorted, t, side="left"), self._sorted.size - 1)
        bad = np.flatnonzero(self._sorted[pos] != t)
        if bad.size:
            i = int(bad[0])
            msg = (f"{what[i]} at t = {lines.rows[sel[i]][0]} matches no robot sample (no "
                   f"robot line has that time)")  # fmt: skip
            if t[i] > self.t[-1]:
                msg += f"; the robot log ends at {self.where(self.t.size - 1)}: truncated?"
            raise lines.error(msg, int(sel[i]))
        return self._order[pos]


def _fmt(value: float) -> str:
    return repr(float(value))


def _line_samples(lines: _Lines, robot: _Robot, kind: str, what: Sequence[str]) -> NDArray:
    """Robot sample of every line of a people or groups log, checked both ways: every line
    has a finite time matching a robot sample, every robot sample has a line."""
    if not lines.rows:
        raise InputError(f"the {kind} log is empty: expected a line (a bare timestamp line "
                         f"at least) for each of the {robot.t.size} robot samples",
                         lines.path)  # fmt: skip
    n = len(lines.rows)
    t = lines.floats(np.arange(n), (0,), ("t",))[:, 0]
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise lines.error(f"t is {_fmt(t[bad[0]])}, expected a finite time (s)", int(bad[0]))
    sample = robot.match(t, lines, np.arange(n), what)
    covered = np.zeros(robot.t.size, dtype=np.bool_)
    covered[sample] = True
    missing = np.flatnonzero(~covered[robot.first])
    if missing.size:
        k = int(missing[0])
        need = f"every robot sample needs a line in the {kind} log (a bare timestamp line at least)"
        later = np.flatnonzero(t > robot.t[k])
        if not later.size:
            last = int(np.argmax(t))
            msg = (f"the {kind} log ends at t = {lines.rows[last][0]} but the robot log goes on "
                   f"to {robot.where(robot.t.size - 1)}: truncated? {need}")  # fmt: skip
            raise lines.error(msg, n - 1)
        msg = f"no line for the robot sample at {robot.where(k)} before this line; {need}"
        raise lines.error(msg, int(later[0]))
    return sample


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


def _read_people(path: PathLike, robot: _Robot) -> _People:
    lines = _Lines(path)
    widths = lines.widths
    bad = np.flatnonzero((widths != 1) & (widths != len(PERSON_COLUMNS)))
    if bad.size:
        msg = (f"expected {len(PERSON_COLUMNS)} values on a people line (or only the "
               f"timestamp), got {widths[bad[0]]}")  # fmt: skip
        raise lines.error(msg, bad[0])
    sel = np.flatnonzero(widths == len(PERSON_COLUMNS))
    values = lines.floats(sel, _PERSON_NUMERIC, [PERSON_COLUMNS[j] for j in _PERSON_NUMERIC])
    table = values[:, _PERSON_TAKE]
    problem = invalid_person_row(table)
    if problem is not None:
        raise lines.error(problem[1], int(sel[problem[0]]))
    what = np.where(widths == 1, "timestamp line", "person").tolist()
    sample = _line_samples(lines, robot, "people", what)[sel]
    if not sel.size:
        return _People.empty()
    code, labels = _codes([lines.rows[i][1] for i in sel])
    order = np.argsort(sample, kind="stable")
    return _People(table[order], sample[order], code[order], labels)


def _parse_group_line(lines: _Lines, i: int) -> tuple[str, list[str]]:
    """Id and member ids of the ``i``-th line of a groups log (not a bare line)."""
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
        lines.number(token, name, i)
    return row[1], row[len(GROUP_HEAD) : slash]


def _read_groups(path: PathLike, robot: _Robot, people: _People):
    """Group tables (sample, code, size, member rows) sorted by sample, and the labels.

    The tables are ``None`` when there is no group (``EpisodeRecord.from_arrays`` then
    leaves the group tables empty).
    """
    lines = _Lines(path)
    sel = np.flatnonzero(lines.widths > 1)
    with _gc_paused():
        parsed = [_parse_group_line(lines, i) for i in sel]
    what = np.where(lines.widths == 1, "timestamp line", "group").tolist()
    sample = _line_samples(lines, robot, "groups", what)[sel]
    if not sel.size:
        return (None,) * 4, None
    code, labels = _codes([p[0] for p in parsed])
    sizes = np.array([len(p[1]) for p in parsed], dtype=np.int64)
    rows = people.find(np.repeat(sample, sizes), [m for p in parsed for m in p[1]])
    missing = np.flatnonzero(rows < 0)
    if missing.size:
        g = int(np.searchsorted(np.cumsum(sizes), missing[0], side="right"))
        member = parsed[g][1][missing[0] - int(sizes[:g].sum())]
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
class _Formats:
    """Line formats of the native logs for a number of decimals (``None``: exact)."""

    def __init__(self, precision: int | None) -> None:
        if precision is None:
            num = cov = "%9r"  # repr: the shortest text that reads back as the same float
        elif isinstance(precision, int) and not isinstance(precision, bool) and precision >= 0:
            num, cov = f"%9.{precision}f", f"%9.{precision + 2}f"
        else:
            raise ValueError(f"precision must be None or a whole number >= 0, got {precision!r}")
        f, c = " " + num, " " + cov
        z, zc = " " + num % 0.0, " " + cov % 0.0
        self.num = num
        self.robot = num + f * 2 + z + f + z * 5 + f * 2 + z + f + z * 5 + f * 5 + "\n"
        self.person = (num + " %6s " + num % 1.0 + f * 2 + z + f + c * 4 + zc + f * 2 + z * 2
                       + zc * 5 + "      0            0 1 0 %6s")  # fmt: skip
        self.group = num + " %6s" + f * 2 + z + "            0 "


def write_native(
    record: EpisodeRecord,
    robot_path: PathLike,
    people_path: PathLike | None,
    groups_path: PathLike | None,
    precision: int | None = None,
) -> None:
    """Write ``record`` as SRPB native logs (t + 23 robot variant); ``None`` skips a file.

    ``precision``: ``None`` (default) writes every number exactly (Python's ``repr``, the
    shortest text that reads back as the same float: ``0.1``, ``1e-05``, ``nan``), so that
    :func:`read_native` gives back the record's values bit for bit and the metrics of the
    logs equal those of the record. A whole number k writes fixed point with k decimals
    (person covariances k + 2): ``precision=4`` gives the reference logger's files byte
    for byte. Either way fields are separated by single spaces and padded to 9 characters
    as the reference logger does, and its reader (``std::stod``) reads them.

    Fields the record does not hold are written as zeros (z, the robot pose and velocity
    covariances, vz, person omega), people reliability 1, detection_id 0, track_age 0,
    matched 1, occluded 0; a person's group column names the first group holding it at that
    sample (else ``none``); a group's cog is the mean of its members' positions and its age
    0. Ids are written as ``record.person_label(id)`` / ``record.group_label(id)`` and must
    be non-empty and free of whitespace. ``ValueError`` for such a label, and for people or
    groups at a sample whose written timestamp equals an earlier sample's (a reader would
    attach them to that earlier sample; with a fixed precision, timestamps closer than
    half its last digit collapse).
    """
    fmt = _Formats(precision)
    robot = record.robot
    cols = [ROBOT_FIELDS.index(f) for f in ROBOT_COLUMNS if f in ROBOT_FIELDS]
    stamps = [fmt.num % v for v in robot[:, 0].tolist()]
    _check_stamps(stamps, record.people_sample, "people")
    _check_stamps(stamps, record.group_sample, "groups")
    _write(robot_path, fmt.robot * robot.shape[0] % tuple(robot[:, cols].ravel().tolist()))
    if people_path is not None:
        _write(people_path, _people_text(record, fmt, stamps))
    if groups_path is not None:
        _write(groups_path, _groups_text(record, fmt, stamps))


def _check_stamps(stamps: list[str], sample: NDArray, what: str) -> None:
    """Refuse rows at a sample whose timestamp text an earlier sample already carries."""
    if not sample.size:
        return
    first: dict[str, int] = {}
    owner = np.array([first.setdefault(s, k) for k, s in enumerate(stamps)], dtype=np.int64)
    clash = np.flatnonzero(owner[sample] != sample)
    if clash.size:
        k = int(sample[clash[0]])
        stamp = stamps[k].strip()
        raise ValueError(f"{what} at sample {k} cannot be written: its timestamp {stamp} "
                         f"equals sample {int(owner[k])}'s, to which a reader would attach "
                         f"them")  # fmt: skip


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


def _merge_bare(stamps: list[str], sample: NDArray, lines: list[str]) -> str:
    """Lines of the entity rows, with a bare timestamp line for every sample without any."""
    empty = np.flatnonzero(np.bincount(sample, minlength=len(stamps)) == 0)
    all_lines = lines + [stamps[k] for k in empty.tolist()]
    order = np.argsort(np.concatenate([sample, empty]), kind="stable")
    return "".join(all_lines[i] + "\n" for i in order.tolist())


def _people_text(record: EpisodeRecord, fmt: _Formats, stamps: list[str]) -> str:
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
    lines = [fmt.person % tuple(row) for row in cells.tolist()]
    return _merge_bare(stamps, sample, lines)


def _groups_text(record: EpisodeRecord, fmt: _Formats, stamps: list[str]) -> str:
    t = record.robot[:, 0]
    sample, sizes, members = record.group_sample, record.group_size, record.group_members
    lines: list[str] = []
    if sample.size:
        starts = record.group_start
        xy = record.people[members][:, [PERSON_FIELDS.index("x"), PERSON_FIELDS.index("y")]]
        cog = np.add.reduceat(xy, starts, axis=0) / sizes[:, None]
        names = _labels(record.group_id, record.group_label, "group")
        heads = [
            fmt.group % row
            for row in zip(t[sample].tolist(), names.tolist(), *cog.T.tolist(), strict=True)
        ]
        member_names = _labels(record.people_id[members], record.person_label, "person")
        cells = [f" {name:>6}" for name in member_names.tolist()]
        lines = [
            head + "".join(cells[s : s + k]) + " / "
            for head, s, k in zip(heads, starts.tolist(), sizes.tolist(), strict=True)
        ]
    return _merge_bare(stamps, sample, lines)
