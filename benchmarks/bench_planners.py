"""Decision time of the classical planners.

    python benchmarks/bench_planners.py [--episodes 3] [--planners dwa social-dwa]

For each planner on SRPB-Crowd-v0 and SRPB-Corridor-v0, runs a few seeded episodes and
prints the median and 95th percentile of the time of its ``act`` calls [ms], and the
median time of ``reset`` (which builds the grid and the static cost-to-go) separately.
The first episode of each planner is run once before timing, so compilation (or loading
numba's cache) is not counted.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import srpb_gym  # noqa: F401 - registers the environments
from srpb_gym.planners import PLANNERS, make_planner

SCENARIOS = ("SRPB-Crowd-v0", "SRPB-Corridor-v0")


def time_episode(env: gym.Env, planner, seed: int) -> tuple[list[float], float]:
    """Durations [s] of every ``act`` call of one episode, and of ``reset``."""
    obs, _ = env.reset(seed=seed)
    knowledge = env.unwrapped.knowledge()
    t0 = time.perf_counter()
    planner.reset(knowledge)
    reset_time = time.perf_counter() - t0
    times = []
    while True:
        knowledge = env.unwrapped.knowledge()
        t0 = time.perf_counter()
        action = planner.act(obs, knowledge)
        times.append(time.perf_counter() - t0)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            return times, reset_time


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--planners", nargs="+", default=sorted(PLANNERS))
    args = ap.parse_args(argv)
    print(f"{'planner':<14}{'scenario':<20}{'steps':>7}{'median ms':>11}{'p95 ms':>9}"
          f"{'max ms':>9}{'reset ms':>10}")  # fmt: skip
    for name in args.planners:
        for env_id in SCENARIOS:
            env = gym.make(env_id)
            planner = make_planner(name)
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
