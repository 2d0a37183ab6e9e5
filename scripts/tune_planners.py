"""Run planners over seeded episodes of the scenarios and print their outcome statistics.

    python scripts/tune_planners.py --planners dwa social-dwa --scenarios corridor fformation \
        --seeds 20 --planner-param dwa.horizon=2.5 --planner-param social-dwa.w_psi=6

For each planner and scenario: success, collision and timeout rates over the seeds
0..N-1 and the median SRPB metrics m_psi, m_fsi, m_dir [%] and m_mef [s] (tracked
people), and the median decision time [ms]. Episodes run through the evaluation harness's
loop (:func:`srpb_gym.evaluation.run_episode`). Planner settings are given as for
``srpb-gym eval``: ``--planner-config FILE`` (YAML, ``{NAME: {FIELD: VALUE}}``) and
``--planner-param NAME.FIELD=VALUE`` on top. ``--verbose`` prints every episode.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import srpb_gym  # noqa: F401 - registers the environments
from srpb_gym.errors import InputError
from srpb_gym.evaluation import run_episode
from srpb_gym.planners import PLANNERS, Planner, check_settings, make_planner, planner_config
from srpb_gym.planners.config import planner_settings
from srpb_gym.seeds import check_not_test

IDS = {
    "corridor": "SRPB-Corridor-v0",
    "fformation": "SRPB-FFormation-v0",
    "crossing": "SRPB-Crossing-v0",
    "crowd": "SRPB-Crowd-v0",
    "doorway": "SRPB-Doorway-v0",
}
METRICS = ("m_psi", "m_fsi", "m_dir", "m_mef")


def episode_row(env: gym.Env, planner: Planner, seed: int, people: bool = True) -> dict:
    """One episode's outcome (1.0 or 0.0), SRPB metrics and median decision time [ms]."""
    times: list[float] = []
    options = None if people else {"people": False}
    out = run_episode(env, planner, seed, options=options, on_act=times.append)
    info = out["info"]
    row = {
        "success": float(info["is_success"]),
        "collision": float(out["collision"]),
        "timeout": float(out["timeout"]),
        "act_ms": 1000.0 * float(np.median(times)),
    }
    return row | {m: float(info[f"srpb/{m}"]) for m in METRICS}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--planners", nargs="+", default=sorted(PLANNERS))
    ap.add_argument("--scenarios", nargs="+", default=list(IDS), choices=list(IDS))
    ap.add_argument("--seeds", type=int, default=20, help="seeds 0..N-1")
    ap.add_argument("--first-seed", type=int, default=0,
                    help="first seed (tuning chooses: never a test seed, srpb_gym/seeds.py)",
                    )  # fmt: skip
    ap.add_argument("--planner-config", metavar="FILE", help="YAML file of planner settings")
    ap.add_argument("--planner-param", action="append", default=[], metavar="NAME.FIELD=VALUE",
                    help="one planner setting, e.g. dwa.horizon=2.5 (repeatable)")  # fmt: skip
    ap.add_argument("--no-people", action="store_true", help="empty variants of the scenarios")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args(argv)
    try:
        check_not_test(args.first_seed, args.seeds, "--first-seed")
        settings = check_settings(planner_settings(args.planner_config, args.planner_param))
        for name in args.planners:
            planner_config(name, settings.get(name))
    except (InputError, KeyError) as exc:
        ap.error(str(exc))
    header = f"{'planner':<13}{'scenario':<11}{'succ':>6}{'coll':>6}{'tout':>6}"
    header += "".join(f"{m:>9}" for m in METRICS) + f"{'act ms':>8}"
    print(header)
    for name in args.planners:
        for scenario in args.scenarios:
            env = gym.make(IDS[scenario])
            planner = make_planner(name, settings.get(name))
            rows = []
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                row = episode_row(env, planner, seed, people=not args.no_people)
                rows.append(row)
                if args.verbose:
                    flags = "S" if row["success"] else ("C" if row["collision"] else "T")
                    vals = " ".join(f"{m}={row[m]:.3g}" for m in METRICS)
                    print(f"  {name} {scenario} seed={seed} {flags} {vals}", flush=True)
            env.close()
            rate = {key: 100.0 * np.mean([r[key] for r in rows])
                    for key in ("success", "collision", "timeout")}  # fmt: skip
            med = {m: float(np.median([r[m] for r in rows])) for m in METRICS}
            act = float(np.median([r["act_ms"] for r in rows]))
            line = f"{name:<13}{scenario:<11}{rate['success']:>5.0f}%{rate['collision']:>5.0f}%"
            line += f"{rate['timeout']:>5.0f}%" + "".join(f"{med[m]:>9.3g}" for m in METRICS)
            print(line + f"{act:>8.2f}", flush=True)


if __name__ == "__main__":
    main()
