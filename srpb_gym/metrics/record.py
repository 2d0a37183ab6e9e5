"""The episode record: what the robot did and what its tracker saw, stored column-wise.

One :class:`EpisodeRecord` holds a whole episode as a few numpy arrays, so the metrics run
vectorised over samples and people. It grows by :meth:`EpisodeRecord.append` (one control
step at a time, as the environment fills it) or is built at once by
:meth:`EpisodeRecord.from_arrays` (as the log readers do); both give the same record.

Tables (all float64 unless said otherwise, SI units, global frame):

- robot, shape (N, 12), columns :data:`ROBOT_FIELDS`: time [s], pose x, y [m], yaw [rad],
  body-frame velocity vx, vy [m/s], omega [rad/s], goal x, y [m], yaw [rad], distance from
  the robot centre to the nearest obstacle [m], planner computation time [s].
- people, shape (P, 9), columns :data:`PERSON_FIELDS`: position [m], yaw [rad], position
  covariance xx, xy, yx, yy [m^2], global-frame velocity [m/s]; ``people_sample`` (int64)
  is the robot sample each row belongs to (non-decreasing), ``people_id`` (int64) the
  person's id.
- groups (F-formations), one row per group per sample: ``group_sample``, ``group_id``,
  ``group_start`` and ``group_size`` (int64) index ``group_members``, which holds row
  indices into the people table.

The integer columns (``people_sample``, ``people_id``, ``group_*``) read as contiguous
copies; ``robot``, ``people`` and ``group_members`` are views.

Ids are integers. Logs with textual ids keep them in ``person_labels``/``group_labels``
(label of id k is ``labels[k]``); without labels an id is written as the integer itself.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

ROBOT_FIELDS: tuple[str, ...] = (
    "t", "x", "y", "yaw", "vx", "vy", "omega",
    "goal_x", "goal_y", "goal_yaw", "obstacle_dist", "planning_time",
)  # fmt: skip
PERSON_FIELDS: tuple[str, ...] = (
    "x", "y", "yaw", "cov_xx", "cov_xy", "cov_yx", "cov_yy", "vx", "vy",
)  # fmt: skip
R = {name: i for i, name in enumerate(ROBOT_FIELDS)}
P = {name: i for i, name in enumerate(PERSON_FIELDS)}

# integer tables: people (sample, id); groups (sample, id, start, size); members (row)
_PINT = {"people_sample": 0, "people_id": 1}
_GINT = {"group_sample": 0, "group_id": 1, "group_start": 2, "group_size": 3}
# Entries of EpisodeRecord.counts: rows in use of the robot, people (and people_sample/id),
# group and member tables; where the last appended sample's people, groups and members
# start (-1: unknown, after from_arrays).
SAMPLES, ROWS, GROUPS, MEMBERS, LAST_ROW, LAST_GROUP, LAST_MEMBER = range(7)


def _grown(buf: NDArray, used: int, need: int) -> NDArray:
    """``buf`` itself when it has ``need`` rows, else a copy of its ``used`` rows in a buffer
    of max(need, 2 x capacity) rows."""
    if need <= buf.shape[0]:
        return buf
    new = np.empty((max(need, 2 * buf.shape[0]), *buf.shape[1:]), dtype=buf.dtype)
    new[:used] = buf[:used]
    return new


class EpisodeRecord:
    """A columnar SRPB episode; see the module docstring for the tables.

    Storage: preallocated tables (robot, people, pint = people sample and id, gint = group
    sample, id, start, size; members) of which the first :attr:`counts` rows are in use;
    appends grow them by doubling. Compiled writers (the simulation's) fill the tables and
    ``counts`` directly after :meth:`reserve`.
    """

    def __init__(
        self,
        capacity: int = 256,
        person_labels: Sequence[str] | None = None,
        group_labels: Sequence[str] | None = None,
    ) -> None:
        small = max(capacity // 4, 4)
        self.tables = (
            np.empty((capacity, len(ROBOT_FIELDS))),
            np.empty((capacity, len(PERSON_FIELDS))),
            np.empty((capacity, len(_PINT)), dtype=np.int64),
            np.empty((small, len(_GINT)), dtype=np.int64),
            np.empty(small, dtype=np.int64),
        )
        self.counts = np.zeros(7, dtype=np.int64)
        self.counts[LAST_ROW:] = -1
        self.person_labels = None if person_labels is None else tuple(person_labels)
        self.group_labels = None if group_labels is None else tuple(group_labels)

    # ------------------------------------------------------------------ building
    def reserve(self, samples: int, rows: int, groups: int, members: int) -> None:
        """Make room for this many more robot samples, people rows, groups and members."""
        n = self.counts
        robot, people, pint, gint, mem = self.tables
        self.tables = (
            _grown(robot, n[SAMPLES], n[SAMPLES] + samples),
            _grown(people, n[ROWS], n[ROWS] + rows),
            _grown(pint, n[ROWS], n[ROWS] + rows),
            _grown(gint, n[GROUPS], n[GROUPS] + groups),
            _grown(mem, n[MEMBERS], n[MEMBERS] + members),
        )

    def append(
        self,
        robot: ArrayLike,
        people_ids: ArrayLike | None = None,
        people: ArrayLike | None = None,
        group_ids: ArrayLike | None = None,
        group_sizes: ArrayLike | None = None,
        group_members: ArrayLike | None = None,
        check: bool = True,
    ) -> int:
        """Append one sample; returns its index.

        ``robot``: the 12 values of :data:`ROBOT_FIELDS`. ``people_ids`` (k,) and
        ``people`` (k, 9): the people tracked at this sample. ``group_ids`` (g,),
        ``group_sizes`` (g,) and ``group_members`` (sum of sizes,): each group's members as
        indices into this sample's ``people`` rows. ``check=False`` skips the consistency
        checks of the group arrays (for callers that build them themselves).
        """
        row = np.asarray(robot, dtype=np.float64)
        if row.shape != (len(ROBOT_FIELDS),):
            raise ValueError(
                f"robot sample must have {len(ROBOT_FIELDS)} values, got shape {row.shape}"
            )
        k = 0
        if people is not None:
            block = np.asarray(people, dtype=np.float64)
            k = block.shape[0] if block.ndim == 2 else block.size // len(PERSON_FIELDS)
            if np.shape(people_ids) != (k,):
                raise ValueError(f"need {k} people ids, got shape {np.shape(people_ids)}")
        sizes = members = None
        if group_ids is not None:
            sizes = np.asarray(group_sizes, dtype=np.int64)
            members = np.asarray(group_members, dtype=np.int64)
            if check:
                self._check_groups(k, group_ids, sizes, members)
        g = 0 if sizes is None else sizes.shape[0]
        self.reserve(1, k, g, 0 if members is None else members.shape[0])
        n = self.counts
        robot_t, people_t, pint, gint, mem = self.tables
        sample, first_person = int(n[SAMPLES]), int(n[ROWS])
        n[LAST_ROW], n[LAST_GROUP], n[LAST_MEMBER] = first_person, n[GROUPS], n[MEMBERS]
        if g:
            rows = gint[n[GROUPS] : n[GROUPS] + g]
            rows[:, 0] = sample
            rows[:, 1] = group_ids
            rows[:, 2] = np.cumsum(sizes) - sizes + n[MEMBERS]
            rows[:, 3] = sizes
            mem[n[MEMBERS] : n[MEMBERS] + members.shape[0]] = members + first_person
            n[GROUPS] += g
            n[MEMBERS] += members.shape[0]
        if k:
            people_t[first_person : first_person + k] = block.reshape(k, len(PERSON_FIELDS))
            pint[first_person : first_person + k, 0] = sample
            pint[first_person : first_person + k, 1] = people_ids
            n[ROWS] += k
        robot_t[sample] = row
        n[SAMPLES] += 1
        return sample

    @staticmethod
    def _check_groups(k: int, group_ids, sizes, members) -> None:
        g = sizes.shape[0]
        if np.shape(group_ids) != (g,) or sizes.sum() != members.shape[0] or np.any(sizes < 1):
            raise ValueError(
                "group_sizes must give one size >= 1 per group and sum to len(group_members)"
            )
        if members.size and (members.min() < 0 or members.max() >= k):
            raise ValueError(f"group member index out of range for {k} people at this sample")

    @classmethod
    def from_arrays(
        cls,
        robot: ArrayLike,
        people: ArrayLike | None = None,
        people_sample: ArrayLike | None = None,
        people_id: ArrayLike | None = None,
        group_sample: ArrayLike | None = None,
        group_id: ArrayLike | None = None,
        group_size: ArrayLike | None = None,
        group_members: ArrayLike | None = None,
        person_labels: Sequence[str] | None = None,
        group_labels: Sequence[str] | None = None,
    ) -> EpisodeRecord:
        """Build a record from whole tables (``group_members`` indexes people rows)."""
        robot = np.asarray(robot, dtype=np.float64).reshape(-1, len(ROBOT_FIELDS))
        rec = cls(max(robot.shape[0], 1), person_labels, group_labels)
        block = np.zeros((0, len(PERSON_FIELDS)))
        if people is not None:
            block = np.asarray(people, dtype=np.float64).reshape(-1, len(PERSON_FIELDS))
        sizes = np.zeros(0, dtype=np.int64)
        members = np.zeros(0, dtype=np.int64)
        if group_sample is not None:
            sizes = np.asarray(group_size, dtype=np.int64).reshape(-1)
            members = np.asarray(group_members, dtype=np.int64).reshape(-1)
        p, g, m = block.shape[0], sizes.shape[0], members.shape[0]
        rec.reserve(robot.shape[0], p, g, m)
        robot_t, people_t, pint, gint, mem = rec.tables
        robot_t[: robot.shape[0]] = robot
        people_t[:p] = block
        if people is not None:
            pint[:p, 0] = people_sample
            pint[:p, 1] = people_id
        if group_sample is not None:
            gint[:g, 0] = group_sample
            gint[:g, 1] = group_id
            gint[:g, 2] = np.cumsum(sizes) - sizes
            gint[:g, 3] = sizes
            mem[:m] = members
        rec.counts[:LAST_ROW] = robot.shape[0], p, g, m
        rec.validate()
        return rec

    def validate(self) -> None:
        """Check the tables' internal consistency (indices, sizes, labels); raises
        ``ValueError``. Values are checked by :func:`invalid_robot_row` and
        :func:`invalid_person_row` (the log readers refuse what they report)."""
        n, p = self.n_samples, self.people.shape[0]
        ps = self.people_sample
        if ps.shape[0] != p or self.people_id.shape[0] != p:
            raise ValueError("people_sample and people_id must have one entry per people row")
        if p and (ps[0] < 0 or ps[-1] >= n or np.any(np.diff(ps) < 0)):
            raise ValueError("people_sample must be non-decreasing sample indices in [0, N)")
        gs, m = self.group_sample, self.group_members
        if gs.size and (gs.min() < 0 or gs.max() >= n or np.any(np.diff(gs) < 0)):
            raise ValueError("group_sample must be non-decreasing sample indices in [0, N)")
        if not (self.group_size.shape == self.group_id.shape == self.group_start.shape == gs.shape):
            raise ValueError("group tables must have one entry per group row")
        if np.any(self.group_size < 1) or self.group_size.sum() != m.shape[0]:
            raise ValueError("group sizes must be >= 1 and sum to len(group_members)")
        if np.any(self.group_start != np.cumsum(self.group_size) - self.group_size):
            raise ValueError("group_start must be the running sum of group_size")
        if m.size and (m.min() < 0 or m.max() >= p):
            raise ValueError("group_members must index people rows")
        if m.size and np.any(ps[m] != np.repeat(gs, self.group_size)):
            raise ValueError("a group member must be a person of the group's own sample")
        for name, ids, labels in (("people_id", self.people_id, self.person_labels),
                                  ("group_id", self.group_id, self.group_labels)):  # fmt: skip
            if labels is not None and ids.size and (ids.min() < 0 or ids.max() >= len(labels)):
                raise ValueError(f"{name} must index its {len(labels)} labels")

    def keep_last(self) -> None:
        """Drop every sample but the last, which becomes sample 0 of a new episode (with its
        people, groups and members): a robot that starts a new task where it stands."""
        samples, rows, groups, members, p0, g0, m0 = self._last_sample()
        robot, people, pint, gint, mem = self.tables
        k, g, m = rows - p0, groups - g0, members - m0
        robot[0] = robot[samples - 1]
        people[:k] = people[p0:rows].copy()
        pint[:k] = pint[p0:rows].copy()
        pint[:k, 0] = 0
        gint[:g] = gint[g0:groups].copy()
        gint[:g, 0] = 0
        gint[:g, 2] -= m0
        mem[:m] = mem[m0:members] - p0
        self.counts[:] = (1, k, g, m, 0, 0, 0)

    def latest(self) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
        """The last sample as small tables: robot (1, 12), people (k, 9), people ids (k,),
        group sizes (g,) and group members (sum of sizes,) as indices into its people."""
        samples, rows, groups, members, p0, g0, m0 = self._last_sample()
        robot, people, pint, gint, mem = self.tables
        return (
            robot[samples - 1 : samples],
            people[p0:rows],
            pint[p0:rows, 1],
            gint[g0:groups, 3],
            mem[m0:members] - p0,
        )

    def _last_sample(self) -> tuple[int, int, int, int, int, int, int]:
        """The rows in use of each table and where the last sample's people, groups and
        members start; ``ValueError`` for an empty record."""
        samples, rows, groups, members, p0, g0, m0 = self.counts.tolist()
        if samples == 0:
            raise ValueError("the record is empty")
        if p0 < 0:  # built by from_arrays
            p0, g0, m0 = self._sample_start(samples - 1)
        return samples, rows, groups, members, p0, g0, m0

    def _sample_start(self, n: int) -> tuple[int, int, int]:
        p0 = int(np.searchsorted(self._int_view(2, ROWS)[:, 0], n))
        gint = self._int_view(3, GROUPS)
        g0 = int(np.searchsorted(gint[:, 0], n))
        m0 = int(gint[g0, 2]) if g0 < gint.shape[0] else int(self.counts[MEMBERS])
        return p0, g0, m0

    def _int_view(self, table: int, count: int) -> NDArray[np.int64]:
        return self.tables[table][: self.counts[count]]

    # ------------------------------------------------------------------ reading
    @property
    def n_samples(self) -> int:
        return int(self.counts[SAMPLES])

    @property
    def robot(self) -> NDArray[np.float64]:
        """(N, 12) view of the robot table."""
        return self.tables[0][: self.counts[SAMPLES]]

    @property
    def people(self) -> NDArray[np.float64]:
        """(P, 9) view of the people table."""
        return self.tables[1][: self.counts[ROWS]]

    def robot_col(self, name: str) -> NDArray[np.float64]:
        """One robot column as a contiguous array (a copy)."""
        return np.ascontiguousarray(self.robot[:, R[name]])

    def person_col(self, name: str) -> NDArray[np.float64]:
        """One people column as a contiguous array (a copy)."""
        return np.ascontiguousarray(self.people[:, P[name]])

    def __getattr__(self, name: str) -> NDArray[np.int64]:
        # integer columns are returned as contiguous copies (what the kernels take)
        if name in _PINT:
            return np.ascontiguousarray(self._int_view(2, ROWS)[:, _PINT[name]])
        if name in _GINT:
            return np.ascontiguousarray(self._int_view(3, GROUPS)[:, _GINT[name]])
        if name == "group_members":
            return self._int_view(4, MEMBERS)
        raise AttributeError(name)

    def person_label(self, pid: int) -> str:
        return str(pid) if self.person_labels is None else self.person_labels[pid]

    def group_label(self, gid: int) -> str:
        return str(gid) if self.group_labels is None else self.group_labels[gid]

    def copy(self) -> EpisodeRecord:
        """A deep copy trimmed to its length."""
        return EpisodeRecord.from_arrays(
            self.robot.copy(), self.people.copy(), self.people_sample.copy(), self.people_id.copy(),
            self.group_sample.copy(), self.group_id.copy(), self.group_size.copy(),
            self.group_members.copy(), self.person_labels, self.group_labels,
        )  # fmt: skip

    def __repr__(self) -> str:
        return (
            f"EpisodeRecord(samples={self.n_samples}, person_rows={self.people.shape[0]}, "
            f"group_rows={self.group_sample.shape[0]})"
        )


# ---------------------------------------------------------------------------- value checks
COVARIANCE_TOLERANCE = 5e-7
"""Slack [m^2] of the covariance checks: half the last digit of the native logs' 6-decimal
covariances, so that rounding a valid covariance never makes it look invalid."""

_ROBOT_UNITS = ("s", "m", "m", "rad", "m/s", "m/s", "rad/s", "m", "m", "rad", "m", "s")
_PERSON_UNITS = ("m", "m", "rad", "m^2", "m^2", "m^2", "m^2", "m/s", "m/s")


def _first(mask: NDArray[np.bool_]) -> int:
    """Index of the first true entry of a 1-D mask, or its length when there is none."""
    hits = np.flatnonzero(mask)
    return int(hits[0]) if hits.size else mask.shape[0]


def invalid_robot_row(robot: ArrayLike) -> tuple[int, str] | None:
    """The first row of a robot table (N, 12; :data:`ROBOT_FIELDS`) holding a value that
    cannot be right, with a one-line reason; ``None`` when every row is valid.

    Rules: every value is finite, except ``planning_time``, which is a time >= 0 [s] or NaN
    (no decision timed at that sample: the final sample of a simulated run, or a run
    without timing; the metrics skip it); ``t`` [s] does not decrease from row to row.
    """
    table = np.asarray(robot, dtype=np.float64).reshape(-1, len(ROBOT_FIELDS))
    if table.shape[0] == 0:
        return None
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(table)
        pt = table[:, R["planning_time"]]
        bad[:, R["planning_time"]] = ~(np.isnan(pt) | (np.isfinite(pt) & (pt >= 0.0)))
        t = table[:, R["t"]]
        back = np.zeros(t.shape[0], dtype=np.bool_)
        back[1:] = t[1:] < t[:-1]
    rows = bad.any(axis=1) | back
    row = _first(rows)
    if row == rows.shape[0]:
        return None
    if bad[row].any():
        col = int(np.flatnonzero(bad[row])[0])
        name, value = ROBOT_FIELDS[col], float(table[row, col])
        if name == "planning_time":
            return row, (f"planning_time is {value!r}, expected a time >= 0 s (or nan: no "
                         f"decision at this sample)")  # fmt: skip
        return row, f"{name} is {value!r}, expected a finite number ({_ROBOT_UNITS[col]})"
    return row, (f"t = {float(t[row])!r} is earlier than the previous sample's t = "
                 f"{float(t[row - 1])!r}: robot times must not decrease")  # fmt: skip


def invalid_person_row(people: ArrayLike) -> tuple[int, str] | None:
    """The first row of a people table (P, 9; :data:`PERSON_FIELDS`) holding a value that
    cannot be right, with a one-line reason; ``None`` when every row is valid.

    Rules: every value is finite; the position covariance is a covariance: variances
    ``cov_xx``, ``cov_yy`` >= 0 and ``|cov_xy|``, ``|cov_yx|`` <= sqrt(cov_xx * cov_yy)
    (positive semi-definite), both up to :data:`COVARIANCE_TOLERANCE`.
    """
    table = np.asarray(people, dtype=np.float64).reshape(-1, len(PERSON_FIELDS))
    if table.shape[0] == 0:
        return None
    tol = COVARIANCE_TOLERANCE
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(table)
        cxx, cxy, cyx, cyy = (table[:, P[f]] for f in ("cov_xx", "cov_xy", "cov_yx", "cov_yy"))
        negative = (cxx < -tol) | (cyy < -tol)
        bound = np.sqrt((np.maximum(cxx, 0.0) + tol) * (np.maximum(cyy, 0.0) + tol)) + tol
        not_psd = (np.abs(cxy) > bound) | (np.abs(cyx) > bound)
    rows = bad.any(axis=1) | negative | not_psd
    row = _first(rows)
    if row == rows.shape[0]:
        return None
    if bad[row].any():
        col = int(np.flatnonzero(bad[row])[0])
        value = float(table[row, col])
        return row, (f"{PERSON_FIELDS[col]} is {value!r}, expected a finite number "
                     f"({_PERSON_UNITS[col]})")  # fmt: skip
    xx, xy, yx, yy = (float(v[row]) for v in (cxx, cxy, cyx, cyy))
    if negative[row]:
        name, value = ("cov_xx", xx) if xx < -tol else ("cov_yy", yy)
        return row, f"{name} is {value!r}: a variance cannot be negative (m^2)"
    name, value = ("cov_xy", xy) if abs(xy) > bound[row] else ("cov_yx", yx)
    return row, (f"{name} is {value!r}, larger in magnitude than sqrt(cov_xx * cov_yy) = "
                 f"{math.sqrt(max(xx, 0.0) * max(yy, 0.0))!r}: not a valid covariance (not "
                 f"positive semi-definite)")  # fmt: skip
