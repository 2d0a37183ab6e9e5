"""``srpb-gym compare``: earlier evaluation runs merged into one table per scenario
(:func:`srpb_gym.evaluation.compare_runs`)."""

from __future__ import annotations

import argparse
from typing import Any

from srpb_gym.evaluation import compare_runs


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
            "left out) says so: (n=18/20). Planners of runs that agree are compared with the "
            "first on the episodes they share, paired by (scenario, seed[, robot]): printed "
            "after the tables, and with --out written as paired.md and paired.json."
        ),
    )
    p.add_argument("dirs", metavar="DIR", nargs="+", help="evaluation folder (or episodes.csv)")
    p.add_argument("--out", metavar="DIR", help="also write the merged results and tables here")
    p.add_argument("--separate", action="store_true",
                   help="keep runs made with different settings apart, as columns "
                        "PLANNER@RUN, instead of refusing them")  # fmt: skip
    p.add_argument("--reference", metavar="PLANNER",
                   help="the planner every other is tested against (default: the first "
                        "of each scenario)")  # fmt: skip
    p.set_defaults(func=run_compare)


def run_compare(args: argparse.Namespace) -> int:
    """Print (and with ``--out`` write) the merged comparison tables."""
    text, _ = compare_runs(args.dirs, args.out, separate=args.separate, reference=args.reference)
    print(text)
    return 0
