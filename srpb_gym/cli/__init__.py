"""The ``srpb-gym`` command line.

Usage::

    srpb-gym metrics ROBOT_LOG [PEOPLE_LOG [GROUPS_LOG]] [--semantics S] [--preset P]
                     [--param NAME=VALUE ...] [--json] [--no-people] [--no-groups]
    srpb-gym eval [--env ID|FILE ...] [--planner NAME ...] [--planner-config FILE]
                  [--planner-param NAME.FIELD=VALUE ...] [--policy PATH ...]
                  [--policy-algo ALGO] [--vecnormalize FILE|none] [--episodes N] [--seed S]
                  [--out DIR] [--resume] [--workers N] [--warmup STEPS] [--video [K]]
                  [--video-stride K] [--robots N] [--semantics S] [--preset P]
                  [--env-kwargs KEY=VALUE ...] [--trust-pickle]
    srpb-gym compare DIR [DIR ...] [--out DIR] [--separate]
    srpb-gym train --env ID [--reward PRESET] [--seed S] [--steps N]
                   [--hyperparams KEY=VALUE ...] [--env-kwargs KEY=VALUE ...] [--config FILE]
                   [--out DIR] [--max-minutes M] [--init MODEL] [--init-new-observation]
                   [--trust-pickle] [--no-progress]
    srpb-gym --version

Every subcommand is registered by one ``add_<name>_command(subparsers)`` function listed in
:data:`COMMANDS`; it sets ``func`` (taking the parsed arguments, returning the exit status).
Each lives in a module of its own: :mod:`srpb_gym.cli.metrics`, :mod:`srpb_gym.cli.eval`,
:mod:`srpb_gym.cli.compare` and :mod:`srpb_gym.training.cli` (``train``).
Exit status: 0 on success, 2 on bad input (one line ``srpb-gym: error: ...`` on stderr),
130 when an evaluation is interrupted (Ctrl-C; what finished is kept, ``--resume`` goes on).
Every figure printed is right or refused: a metric that cannot be computed (the social
metrics of a robot log without its people log) is printed as ``n/a`` (``null`` in JSON).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

from srpb_gym._version import __version__
from srpb_gym.cli.common import PROG
from srpb_gym.cli.compare import add_compare_command, run_compare
from srpb_gym.cli.eval import add_eval_command, run_eval
from srpb_gym.cli.metrics import (
    add_metrics_command,
    example_log,
    format_table,
    load_metrics_episode,
    parse_params,
    run_metrics,
    social_metrics,
)
from srpb_gym.errors import InputError
from srpb_gym.training.cli import add_train_command

__all__ = [
    "COMMANDS",
    "PROG",
    "add_compare_command",
    "add_eval_command",
    "add_metrics_command",
    "add_train_command",
    "build_parser",
    "example_log",
    "format_table",
    "load_metrics_episode",
    "main",
    "parse_params",
    "run_compare",
    "run_eval",
    "run_metrics",
    "social_metrics",
]

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
