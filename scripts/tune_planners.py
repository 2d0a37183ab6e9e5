"""Run planners over seeded episodes of the scenarios and print their outcome statistics.

    python scripts/tune_planners.py --planners dwa social-dwa --scenarios corridor fformation \
        --seeds 20

For each planner and scenario: success, collision and timeout rates over the seeds
0..N-1 and the median SRPB metrics m_psi, m_fsi, m_dir [%] and m_mef [s] (tracked
people). ``--param NAME=VALUE`` passes keyword arguments to the planners' constructors
(numbers are parsed), ``--verbose`` prints every episode.
"""

from __future__ import annotations

import argparse
import ast
import time

import gymnasium as gym
import numpy as np

import srpb_gym  # noqa: F401 - registers the environments
from srpb_gym.planners import PLANNERS, make_planner

IDS = {
    "corridor": "SRPB-Corridor-v0",
    "fformation": "SRPB-FFormation-v0",
    "crossing": "SRPB-Crossing-v0",
    "crowd": "SRPB-Crowd-v0",
    "doorway": "SRPB-Doorway-v0",
}
METRICS = ("m_psi", "m_fsi", "m_dir", "m_mef")


def run_episode(env: gym.Env, planner, seed: int, people: bool = True) -> dict[str, float]:
    """One episode; returns its outcome, SRPB metrics and the planner's decision times."""
    obs, _ = env.reset(seed=seed, options=None if people else {"people": False})
    planner.reset(env.unwrapped.knowledge())
    times = []
    while True:
        knowledge = env.unwrapped.knowledge()
        t0 = time.perf_counter()
        action = planner.act(obs, knowledge)
        times.append(time.perf_counter() - t0)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    out = {
        "success": float(info["is_success"]),
        "collision": float(info["collision"]),
        "timeout": float(truncated),
        "act_ms": 1000.0 * float(np.median(times)),
    }
    out |= {m: float(info[f"srpb/{m}"]) for m in METRICS}
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--planners", nargs="+", default=sorted(PLANNERS))
    ap.add_argument("--scenarios", nargs="+", default=list(IDS), choices=list(IDS))
    ap.add_argument("--seeds", type=int, default=20, help="seeds 0..N-1")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--param", action="append", default=[], help="NAME=VALUE for the planner")
    ap.add_argument("--no-people", action="store_true", help="empty variants of the scenarios")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args(argv)
    kwargs = {}
    for item in args.param:
        key, value = item.split("=", 1)
        try:
            kwargs[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            kwargs[key] = value
    header = f"{'planner':<13}{'scenario':<11}{'succ':>6}{'coll':>6}{'tout':>6}"
    header += "".join(f"{m:>9}" for m in METRICS) + f"{'act ms':>8}"
    print(header)
    for name in args.planners:
        for scenario in args.scenarios:
            env = gym.make(IDS[scenario])
            planner = make_planner(name, **kwargs) if name != "go-to-goal" else make_planner(name)
            rows = []
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                row = run_episode(env, planner, seed, people=not args.no_people)
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
