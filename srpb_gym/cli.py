"""The ``srpb-gym`` command line.

Usage::

    srpb-gym metrics ROBOT_LOG [PEOPLE_LOG [GROUPS_LOG]] [--semantics S] [--preset P]
                     [--param NAME=VALUE ...] [--json] [--no-people] [--no-groups]
    srpb-gym eval [--env ID|FILE ...] [--planner NAME ...] [--planner-config FILE]
                  [--planner-param NAME.FIELD=VALUE ...] [--policy PATH ...]
                  [--policy-algo ALGO] [--vecnormalize FILE|none] [--episodes N] [--seed S]
                  [--out DIR] [--resume] [--workers N] [--warmup STEPS] [--video [K]]
                  [--video-stride K] [--robots N] [--semantics S] [--preset P]
                  [--env-kwargs KEY=VALUE ...]
    srpb-gym compare DIR [DIR ...] [--out DIR] [--separate]
    srpb-gym train --env ID [--reward PRESET] [--seed S] [--steps N]
                   [--hyperparams KEY=VALUE ...] [--env-kwargs KEY=VALUE ...] [--config FILE]
                   [--out DIR] [--no-progress]
    srpb-gym --version

Every subcommand is registered by one ``add_<name>_command(subparsers)`` function listed in
:data:`COMMANDS`; it sets ``func`` (taking the parsed arguments, returning the exit status).
Exit status: 0 on success, 2 on bad input (one line ``srpb-gym: error: ...`` on stderr),
130 when an evaluation is interrupted (Ctrl-C; what finished is kept, ``--resume`` goes on).
Every figure printed is right or refused: a metric that cannot be computed (the social
metrics of a robot log without its people log) is printed as ``n/a`` (``null`` in JSON).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Any

from srpb_gym import __version__
from srpb_gym.errors import InputError
from srpb_gym.training.cli import add_train_command

PROG = "srpb-gym"


# ---------------------------------------------------------------------------- metrics
def add_metrics_command(subparsers: Any) -> None:
    """Register ``metrics``: evaluate one episode and print its SRPB metrics."""
    from srpb_gym.metrics.params import PARAM_NAMES, PRESETS, SEMANTICS

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
    from importlib.resources import files

    return str(files("srpb_gym") / "data" / "example" / "fformation5_robot.txt")


def run_metrics(args: argparse.Namespace) -> int:
    """Evaluate the episode named by ``args`` and print its metrics (``n/a``/``null`` for
    the metrics its logs cannot give)."""
    from srpb_gym.metrics import METRIC_DESCRIPTIONS, METRIC_UNITS, evaluate

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
    from srpb_gym.metrics import METRIC_NAMES

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
    from pathlib import Path

    from srpb_gym.metrics import io_native
    from srpb_gym.metrics.io import load_episode

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
    from srpb_gym.metrics.params import resolve_params

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


# ---------------------------------------------------------------------------- eval
def add_eval_command(subparsers: Any) -> None:
    """Register ``eval``: run planners and policies on scenarios, write the results."""
    from srpb_gym.evaluation.spec import DEFAULT_WARMUP, ENV_IDS
    from srpb_gym.metrics.params import PRESETS, SEMANTICS

    p = subparsers.add_parser(
        "eval",
        help="evaluate planners and learned policies on scenarios",
        description=(
            "Run every planner on every scenario for N episodes (episode i uses seed S+i), "
            "print one table per scenario (median [interquartile range] of every SRPB metric, "
            "success, collision and timeout rates) and write episodes, tables, figures and "
            "the configuration into --out. Without --env/--planner/--policy: "
            "SRPB-Corridor-v0 with every registered planner, 5 episodes."
        ),
        epilog=f"environment ids: {', '.join(ENV_IDS)}; or a scenario file "
        "(envs/my_lab.yaml), run as SRPB-Custom-v0 and labelled by its scenario name",
    )
    many = {"action": "extend", "nargs": "+"}
    p.add_argument("--env", metavar="ID|FILE", **many,
                   help="environment id(s) or scenario file(s) (.yaml)")  # fmt: skip
    p.add_argument("--planner", metavar="NAME", **many, help="registered planner(s)")
    p.add_argument("--planner-config", metavar="FILE",
                   help="YAML file of planner settings: {NAME: {FIELD: VALUE}}, nested "
                        "configs as nested mappings (see docs/planners.md)")  # fmt: skip
    p.add_argument("--planner-param", metavar="NAME.FIELD=VALUE", action="append", default=[],
                   help="set one planner setting, e.g. dwa.horizon=2.5 or "
                        "dwa.global_planner.spacing=0.2 (repeatable; applied over "
                        "--planner-config)")  # fmt: skip
    p.add_argument("--policy", metavar="PATH", **many, default=[],
                   help="stable-baselines3 model .zip file(s), srpb-gym train run "
                        "folder(s) (their model.zip) or shipped model name(s), each named "
                        "after the file, folder or name")  # fmt: skip
    p.add_argument("--policy-algo", default=None, metavar="ALGO",
                   help="force the algorithm of the --policy files: PPO, A2C, SAC, TD3, DDPG "
                        "or DQN (default: read from each file)")  # fmt: skip
    p.add_argument("--vecnormalize", default="auto", metavar="FILE",
                   help="observation-normalisation statistics of the --policy files, or "
                        "'none' for raw observations (default: vecnormalize.pkl where "
                        "srpb-gym train or the RL Zoo put it, see docs/evaluation.md)")  # fmt: skip
    p.add_argument("--episodes", type=int, default=5, metavar="N", help="per pair (default: 5)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="first seed (default: 0)")
    p.add_argument("--out", metavar="DIR",
                   help="output folder, new or empty (default: runs/eval-<time>)")  # fmt: skip
    p.add_argument("--resume", action="store_true",
                   help="continue the interrupted run in --out (same options; finished "
                        "episodes are kept, the others run)")  # fmt: skip
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="worker processes (default: 1; at most the CPU count and the "
                        "number of episodes)")  # fmt: skip
    p.add_argument("--warmup", type=int, default=DEFAULT_WARMUP, metavar="STEPS",
                   help="untimed control steps of each planner before its first timed "
                        f"episode, in each process (default: {DEFAULT_WARMUP}; 0: none)",
                   )  # fmt: skip
    p.add_argument("--video", type=int, nargs="?", const=1, default=0, metavar="K",
                   help="film the first K episodes of each pair (default K: 1)")  # fmt: skip
    p.add_argument("--video-stride", type=int, default=1, metavar="K",
                   help="film every K-th control step, played at the render rate / K, so "
                        "in real time (default: 1; the last step is always filmed)",
                   )  # fmt: skip
    p.add_argument("--robots", type=int, default=1, metavar="N",
                   help="robots per episode (default: 1). N > 1 runs the multi-robot "
                        "(PettingZoo) environment: a planner instance per robot, a --policy "
                        "shared by all; results per robot and pooled")  # fmt: skip
    p.add_argument("--semantics", choices=SEMANTICS, default="paper",
                   help="metric semantics (default: paper)")  # fmt: skip
    p.add_argument("--preset", choices=tuple(PRESETS), default="paper",
                   help="metric parameter preset (default: paper)")  # fmt: skip
    p.add_argument("--env-kwargs", **many, default=[], metavar="KEY=VALUE",
                   help="keyword arguments of every environment, values in YAML, e.g. "
                        "'crowd={robot_reaction: 0.0}' (as srpb-gym train --env-kwargs); "
                        "a model of srpb-gym train observes with the observation settings "
                        "it records")  # fmt: skip
    p.set_defaults(func=run_eval)


def _stderr(line: str) -> None:
    print(f"{PROG}: {line}", file=sys.stderr)


def run_eval(args: argparse.Namespace) -> int:
    """Run the evaluation described by ``args``; 130 when interrupted."""
    from srpb_gym.config import parse_overrides
    from srpb_gym.evaluation import resolve_config, run_evaluation
    from srpb_gym.planners.config import planner_settings

    if args.video:
        from srpb_gym.evaluation.figures import video_support

        missing = video_support()
        if missing:
            raise InputError(missing, key="--video")
    if args.resume and not args.out:
        raise InputError("give the folder of the run to continue with --out", key="--resume")
    config = resolve_config(
        args.env, args.planner, args.policy, policy_algo=args.policy_algo,
        vecnormalize=args.vecnormalize, episodes=args.episodes, seed=args.seed, out=args.out,
        workers=args.workers, video=args.video, semantics=args.semantics, preset=args.preset,
        planner_settings=planner_settings(args.planner_config, args.planner_param),
        argv=getattr(args, "argv", ()), warmup=args.warmup, resume=args.resume, log=_stderr,
        robots=args.robots, env_kwargs=parse_overrides(args.env_kwargs, "--env-kwargs"),
        video_stride=args.video_stride,
    )  # fmt: skip
    try:
        outcome = run_evaluation(config, log=_stderr)
    except KeyboardInterrupt:  # outside the episodes (set-up, figures)
        print(f"{PROG}: interrupted; partial results in {config.out}", file=sys.stderr)
        return 130
    if outcome.text:
        print(outcome.text)
    if outcome.interrupted:
        print(f"{PROG}: interrupted: {outcome.finished} of {outcome.planned} episodes "
              f"finished; results so far in {config.out} (--resume continues)",
              file=sys.stderr)  # fmt: skip
        return 130
    print(f"\nresults in {config.out}")
    return 0


# ---------------------------------------------------------------------------- compare
def add_compare_command(subparsers: Any) -> None:
    """Register ``compare``: merge earlier evaluations into one table per scenario."""
    p = subparsers.add_parser(
        "compare",
        help="compare earlier evaluation runs",
        description=(
            "Merge the episodes.csv of earlier `srpb-gym eval` runs into one table per "
            "scenario. A planner present in several runs is labelled PLANNER@RUN_FOLDER. "
            "Runs made with different --semantics, --preset, metric parameters or --robots "
            "(read from each run's config.json) are refused unless --separate keeps them "
            "apart. A cell over fewer episodes than the 'episodes' row (undefined values "
            "left out) says so: (n=18/20)."
        ),
    )
    p.add_argument("dirs", metavar="DIR", nargs="+", help="evaluation folder (or episodes.csv)")
    p.add_argument("--out", metavar="DIR", help="also write the merged results and tables here")
    p.add_argument("--separate", action="store_true",
                   help="keep runs made with different settings apart, as columns "
                        "PLANNER@RUN, instead of refusing them")  # fmt: skip
    p.set_defaults(func=run_compare)


def run_compare(args: argparse.Namespace) -> int:
    """Print (and with ``--out`` write) the merged comparison tables."""
    from srpb_gym.evaluation import compare_runs

    text, _ = compare_runs(args.dirs, args.out, separate=args.separate)
    print(text)
    return 0


# ---------------------------------------------------------------------------- main
COMMANDS: list[Callable[[Any], None]] = [
    add_metrics_command, add_eval_command, add_compare_command, add_train_command,
]  # fmt: skip
"""Functions registering one subcommand each on the subparsers object."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand of :data:`COMMANDS`."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Human-aware robot navigation benchmark scored by the SRPB metrics.",
    )
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for register in COMMANDS:
        register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 bad input or usage)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        args.argv = tuple(sys.argv[1:] if argv is None else argv)
    except SystemExit as exc:  # --help, --version and usage errors
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if getattr(args, "func", None) is None:
        parser.print_usage(sys.stderr)
        print(f"{PROG}: error: a command is required", file=sys.stderr)
        return 2
    try:
        return args.func(args)
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # stdout closed early (piped into head, ...)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
