"""Steps per second of the PettingZoo multi-robot environment beside the Gymnasium one.

One step = every agent still in the episode stepped once. Random actions (drawn ahead of
time), resets included, all sensors, metrics and info on, single process, in one run so the
ratios compare like with like:

    python benchmarks/bench_multi.py [--scenario crowd] [--robots 1 3 8] [--steps 5000]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import srpb_gym
from srpb_gym.registration import SCENARIO_IDS


def run_gym(env: gym.Env, steps: int, seed: int) -> float:
    actions = np.random.default_rng(seed).uniform(-1, 1, (steps, 2)).astype(np.float32)
    env.reset(seed=seed)
    t0 = time.perf_counter()
    for k in range(steps):
        _, _, terminated, truncated, _ = env.step(actions[k])
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - t0)


def run_parallel(env, steps: int, seed: int) -> float:
    n = len(env.possible_agents)
    actions = np.random.default_rng(seed).uniform(-1, 1, (steps, n, 2)).astype(np.float32)
    env.reset(seed=seed)
    t0 = time.perf_counter()
    for k in range(steps):
        env.step({a: actions[k, i] for i, a in enumerate(env.agents)})
        if not env.agents:
            env.reset()
    return steps / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="crowd")
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 3, 8])
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    env_id = next(k for k, v in SCENARIO_IDS.items() if v == args.scenario)
    single = gym.make(env_id)
    multi = {n: srpb_gym.parallel_env(scenario=args.scenario, n_robots=n) for n in args.robots}
    run_gym(single, 300, 0)  # load the kernels
    for env in multi.values():
        run_parallel(env, 300, 0)
    best = {"gym": 0.0} | {n: 0.0 for n in args.robots}
    for r in range(args.rounds):  # interleaved rounds, best of each: noise hits all alike
        best["gym"] = max(best["gym"], run_gym(single, args.steps, r))
        for n, env in multi.items():
            best[n] = max(best[n], run_parallel(env, args.steps, r))
    print(f"{args.scenario}: best of {args.rounds} rounds x {args.steps} steps, one process")
    print(f"{'Gymnasium env (1 robot)':>28}: {best['gym']:7.0f} steps/s")
    for n in args.robots:
        ratio = best[n] / best["gym"]
        print(
            f"{f'parallel env, {n} robot(s)':>28}: {best[n]:7.0f} steps/s "
            f"({100 * ratio:.0f} % of the Gymnasium env; {n * best[n]:.0f} robot-steps/s)"
        )


if __name__ == "__main__":
    main()
