"""Decision time of the classical planners.

    python benchmarks/bench_planners.py [--episodes 3] [--planners dwa social-dwa]
        [--planner-config FILE] [--planner-param dwa.horizon=2.5 ...]

For each planner on SRPB-Crowd-v0 and SRPB-Corridor-v0, runs a few seeded episodes (the
evaluation harness's episode loop, :func:`srpb_gym.evaluation.run_episode`) and prints the
median and 95th percentile of the time of its ``act`` calls [ms], and the median time of
``reset`` (which builds the grid and the static cost-to-go) separately. The first episode
of each planner is run once before timing, so compilation (or loading numba's cache) is
not counted. Planner settings are given as for ``srpb-gym eval``.
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

SCENARIOS = ("SRPB-Crowd-v0", "SRPB-Corridor-v0")


def time_episode(env: gym.Env, planner: Planner, seed: int) -> tuple[list[float], float]:
    """Durations [s] of every ``act`` call of one episode, and of ``reset``."""
    times: list[float] = []
    out = run_episode(env, planner, seed, on_act=times.append)
    return times, out["reset_time"]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--planners", nargs="+", default=sorted(PLANNERS))
    ap.add_argument("--planner-config", metavar="FILE", help="YAML file of planner settings")
    ap.add_argument("--planner-param", action="append", default=[], metavar="NAME.FIELD=VALUE",
                    help="one planner setting (repeatable)")  # fmt: skip
    args = ap.parse_args(argv)
    try:
        settings = check_settings(planner_settings(args.planner_config, args.planner_param))
        for name in args.planners:
            planner_config(name, settings.get(name))
    except (InputError, KeyError) as exc:
        ap.error(str(exc))
    print(f"{'planner':<14}{'scenario':<20}{'steps':>7}{'median ms':>11}{'p95 ms':>9}"
          f"{'max ms':>9}{'reset ms':>10}")  # fmt: skip
    for name in args.planners:
        for env_id in SCENARIOS:
            env = gym.make(env_id)
            planner = make_planner(name, settings.get(name))
            time_episode(env, planner, seed=1000)  # warm up: compile or load the caches
            acts, resets = [], []
            for seed in range(args.episodes):
                times, reset_time = time_episode(env, planner, seed)
                acts += times
                resets.append(reset_time)
            ms = 1000.0 * np.array(acts)
            print(f"{name:<14}{env_id:<20}{ms.size:>7}{np.median(ms):>11.2f}"
                  f"{np.percentile(ms, 95):>9.2f}{ms.max():>9.2f}"
                  f"{1000.0 * np.median(resets):>10.1f}", flush=True)  # fmt: skip
            env.close()


if __name__ == "__main__":
    main()
