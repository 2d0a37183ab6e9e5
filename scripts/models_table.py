"""The shipped models' test figures, from their cards, as one Markdown table.

    python scripts/models_table.py            # every shipped model
    python scripts/models_table.py ppo-crowd-srpb ppo-crowd-task

One row per model and scenario it was tested on (a policy shared by several robots: one
row per planner of its test, its own and the classical robots beside it): the test seeds,
success and collision rates with Wilson 95 % intervals (the collisions the robot caused in
brackets), and the medians of ``m_psi``, ``m_fsi`` and ``m_dir`` from the true people
beside those from the tracked ones. A card shipped before the ground truth was kept shows
the tracked figures only ("n/a" for the truth). docs/results.md holds its output.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from srpb_gym.evaluation.intervals import wilson
from srpb_gym.models import card, model_names

METRICS = ("m_psi", "m_fsi", "m_dir")


def rate(f: dict[str, Any], key: str, n: int) -> str:
    """``key``'s rate in % with its Wilson 95 % interval."""
    low, high = wilson(round(f[key] * n), n) or (0.0, 0.0)
    return f"{100 * f[key]:.1f} [{low:.1f}-{high:.1f}]"


def row(label: str, where: str, seeds: str, f: dict[str, Any], n: int) -> str:
    """One table row of the figures ``f`` over ``n`` episodes."""
    caused = f.get("caused_collision")
    collision = rate(f, "collision", n) + ("" if caused is None else f" ({100 * caused:.1f})")
    metrics = " | ".join(
        (f"{f['gt_' + m]:.3g}" if "gt_" + m in f else "n/a") + f" / {f[m]:.3g}" for m in METRICS
    )
    return f"| {label} | {where} | {seeds} | {rate(f, 'success', n)} | {collision} | {metrics} |"


def table(names: list[str]) -> str:
    """The Markdown table of the models ``names``."""
    lines = [
        "| model | tested on | seeds | success % | collision % (robot's) | m_psi % GT / tracked "
        "| m_fsi % GT / tracked | m_dir % GT / tracked |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name in names:
        facts = card(name)
        test = facts["test"]
        seeds = f"{test['seed']}-{test['seed'] + test['episodes'] - 1}"
        if "robots" in facts:  # the planners of a multi-robot test, every robot's episode
            where = f"{facts['env']}, {facts['robots']} robots"
            for planner, f in test["results"].items():
                label = f"`{name}`" if planner == name else f"{facts['robots']} x `{planner}`"
                lines.append(row(label, where, seeds, f, f["episodes"]))
            continue
        for env_id, f in test["results"].items():
            lines.append(row(f"`{name}`", env_id, seeds, f, round(f["episodes"])))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", metavar="MODEL", help="default: every shipped model")
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in model_names()]
    if unknown:
        parser.error(f"no shipped model {unknown[0]!r}; shipped: {', '.join(model_names())}")
    print(table(args.names or model_names()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
