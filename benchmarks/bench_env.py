"""Steps per second of ``env.step`` for every registered id, single process.

Random actions (drawn ahead of time), episode resets included, every info key computed,
through ``gym.make`` with its default wrappers. Then SRPB-Crowd-v0 with the log-encoded
lidar alone and with the standing groups' O-spaces drawn into it (the observation of
``ppo-crowd-srpb``), alternating runs. With ``--profile`` also prints where the
time of SRPB-Crowd-v0 goes.

    python benchmarks/bench_env.py [--steps 20000] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import srpb_gym
from srpb_gym.registration import CUSTOM_ID, SCENARIO_IDS

ENVS = Path(srpb_gym.__file__).resolve().parents[1] / "envs"
LOG = {"lidar_encoding": "log"}
GROUPS = {"lidar_encoding": "log", "lidar_groups": 0.0001}


def make(env_id: str) -> gym.Env:
    kwargs = {"scenario": str(ENVS / "corridor.yaml")} if env_id == CUSTOM_ID else {}
    return gym.make(env_id, **kwargs)


def run(env: gym.Env, steps: int, seed: int = 0) -> tuple[float, int]:
    """(steps per second, episodes) over ``steps`` steps."""
    actions = np.random.default_rng(seed).uniform(-1, 1, (steps, *env.action_space.shape))
    actions = actions.astype(np.float32)
    env.reset(seed=seed)
    episodes = 0
    t0 = time.perf_counter()
    for k in range(steps):
        _, _, terminated, truncated, _ = env.step(actions[k])
        if terminated or truncated:
            env.reset()
            episodes += 1
    return steps / (time.perf_counter() - t0), episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--profile", action="store_true")
    args = parser.parse_args()
    for env_id in [*SCENARIO_IDS, CUSTOM_ID]:
        env = make(env_id)
        run(env, 300)  # load the kernels
        rate, episodes = max(run(env, args.steps, seed) for seed in range(3))
        print(f"{env_id:>20}: {rate:7.0f} steps/s  ({args.steps} steps, {episodes} episodes)")
    envs = {"log": gym.make("SRPB-Crowd-v0", observation=LOG),
            "groups": gym.make("SRPB-Crowd-v0", observation=GROUPS)}  # fmt: skip
    for env in envs.values():
        run(env, 300)
    rates: dict[str, list[float]] = {name: [] for name in envs}
    for seed in range(3):
        for name, env in envs.items():
            rates[name].append(run(env, args.steps, seed)[0])
    best = {name: max(r) for name, r in rates.items()}
    print(f"SRPB-Crowd-v0 observation={LOG}: {best['log']:.0f} steps/s; with "
          f"lidar_groups {GROUPS['lidar_groups']}: {best['groups']:.0f} steps/s, "
          f"{best['groups'] / best['log']:.2f} x")  # fmt: skip
    if args.profile:
        env = make("SRPB-Crowd-v0")
        profiler = cProfile.Profile()
        profiler.runcall(run, env, args.steps)
        pstats.Stats(profiler).sort_stats("tottime").print_stats(20)


if __name__ == "__main__":
    main()
