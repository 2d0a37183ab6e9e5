"""Whether every packaged scenario is solvable: the reference planner on each of them.

    python benchmarks/bench_reference_planner.py [--episodes 100] [--seed 3000000]
        [--workers 2] [--out DIR] [--planner oracle-social-dwa] [--env ID ...]
        [--planner-param oracle-social-dwa.FIELD=VALUE ...]

Runs a reference planner (:data:`srpb_gym.planners.REFERENCE_PLANNERS`, handed the true
people instead of the tracker's) for ``--episodes`` episodes on every packaged scenario
with the evaluation harness (:func:`srpb_gym.evaluation.resolve_config` and
:func:`~srpb_gym.evaluation.run_evaluation`: the same episodes as ``srpb-gym eval
--planner oracle-social-dwa``, every file of an evaluation written into ``--out``), and
prints per scenario the success rate with its Wilson 95 % interval, the collision and
timeout rates, and whether the target holds (:data:`TARGET_SUCCESS` and
:data:`TARGET_COLLISIONS`, on the measured rates): PASS or FAIL. Exit status 1 when a
scenario fails.

Seeds: from the validation range (``srpb_gym.seeds.VALIDATION``, 3,000,000 on) by
default, as for any figure that may still lead to a choice (such as the reference
planner's settings); ``--seed 20000000`` measures on the test range, as the published
tables do.

The collision column counts every episode with a collision, the next one those the robot
caused (:func:`caused_by_robot`: the episode's first collision as attributed by
:mod:`srpb_gym.sim.contact`; a collision not attributed counts against the robot). The
target is on the collisions the robot causes. Columns are built from :data:`COLUMNS`, one
function each.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from srpb_gym.errors import InputError
from srpb_gym.evaluation import EpisodeResult, resolve_config, run_evaluation
from srpb_gym.evaluation.intervals import wilson
from srpb_gym.planners import REFERENCE_PLANNERS
from srpb_gym.planners.config import planner_settings
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.seeds import VALIDATION, range_of

SCENARIOS: tuple[str, ...] = tuple(SCENARIO_IDS)
TARGET_SUCCESS = 95.0
"""%, the least success rate of a solvable scenario."""
TARGET_COLLISIONS = 2.0
"""%, the largest rate of episodes in which the robot causes a contact."""


def caused_by_robot(result: EpisodeResult) -> bool:
    """Whether the robot caused the episode's collision (an unattributed one counts)."""
    first = result.first_collision
    return result.collision and (first is None or first.by == "robot")


def percent(count: int, n: int) -> float:
    """``count`` of ``n`` in % (0 for no episode)."""
    return 100.0 * count / n if n else 0.0


def success_cell(results: Sequence[EpisodeResult]) -> str:
    """Success rate [Wilson 95 % interval] in %."""
    n, k = len(results), sum(r.is_success for r in results)
    low, high = wilson(k, n) or (float("nan"), float("nan"))
    return f"{percent(k, n):5.1f} [{low:5.1f}, {high:5.1f}]"


def rate_cell(flag: Callable[[EpisodeResult], bool]) -> Callable[[Sequence[EpisodeResult]], str]:
    """A column of the rate of the episodes ``flag`` marks, in % (with the count)."""

    def cell(results: Sequence[EpisodeResult]) -> str:
        k = sum(bool(flag(r)) for r in results)
        return f"{percent(k, len(results)):5.1f} ({k})"

    return cell


#: (header, width, cell of a scenario's results): the printed columns after the scenario
COLUMNS: list[tuple[str, int, Callable[[Sequence[EpisodeResult]], str]]] = [
    ("episodes", 9, lambda results: str(len(results))),
    ("success % [Wilson 95 %]", 25, success_cell),
    ("collision %", 12, rate_cell(lambda r: r.collision)),
    ("by robot %", 12, rate_cell(caused_by_robot)),
    ("timeout %", 11, rate_cell(lambda r: r.timeout)),
]


def check(results: Sequence[EpisodeResult]) -> bool:
    """Whether a scenario's episodes meet the target: success rate at least
    :data:`TARGET_SUCCESS`, rate of contacts the robot caused at most
    :data:`TARGET_COLLISIONS` (measured rates, in %)."""
    n = len(results)
    success = percent(sum(r.is_success for r in results), n)
    caused = percent(sum(caused_by_robot(r) for r in results), n)
    return n > 0 and success >= TARGET_SUCCESS and caused <= TARGET_COLLISIONS


def report(envs: Sequence[str], results: Sequence[EpisodeResult]) -> tuple[str, bool]:
    """The table (a row per scenario of ``envs``) and whether every scenario passes."""
    header = f"{'scenario':<20}" + "".join(f"{h:>{w}}" for h, w, _ in COLUMNS) + "  target"
    lines, passed = [header], True
    for env in envs:
        mine = [r for r in results if r.env == env]
        ok = check(mine)
        passed &= ok
        cells = "".join(f"{cell(mine):>{w}}" for _, w, cell in COLUMNS)
        lines.append(f"{env:<20}{cells}  {'PASS' if ok else 'FAIL'}")
    return "\n".join(lines), passed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--planner", default=next(iter(REFERENCE_PLANNERS)),
                    choices=tuple(REFERENCE_PLANNERS), help="the reference planner")  # fmt: skip
    ap.add_argument("--env", nargs="+", default=list(SCENARIOS), metavar="ID",
                    help="environment ids (default: every packaged scenario)")  # fmt: skip
    ap.add_argument("--episodes", type=int, default=100, help="per scenario (default: 100)")
    ap.add_argument("--seed", type=int, default=VALIDATION.start,
                    help=f"first seed (default: {VALIDATION.start}, validation seeds)")  # fmt: skip
    ap.add_argument("--workers", type=int, default=1, help="worker processes (default: 1)")
    ap.add_argument("--out", metavar="DIR", help="output folder (default: runs/bench-reference-"
                    "<time>)")  # fmt: skip
    ap.add_argument("--planner-config", metavar="FILE", help="YAML file of planner settings")
    ap.add_argument("--planner-param", action="append", default=[], metavar="NAME.FIELD=VALUE",
                    help="one planner setting (repeatable)")  # fmt: skip
    args = ap.parse_args(argv)
    out = args.out or str(Path("runs") / time.strftime("bench-reference-%Y%m%d-%H%M%S"))
    # the srpb-gym command of the same episodes, which the run's command.txt records
    same = ["eval", "--env", *args.env, "--planner", args.planner, "--episodes",
            str(args.episodes), "--seed", str(args.seed), "--workers", str(args.workers),
            "--out", out]  # fmt: skip
    if args.planner_config:
        same += ["--planner-config", args.planner_config]
    same += [f"--planner-param={p}" for p in args.planner_param]
    try:
        config = resolve_config(
            args.env, [args.planner], episodes=args.episodes, seed=args.seed, out=out,
            workers=args.workers, argv=tuple(same),
            planner_settings=planner_settings(args.planner_config, args.planner_param),
        )  # fmt: skip
    except InputError as exc:
        ap.error(str(exc))
    seeds = range_of(args.seed)
    where = seeds.name if seeds is not None else "no named range"
    print(f"{args.planner}: {args.episodes} episodes per scenario, seeds {args.seed}-"
          f"{args.seed + args.episodes - 1} ({where}), {config.workers} worker(s); target "
          f"success >= {TARGET_SUCCESS:g} %, collisions caused by the robot <= "
          f"{TARGET_COLLISIONS:g} %", flush=True)  # fmt: skip
    outcome = run_evaluation(config)
    if outcome.interrupted:
        print(f"interrupted: {outcome.finished} of {outcome.planned} episodes; --out {out}")
        return 130
    text, passed = report(config.envs, outcome.results)
    print(text)
    print(f"\n{'every scenario passes' if passed else 'some scenario fails'}; results in {out}")
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
