"""Per-episode rows, their statistics and the comparison tables.

``episodes.csv`` holds one row per episode: ``env``, ``planner``, ``seed``, ``is_success``,
``collision``, ``timeout`` (0/1), then every metric of :data:`METRIC_NAMES` from the
people the robot tracked at full precision (``repr`` of the float, ``nan`` when undefined),
then the same metrics from ground truth (:data:`GT_COLUMNS`, ``gt_m_psi``, ...), then
``scenario``: the episode's scenario (for ``SRPB-Mix-v0`` the one drawn), then the
episode's first collision, attributed (:data:`COLLISION_COLUMNS`: ``collision_kind``
``wall``/``person``/``robot``, ``collision_by`` ``robot``/``person``/``other_robot``, the
robot's and the other's speed and closing speed [m/s]; empty kind and cause and ``nan``
speeds without a collision; :mod:`srpb_gym.sim.contact`), then ``people_pushed_back``:
the most any walker moved against the way it walks [m] (pushed back by the robot:
:attr:`srpb_gym.sim.crowd.Crowd.pushed_back`). A file without the ``scenario``
column reads as empty scenarios, one without the ground-truth columns (an older run) as
ground truth not computed (NaN), one without the collision columns as collisions not
attributed, one without ``people_pushed_back`` as not known (NaN). A multi-robot run has
one row per (episode, robot), with a ``robot`` column (the robot's index) after ``seed``.

The tables follow the SRPB paper's Table 4: one per scenario, rows = metrics with units
(after the episode count and the success, collision and timeout rates in % with their
Wilson 95 % intervals, ``94 [87.5-97.2]``; the collision rate split by who caused the
episode's first collision, ``6 [2.8-12.5] (robot 4 %, person 2 %)``: :func:`rate_cell`),
columns = planners, cells = median over the
episodes with the percentile bootstrap 95 % interval of the median, ``12.3 [11.0-13.5]``
(:mod:`~srpb_gym.evaluation.intervals`). The metrics that depend on the people
(:data:`PEOPLE_METRICS`) have two rows, ``m_psi (tracked)`` and ``m_psi (ground truth)``;
the others are computed from the robot alone and read the same either way. The
interquartile range stays in the CSV table and ``summary.json``. In a multi-robot run each
planner has a column per robot (``dwa/robot_0``, ...) and a pooled column (``dwa/pooled``:
every robot's episodes together).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections import Counter
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from srpb_gym.errors import InputError
from srpb_gym.evaluation.data import EpisodeResult
from srpb_gym.evaluation.intervals import bootstrap_median, finite, wilson
from srpb_gym.metrics import METRIC_NAMES, METRIC_RANGES, METRIC_UNITS
from srpb_gym.metrics.io_native import read_text
from srpb_gym.sim.contact import CAUSES, FIELDS, KINDS, STEP_PREFIX, Collision

GT_PREFIX = "gt_"
GT_COLUMNS: tuple[str, ...] = tuple(f"{GT_PREFIX}{m}" for m in METRIC_NAMES)
"""The ground-truth metric columns of ``episodes.csv``: ``gt_<metric>``."""
COLLISION_COLUMNS: tuple[str, ...] = tuple(f"{STEP_PREFIX}{f}" for f in FIELDS)
"""The columns of an episode's first collision: ``collision_kind``, ``collision_by``,
``collision_robot_speed``, ``collision_other_speed``, ``collision_robot_closing``,
``collision_other_closing``."""
CSV_COLUMNS: tuple[str, ...] = (
    "env", "planner", "seed", "is_success", "collision", "timeout", *METRIC_NAMES, *GT_COLUMNS,
    "scenario", *COLLISION_COLUMNS, "people_pushed_back",
)  # fmt: skip
ROBOT_COLUMNS: tuple[str, ...] = (*CSV_COLUMNS[:3], "robot", *CSV_COLUMNS[3:])
"""The columns of a multi-robot run's ``episodes.csv``."""
POOLED = "pooled"
UNATTRIBUTED = "unattributed"
"""The cause of a collision of ``summary.json``'s ``collision_by_rate`` whose row holds no
attribution (an ``episodes.csv`` written before it was kept)."""
BY_LABELS = {"robot": "robot", "person": "person", "other_robot": "other robot",
             UNATTRIBUTED: "not attributed"}  # fmt: skip
"""How the tables name each cause of a collision."""
PUSHED_BACK = 1.0
"""m: an episode in which a walker was pushed back farther than this counts in
``summary.json``'s ``pushed_back_rate`` (and the tables' ``people pushed back > 1 m``)."""
PUSHED_BACK_LABEL = f"people pushed back > {PUSHED_BACK:g} m"
OUTCOMES: tuple[tuple[str, str], ...] = (
    ("success", "is_success"), ("collision", "collision"), ("timeout", "timeout"),
)  # fmt: skip

PEOPLE_METRICS: tuple[str, ...] = tuple(
    m for m in METRIC_NAMES if m.split("_")[1] in ("psi", "fsi", "dir")
)
"""The metrics computed from the people (m_psi, m_fsi, m_dir and their variants): the only
ones whose tracked and ground-truth values differ; the tables show both."""
TRACKED, GROUND_TRUTH = "tracked", "ground truth"
STATISTICS = {
    "metrics": "from the people the robot tracked (what SRPB scores on a real robot)",
    "metrics_gt": "from ground truth (what the people experienced)",
    "median": "over the finite values; q1, q3: quartiles (linear interpolation)",
    "ci_low, ci_high": "percentile bootstrap 95 % interval of the median: 10000 resamples, "
    "numpy default_rng(0); null from fewer than 2 values",
    "<outcome>_rate_ci": "Wilson score 95 % interval of the rate, %",
    "collision_by_rate": "episodes whose first collision was caused by the robot, a person, "
    "another robot, or is not attributed (an older episodes.csv), % of all episodes",
    "people_pushed_back": "the most any walker moved against the way it walks in an "
    "episode [m] (statistics as a metric's)",
    "pushed_back_rate": f"episodes in which a walker was pushed back farther than "
    f"{PUSHED_BACK:g} m, % of the episodes where it is known, with its Wilson 95 % interval",
}
"""What the statistics of ``summary.json`` are (its ``statistics`` key)."""
Summary = dict[str, dict[str, dict[str, Any]]]
"""env id -> planner -> statistics (see :func:`summarize`)."""


# ---------------------------------------------------------------------------- CSV
def csv_row(result: EpisodeResult, robots: bool = False) -> list[str]:
    """The ``episodes.csv`` row of one episode (with its ``robot`` column when ``robots``;
    empty for a single-robot row)."""
    flags = [str(int(v)) for v in (result.is_success, result.collision, result.timeout)]
    values = [repr(float(result.metrics[m])) for m in METRIC_NAMES]
    truth = [repr(result.truth(m)) for m in METRIC_NAMES]
    robot = ["" if result.robot is None else str(result.robot)] if robots else []
    c = result.first_collision
    hit = ["", "", *("nan" for _ in FIELDS[2:])] if c is None else [
        c.kind, c.by, *(repr(float(getattr(c, f))) for f in FIELDS[2:])]  # fmt: skip
    return [result.env, result.planner, str(result.seed), *robot, *flags, *values, *truth,
            result.scenario, *hit, repr(float(result.pushed_back))]  # fmt: skip


class EpisodeWriter:
    """``episodes.csv``, one row appended and flushed as each episode finishes; it starts
    with the header and the rows ``done`` (episodes finished earlier, when resuming).
    ``robots``: write the ``robot`` column (a multi-robot run)."""

    def __init__(self, path: str, done: Iterable[EpisodeResult] = (), robots: bool = False):
        self.path = path
        self.robots = robots
        write_episodes(path, done, robots)
        self._file = open(path, "a", newline="", encoding="utf-8")  # noqa: SIM115
        self._csv = csv.writer(self._file)

    def write(self, result: EpisodeResult) -> None:
        self._csv.writerow(csv_row(result, self.robots))
        self._file.flush()

    def close(self) -> None:
        self._file.close()


def write_episodes(path: str, results: Iterable[EpisodeResult], robots: bool | None = None) -> None:
    """Write ``episodes.csv`` at once (replacing the file atomically); with the ``robot``
    column when ``robots`` (``None``: when a row has a robot)."""
    results = list(results)
    if robots is None:
        robots = any(r.robot is not None for r in results)
    tmp = f"{path}.tmp"
    with open(tmp, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(ROBOT_COLUMNS if robots else CSV_COLUMNS)
        writer.writerows(csv_row(r, robots) for r in results)
    os.replace(tmp, path)


def read_episodes(path: str) -> list[EpisodeResult]:
    """The rows of an ``episodes.csv``; :class:`InputError` naming the file and line."""
    return parse_episodes(read_text(path), path)


def parse_episodes(text: str, path: str) -> list[EpisodeResult]:
    """The rows of ``episodes.csv`` text read from ``path``: every row checked (its number
    of values, 0/1 flags, an integer seed (and robot), numbers, each (episode, robot)
    once); a metric column the file lacks (a ground-truth column of an older run) reads as
    not computed (NaN), an empty ``robot`` as a single-robot row. :class:`InputError` names
    file and line."""
    reader = csv.reader(io.StringIO(text, newline=""))
    rows: list[tuple[int, list[str]]] = []
    try:
        for row in reader:
            rows.append((reader.line_num, row))
    except csv.Error as exc:
        raise InputError(f"malformed CSV: {exc}", path, reader.line_num) from None
    if not rows:
        raise InputError("empty file (expected a header line)", path, line=1)
    header = rows[0][1]
    missing = [c for c in CSV_COLUMNS[:6] if c not in header]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}: not an episodes.csv "
                         f"file?", path, line=1)  # fmt: skip
    col = {name: i for i, name in enumerate(header)}
    out: list[EpisodeResult] = []
    seen: dict[tuple[str, str, int, int | None], int] = {}
    for line, row in rows[1:]:
        if not row:
            continue
        result = _parse_row(row, col, path, line)
        key = (result.env, result.planner, result.seed, result.robot)
        if key in seen:
            robot = "" if result.robot is None else f" / robot {result.robot}"
            raise InputError(f"episode {key[0]} / {key[1]} / seed {key[2]}{robot} is listed "
                             f"twice (also on line {seen[key]})", path, line)  # fmt: skip
        seen[key] = line
        out.append(result)
    return out


def _parse_row(row: list[str], col: dict[str, int], path: str, line: int) -> EpisodeResult:
    if len(row) != len(col):
        raise InputError(f"expected {len(col)} values, got {len(row)}", path, line)
    flags = []
    for name in ("is_success", "collision", "timeout"):
        value = row[col[name]].strip()
        if value not in ("0", "1"):
            raise InputError(f"column {name} is {value!r}, expected 0 or 1", path, line)
        flags.append(value == "1")
    try:
        seed = int(row[col["seed"]])
    except ValueError:
        raise InputError(f"column seed is {row[col['seed']]!r}, expected an integer", path,
                         line) from None  # fmt: skip
    metrics = {m: _number(row, col, m, path, line) for m in METRIC_NAMES}
    truth = {m: _number(row, col, f"{GT_PREFIX}{m}", path, line) for m in METRIC_NAMES
             if f"{GT_PREFIX}{m}" in col}  # fmt: skip
    env, planner = row[col["env"]], row[col["planner"]]
    if not env or not planner:
        raise InputError("empty env or planner", path, line)
    robot = row[col["robot"]].strip() if "robot" in col else ""
    if robot and not (robot.isdigit() and robot.isascii()):
        raise InputError(f"column robot is {robot!r}, expected a robot index (0, 1, ...)",
                         path, line)  # fmt: skip
    scenario = row[col["scenario"]] if "scenario" in col else ""
    return EpisodeResult(env, planner, seed, *flags, metrics, robot=int(robot) if robot else None,
                         scenario=scenario, ground_truth=truth,
                         first_collision=_collision(row, col, flags[1], path, line),
                         pushed_back=_number(row, col, "people_pushed_back", path,
                                             line))  # fmt: skip


def _collision(
    row: list[str], col: dict[str, int], collided: bool, path: str, line: int
) -> Collision | None:
    """The attributed first collision of a row (``None``: none, or the columns absent)."""
    kind_col, by_col = COLLISION_COLUMNS[:2]
    kind = row[col[kind_col]].strip() if kind_col in col else ""
    if not kind:
        return None
    by = row[col[by_col]].strip() if by_col in col else ""
    for name, value, valid in ((kind_col, kind, KINDS), (by_col, by, CAUSES)):
        if value not in valid:
            raise InputError(f"column {name} is {value!r}, expected one of "
                             f"{', '.join(valid)}", path, line)  # fmt: skip
    if not collided:
        raise InputError(f"column {kind_col} is {kind!r} in an episode without a collision",
                         path, line)  # fmt: skip
    speeds = [_number(row, col, name, path, line) for name in COLLISION_COLUMNS[2:]]
    return Collision(kind, by, *speeds)


#: the columns that hold speeds or a distance (>= 0; the closing speeds may be negative)
SPEED_COLUMNS = ("collision_robot_speed", "collision_other_speed", "people_pushed_back")


def _number(row: list[str], col: dict[str, int], name: str, path: str, line: int) -> float:
    if name not in col:
        return math.nan
    try:
        value = float(row[col[name]])
    except ValueError:
        raise InputError(f"column {name} is {row[col[name]]!r}, expected a number", path,
                         line) from None  # fmt: skip
    metric = name.removeprefix(GT_PREFIX)
    if metric in METRIC_RANGES:
        check_metric_value(metric, value, name, path, line)
    elif math.isinf(value):  # a speed of the collision attribution
        raise InputError(f"column {name} is {value!r}, expected a finite number or nan", path,
                         line)  # fmt: skip
    elif name in SPEED_COLUMNS and value < 0.0:
        raise InputError(f"column {name} is {value!r}, expected >= 0", path, line)
    return value


def check_metric_value(metric: str, value: float, column: str, path: str, line: int) -> None:
    """Refuse a value of ``metric`` read back from column ``column`` of ``path`` (at
    ``line``) that the metric cannot take (:data:`~srpb_gym.metrics.METRIC_RANGES`, with
    a relative slack of 1e-9 for rounding), or that is infinite: an :class:`InputError`
    naming file, line and column. NaN (a metric not computed) passes."""
    if math.isnan(value):
        return
    low, high = METRIC_RANGES[metric]
    unit = METRIC_UNITS[metric]
    if math.isinf(value):
        raise InputError(f"column {column} is {value!r}: a metric is finite or not computed "
                         "(nan)", path, line)  # fmt: skip
    slack = 1e-9 * max(1.0, abs(low), abs(high) if math.isfinite(high) else 1.0)
    if not low - slack <= value <= high + slack:
        span = f"from {low:g} to {high:g}" if math.isfinite(high) else f"at least {low:g}"
        raise InputError(f"column {column} is {value!r}, out of the range of {metric} "
                         f"({span}, {unit})", path, line)  # fmt: skip


# ---------------------------------------------------------------------------- statistics
def group(results: Iterable[EpisodeResult]) -> dict[str, dict[str, list[EpisodeResult]]]:
    """Results by env id, then planner, in order of first appearance."""
    out: dict[str, dict[str, list[EpisodeResult]]] = {}
    for r in results:
        out.setdefault(r.env, {}).setdefault(r.planner, []).append(r)
    return out


def describe(values: Sequence[float]) -> dict[str, float | int | None]:
    """Median, quartiles (linear interpolation), mean, std, min, max of the finite values,
    and ``ci_low``, ``ci_high``: the percentile bootstrap 95 % interval of the median
    (:func:`~.intervals.bootstrap_median`; ``None`` from fewer than two values); ``n``: how
    many are finite. Statistics of no value are ``None``."""
    x = finite(values)
    if x.size == 0:
        return {"n": 0, **dict.fromkeys(("median", "q1", "q3", "mean", "std", "min", "max",
                                         "ci_low", "ci_high"))}  # fmt: skip
    q1, median, q3 = np.percentile(x, [25.0, 50.0, 75.0])
    ci = bootstrap_median(x) or (None, None)
    return {"n": int(x.size), "median": float(median), "q1": float(q1), "q3": float(q3),
            "mean": float(x.mean()), "std": float(x.std()), "min": float(x.min()),
            "max": float(x.max()), "ci_low": ci[0], "ci_high": ci[1]}  # fmt: skip


def summarize(results: Iterable[EpisodeResult]) -> Summary:
    """Per env and planner: ``episodes``, ``success_rate``, ``collision_rate``,
    ``timeout_rate`` (%) with their Wilson 95 % intervals (``success_rate_ci``, ...:
    ``[low, high]`` in %), ``collision_by_rate`` (who caused the first collision:
    ``robot``, ``person``, ``other_robot``, ``unattributed``, in % of all episodes, summing
    to ``collision_rate``), ``metrics`` (name -> :func:`describe`, from the tracked people)
    and ``metrics_gt`` (the same from ground truth).

    A planner whose rows are of several robots gets an entry per robot,
    ``<planner>/robot_<r>``, and a pooled one, ``<planner>/pooled`` (every robot's
    episodes together: ``episodes`` counts robot-episodes); these entries also hold
    ``planner`` and ``robot`` (the index, or ``"pooled"``)."""
    summary: Summary = {}
    for env, planners in group(results).items():
        summary[env] = {}
        for planner, rows in planners.items():
            robots = sorted({r.robot for r in rows if r.robot is not None})
            if not robots:
                summary[env][planner] = _entry(rows)
                continue
            for robot in robots:
                mine = [r for r in rows if r.robot == robot]
                summary[env][f"{planner}/robot_{robot}"] = _entry(mine, planner, robot)
            summary[env][f"{planner}/{POOLED}"] = _entry(rows, planner, POOLED)
    return summary


def _entry(
    rows: Sequence[EpisodeResult], planner: str | None = None, robot: int | str | None = None
) -> dict[str, Any]:
    entry: dict[str, Any] = {"episodes": len(rows)}
    if planner is not None:
        entry |= {"planner": planner, "robot": robot}
    for label, attr in OUTCOMES:
        count = sum(bool(getattr(r, attr)) for r in rows)
        entry[f"{label}_rate"] = 100.0 * count / len(rows)
        entry[f"{label}_rate_ci"] = wilson(count, len(rows))
    causes = Counter(r.first_collision.by if r.first_collision else UNATTRIBUTED
                     for r in rows if r.collision)  # fmt: skip
    entry["collision_by_rate"] = {c: 100.0 * causes[c] / len(rows)
                                  for c in (*CAUSES, UNATTRIBUTED)}  # fmt: skip
    back = [r.pushed_back for r in rows]
    entry["people_pushed_back"] = describe(back)
    entry["pushed_back_rate"], entry["pushed_back_rate_ci"] = pushed_back_rate(back) or (None, None)
    entry["metrics"] = {m: describe([r.metrics[m] for r in rows]) for m in METRIC_NAMES}
    entry["metrics_gt"] = {m: describe([r.truth(m) for r in rows]) for m in METRIC_NAMES}
    return entry


def pushed_back_rate(values: Sequence[float]) -> tuple[float, Any] | None:
    """The share (%) of the known (finite) ``people_pushed_back`` values above
    :data:`PUSHED_BACK`, with its Wilson 95 % interval; ``None`` when none is known."""
    back = finite(values)
    if back.size == 0:
        return None
    pushed = int((back > PUSHED_BACK).sum())
    return 100.0 * pushed / back.size, wilson(pushed, back.size)


# ---------------------------------------------------------------------------- tables
def number(value: float | None) -> str:
    """A compact number: 3 significant digits, at most 3 decimals, ``n/a`` for none; a
    value that is not 0 but rounds to it reads ``<0.001`` (``>-0.001``), never ``0``."""
    if value is None or not math.isfinite(value):
        return "n/a"
    if value == 0:
        return "0"
    decimals = min(3, max(0, 2 - math.floor(math.log10(abs(value)))))
    text = f"{value:.{decimals}f}"
    if float(text) == 0:
        return "<0.001" if value > 0 else ">-0.001"
    return text


def rate(value: float) -> str:
    """A percentage with at most one decimal: ``100``, ``33.3``, ``0``."""
    return f"{value:.1f}".rstrip("0").rstrip(".")


def interval(low: float | None, high: float | None, fmt: Any = None) -> str:
    """``[low-high]`` (``[low, high]`` when low is negative), ``[n/a]`` for none."""
    fmt = fmt or number
    if low is None or high is None:
        return "[n/a]"
    return f"[{fmt(low)}-{fmt(high)}]" if low >= 0 else f"[{fmt(low)}, {fmt(high)}]"


def cell(
    stats: dict[str, Any], episodes: int | None = None, keys: tuple[str, str] = ("q1", "q3")
) -> str:
    """``median [q1-q3]`` (``[q1, q3]`` when q1 is negative; ``keys``: the bounds shown,
    ``("ci_low", "ci_high")`` for the median's 95 % interval), followed by ``(n=18/20)``
    when the statistics are over fewer values (``stats["n"]``, the finite ones) than the
    ``episodes``; ``n/a`` when no episode has a value."""
    if stats["median"] is None:
        return "n/a"
    iqr = interval(stats.get(keys[0]), stats.get(keys[1]))
    n = stats.get("n")
    fewer = ""
    if episodes is not None and n is not None and n != episodes:
        fewer = f" (n={n}/{episodes})"
    return f"{number(stats['median'])} {iqr}{fewer}"


def rate_cell(entry: dict[str, Any], label: str) -> str:
    """``94 [87.5-97.2]``: a rate of ``entry`` (a planner's summary) with its Wilson 95 %
    interval. The collision rate is followed by who caused the episodes' first
    collisions, in % of all episodes, ``6 [2.8-12.5] (robot 4 %, person 2 %)``: the
    robot and people always, another robot and ``not attributed`` (rows of an older
    ``episodes.csv``) where there are such; nothing when no collision is attributed."""
    ci = entry.get(f"{label}_rate_ci") or (None, None)
    text = f"{rate(entry[f'{label}_rate'])} {interval(*ci, fmt=rate)}"
    by = entry.get("collision_by_rate") if label == "collision" else None
    if not by or not any(by.get(c) for c in CAUSES):
        return text
    parts = [f"{BY_LABELS[c]} {rate(by[c])} %" for c in (*CAUSES, UNATTRIBUTED)
             if c in CAUSES[:2] or by.get(c)]  # fmt: skip
    return f"{text} ({', '.join(parts)})"


def metric_rows() -> list[tuple[str, str, bool]]:
    """(row label, metric, ground truth) of the metric rows of a table: the metrics of
    :data:`PEOPLE_METRICS` twice, ``m_psi (tracked)`` and ``m_psi (ground truth)``."""
    out = []
    for m in METRIC_NAMES:
        if m in PEOPLE_METRICS:
            out += [(f"{m} ({TRACKED})", m, False), (f"{m} ({GROUND_TRUTH})", m, True)]
        else:
            out.append((m, m, False))
    return out


def table(planners: dict[str, dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    """Header and rows of one scenario's table (cells as text): rates with their Wilson
    intervals, metrics as median [95 % interval of the median]."""
    names = list(planners)
    rows = [["episodes", "-", *(str(planners[p]["episodes"]) for p in names)]]
    rows += [[label, "%", *(rate_cell(planners[p], label) for p in names)]
             for label, _ in OUTCOMES]  # fmt: skip
    rows.append([PUSHED_BACK_LABEL, "%", *(_pushed_cell(planners[p]) for p in names)])
    for label, m, gt in metric_rows():
        key = "metrics_gt" if gt else "metrics"
        rows.append([label, METRIC_UNITS[m], *(
            cell(planners[p][key][m], planners[p]["episodes"], ("ci_low", "ci_high"))
            for p in names)])  # fmt: skip
    return ["metric", "unit", *names], rows


def _pushed_cell(entry: dict[str, Any]) -> str:
    """``3 [1.0-8.6]``: the share of episodes with a walker pushed back (``n/a``: unknown)."""
    return "n/a" if entry.get("pushed_back_rate") is None else rate_cell(entry, "pushed_back")


def format_text(title: str, header: list[str], rows: list[list[str]]) -> str:
    """An aligned plain-text table under ``title``."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = [title, "  ".join(h.ljust(w) for h, w in zip(header, widths)).rstrip()]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    return "\n".join(lines)


def format_markdown(title: str, header: list[str], rows: list[list[str]]) -> str:
    """A Markdown table under a heading."""
    lines = [f"## {title}", "", "| " + " | ".join(header) + " |"]
    lines.append("| --- | --- | " + " | ".join("---:" for _ in header[2:]) + " |")
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def latex_escape(text: str) -> str:
    """``text`` for LaTeX: special characters escaped, ``^2`` as a superscript."""
    out = "".join("\\" + ch if ch in "&%$#_{}" else ch for ch in text)
    out = out.replace("<", "\\textless{}").replace(">", "\\textgreater{}")
    return out.replace("^2", "$^2$").replace("~", "\\textasciitilde{}")


def format_latex(title: str, header: list[str], rows: list[list[str]]) -> str:
    """A ``table`` environment (booktabs rules) with ``title`` as its caption."""
    spec = "ll" + "r" * (len(header) - 2)
    lines = ["% needs \\usepackage{booktabs}", "\\begin{table}[t]", "\\centering",
             f"\\caption{{{latex_escape(title)}}}", f"\\begin{{tabular}}{{{spec}}}",
             "\\toprule", " & ".join(latex_escape(h) for h in header) + " \\\\",
             "\\midrule"]  # fmt: skip
    lines += [" & ".join(latex_escape(c) for c in r) + " \\\\" for r in rows]
    lines += ["\\bottomrule", "\\end{tabular}", "\\end{table}"]
    return "\n".join(lines) + "\n"


def table_csv(path: str, planners: dict[str, dict[str, Any]]) -> None:
    """The table as numbers: metric, unit, then median, q1, q3 and n (the episodes with a
    value) per planner (rates and counts in the median column, blank where undefined), then
    ci_low and ci_high per planner (the 95 % interval: Wilson for a rate, bootstrap for a
    median). Rows: the counts and rates, the tracked metrics (``m_psi``), then the
    ground-truth ones (``gt_m_psi``)."""
    names = list(planners)
    keys, ci = ("median", "q1", "q3", "n"), ("ci_low", "ci_high")
    header = ["metric", "unit"] + [f"{p} {s}" for p in names for s in keys]
    header += [f"{p} {s}" for p in names for s in ci]
    count = ("", "", "")
    rows = [["episodes", "-", *(v for p in names for v in (planners[p]["episodes"], *count)),
             *("" for _ in names for _ in ci)]]  # fmt: skip
    for label, _ in OUTCOMES:
        bounds = [planners[p].get(f"{label}_rate_ci") or ("", "") for p in names]
        rows.append([label, "%", *(v for p in names
                                   for v in (planners[p][f"{label}_rate"], "", "", "")),
                     *(v for b in bounds for v in b)])  # fmt: skip
    pushed = [_blank(planners[p].get("pushed_back_rate")) for p in names]
    bounds = [planners[p].get("pushed_back_rate_ci") or ("", "") for p in names]
    rows.append([PUSHED_BACK_LABEL, "%", *(v for x in pushed for v in (x, "", "", "")),
                 *(v for b in bounds for v in b)])  # fmt: skip
    for prefix, key in (("", "metrics"), (GT_PREFIX, "metrics_gt")):
        for m in METRIC_NAMES:
            stats = [planners[p][key][m] for p in names]
            rows.append([f"{prefix}{m}", METRIC_UNITS[m],
                         *(_blank(s.get(k)) for s in stats for k in keys),
                         *(_blank(s.get(k)) for s in stats for k in ci)])  # fmt: skip
    with open(path, "w", newline="", encoding="utf-8") as f:
        csv.writer(f).writerows([header, *rows])


def _blank(value: float | None) -> Any:
    return "" if value is None else value


WHAT = "median [95 % CI] (rates: Wilson 95 % CI)"


def title_of(env: str, planners: dict[str, dict[str, Any]]) -> str:
    robots = [p for p in planners.values() if isinstance(p.get("robot"), int)]
    if not robots:
        counts = sorted({p["episodes"] for p in planners.values()})
        episodes = "/".join(map(str, counts))
        return f"{env}: {WHAT} over {episodes} episodes per planner"
    counts = "/".join(map(str, sorted({p["episodes"] for p in robots})))
    n = "/".join(map(str, sorted(set(Counter(p["planner"] for p in robots).values()))))
    return (f"{env}, {n} robots: {WHAT} over {counts} episodes per robot; {POOLED}: all "
            f"robots' episodes together")  # fmt: skip


def tables_text(summary: Summary) -> str:
    """Every scenario's table as aligned text, one after the other."""
    return "\n\n".join(format_text(title_of(env, planners), *table(planners))
                        for env, planners in summary.items())  # fmt: skip


def write_tables(summary: Summary, out: str) -> list[str]:
    """Write ``table_<env>.md``, ``.csv`` and ``.tex`` into ``out``; returns the paths."""
    paths = []
    for env, planners in summary.items():
        header, rows = table(planners)
        title = title_of(env, planners)
        base = os.path.join(out, f"table_{env}")
        for suffix, text in ((".md", format_markdown(title, header, rows)),
                             (".tex", format_latex(title, header, rows))):  # fmt: skip
            with open(base + suffix, "w", encoding="utf-8") as f:
                f.write(text)
        table_csv(base + ".csv", planners)
        paths += [base + s for s in (".md", ".csv", ".tex")]
    return paths
