"""``srpb-gym metrics``: the SRPB metrics of one episode, read from SRPB native logs or an
``.npz`` record. Every figure printed is right or refused: a metric that cannot be computed
(the social metrics of a robot log without its people log) is printed as ``n/a`` (``null``
in JSON)."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import warnings
from collections.abc import Sequence
from importlib.resources import files
from pathlib import Path
from typing import Any

from srpb_gym.cli.common import PROG
from srpb_gym.errors import InputError
from srpb_gym.metrics import METRIC_DESCRIPTIONS, METRIC_NAMES, METRIC_UNITS, evaluate, io_native
from srpb_gym.metrics.io import load_episode
from srpb_gym.metrics.params import PARAM_NAMES, PRESETS, SEMANTICS, resolve_params


def add_metrics_command(subparsers: Any) -> None:
    """Register ``metrics``: evaluate one episode and print its SRPB metrics."""
    p = subparsers.add_parser(
        "metrics",
        help="compute the SRPB metrics of one episode",
        description=(
            "Compute the SRPB metrics of one episode, read from SRPB native logs "
            "(*_robot.txt; *_people.txt and *_groups.txt siblings are found automatically "
            "when no other log is given) or from an srpb-gym .npz record."
        ),
        epilog=f"parameter names: {', '.join(PARAM_NAMES)}",
    )
    p.add_argument("robot_log", metavar="ROBOT_LOG", nargs="?", help="robot log, or an .npz record")
    p.add_argument("people_log", metavar="PEOPLE_LOG", nargs="?", help="people log")
    p.add_argument("groups_log", metavar="GROUPS_LOG", nargs="?", help="groups log")
    p.add_argument(
        "--semantics",
        choices=SEMANTICS,
        default="paper",
        help="paper equations or the reference tool's numbers (default: paper)",
    )
    p.add_argument(
        "--preset",
        choices=tuple(PRESETS),
        default="paper",
        help="parameter preset (default: paper)",
    )
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override one parameter (repeatable)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--example",
        action="store_true",
        help="evaluate the bundled example episode (a robot crossing a 5-person F-formation)",
    )
    p.add_argument(
        "--no-people",
        action="store_true",
        help="the run truly had nobody around: score the social metrics of a robot log "
        "without a people log (else they are not computed: n/a)",
    )
    p.add_argument(
        "--no-groups",
        action="store_true",
        help="the run truly had no F-formation: score m_fsi without a groups log "
        "(else it is not computed: n/a)",
    )
    p.set_defaults(func=run_metrics)


def example_log() -> str:
    """Path of the bundled example robot log (its people and groups logs lie beside it)."""
    return str(files("srpb_gym") / "data" / "example" / "fformation5_robot.txt")


def run_metrics(args: argparse.Namespace) -> int:
    """Evaluate the episode named by ``args`` and print its metrics (``n/a``/``null`` for
    the metrics its logs cannot give)."""
    overrides = parse_params(args.param, args.preset)
    if args.example == (args.robot_log is not None):
        raise InputError("give either ROBOT_LOG or --example", key="metrics")
    robot_log = example_log() if args.example else args.robot_log
    record, not_computed, notes = load_metrics_episode(
        robot_log, args.people_log, args.groups_log, args.no_people, args.no_groups
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            values: dict[str, float | None] = dict(
                evaluate(record, args.semantics, args.preset, **overrides)
            )
        except InputError:
            raise
        except ValueError as exc:  # an episode that cannot be evaluated (no sample, ...)
            raise InputError(str(exc), robot_log) from None
    for name in not_computed:
        values[name] = None
    for note in notes:
        print(f"{PROG}: note: {note}", file=sys.stderr)
    for warning in caught:
        print(f"{PROG}: warning: {warning.message}", file=sys.stderr)
    if args.json:
        print(json.dumps({name: _json_number(v) for name, v in values.items()}, indent=2))
    else:
        print(format_table(values, METRIC_UNITS, METRIC_DESCRIPTIONS))
    return 0


def social_metrics(bases: Sequence[str]) -> list[str]:
    """The metric names of the social metrics ``bases`` (``m_psi``, ...) with their
    ``_min``, ``_max`` and ``_viol`` variants."""
    return [m for m in METRIC_NAMES if any(m == b or m.startswith(f"{b}_") for b in bases)]


def load_metrics_episode(
    robot_log: str,
    people_log: str | None = None,
    groups_log: str | None = None,
    no_people: bool = False,
    no_groups: bool = False,
) -> tuple[Any, list[str], list[str]]:
    """The episode of ``srpb-gym metrics``, the metrics its logs cannot give and one note
    per missing log.

    An ``.npz`` record holds its people and groups. For native logs the people and groups
    logs are the ones given or, when none is given, the ``*_people.txt`` /
    ``*_groups.txt`` siblings of a ``*_robot.txt`` log. Without a people log the social
    metrics (m_psi, m_fsi, m_dir) are not computed, without a groups log m_fsi is not,
    unless ``no_people`` / ``no_groups`` say that the run truly had nobody / no group.
    """
    if Path(robot_log).suffix.lower() == ".npz":
        if no_people or no_groups:
            flag = "--no-people" if no_people else "--no-groups"
            raise InputError("an .npz record holds its people and groups itself", robot_log,
                             key=flag)  # fmt: skip
        return load_episode(robot_log, people_log, groups_log), [], []
    people: str | os.PathLike[str] | None = people_log
    groups: str | os.PathLike[str] | None = groups_log
    if people is None and groups is None:
        people, groups = io_native.sibling_logs(robot_log)
    for flag, given, log in (("--no-people", no_people, people), ("--no-groups", no_groups,
                                                                   groups)):  # fmt: skip
        if given and log is not None:
            raise InputError(f"the run has a log of them: {os.fspath(log)}", key=flag)
    no_groups = no_groups or no_people
    missing, notes = [], []
    sibling = "" if people_log is not None or groups_log is not None else " given or found"
    if people is None and not no_people:
        missing += social_metrics(("m_psi", "m_fsi", "m_dir"))
        notes.append(f"no people log{sibling} for {robot_log}: the social metrics m_psi, "
                     f"m_fsi, m_dir are not computed (--no-people: the run had nobody "
                     f"around)")  # fmt: skip
    elif groups is None and not no_groups:
        missing += social_metrics(("m_fsi",))
        notes.append(f"no groups log{sibling} for {robot_log}: m_fsi is not computed "
                     f"(--no-groups: the run had no F-formation)")  # fmt: skip
    # False: the reader's "no such log" (it refuses None, so that no log passes unsaid)
    record = io_native.read_native(robot_log, False if people is None else people,
                                   False if groups is None else groups)  # fmt: skip
    return record, missing, notes


def parse_params(items: Sequence[str], preset: str) -> dict[str, float]:
    """``NAME=VALUE`` overrides as a dict, validated against the parameters of ``preset``.

    Raises :class:`InputError` (key ``--param``) listing the valid names on a bad item.
    """
    overrides: dict[str, Any] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise InputError(f"expected NAME=VALUE, got {item!r}", key="--param")
        overrides[name.strip()] = value.strip()
    try:
        resolve_params(preset, **overrides)
    except KeyError as exc:
        raise InputError(str(exc.args[0]), key="--param") from None
    except ValueError as exc:
        raise InputError(str(exc), key="--param") from None
    return {name: float(value) for name, value in overrides.items()}


def format_table(
    values: dict[str, float | None],
    units: dict[str, str],
    descriptions: dict[str, str] | None = None,
) -> str:
    """An aligned table: metric, value (6 significant digits; ``n/a`` for ``None``, not
    computed), unit, and what it measures."""
    descriptions = descriptions or {}
    rows = [("metric", "value", "unit", "")]
    rows += [
        (name, "n/a" if v is None else f"{float(v):.6g}", units.get(name, ""),
         descriptions.get(name, ""))
        for name, v in values.items()
    ]  # fmt: skip
    w = [max(len(r[i]) for r in rows) for i in range(3)]
    return "\n".join(f"{n:<{w[0]}}  {v:>{w[1]}}  {u:<{w[2]}}  {d}".rstrip() for n, v, u, d in rows)


def _json_number(value: float | None) -> float | str | None:
    """A float for JSON; non-finite values as the strings NaN, Infinity, -Infinity; ``None``
    (not computed) as ``null``."""
    if value is None:
        return None
    value = float(value)
    if math.isnan(value):
        return "NaN"
    if math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    return value
