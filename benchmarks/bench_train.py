"""PPO training throughput by vector environment type and worker count.

Trains ``--steps`` environment steps of PPO (the hyperparameters of configs/train/ppo.yaml
for the id, periodic evaluation off) with each setting, side by side in one run, and
prints environment steps per second of the whole loop (collection and updates)::

    python benchmarks/bench_train.py --env SRPB-Crowd-v0 --steps 16384
"""

from __future__ import annotations

import argparse
import tempfile
import time

from srpb_gym.training.config import resolve
from srpb_gym.training.run import train

SETTINGS = (("dummy", 1), ("dummy", 2), ("subproc", 2), ("subproc", 4))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="SRPB-Crowd-v0")
    parser.add_argument("--steps", type=int, default=16384)
    parser.add_argument("--reward", default="srpb")
    args = parser.parse_args()
    print(f"{args.env}, {args.steps} steps each, n_steps 512 per environment")
    print(f"{'vec_env':>8} {'n_envs':>6} {'steps/s':>8} {'wall s':>7}")
    for vec_env, n_envs in SETTINGS:
        config = resolve(args.env, {"vec_env": vec_env, "n_envs": n_envs, "eval_freq": 0,
                                    "n_timesteps": args.steps})  # fmt: skip
        with tempfile.TemporaryDirectory() as out:
            started = time.perf_counter()
            result = train(args.env, config, preset=args.reward, out=f"{out}/run",
                           progress=False, log=lambda line: None)  # fmt: skip
            wall = time.perf_counter() - started
        print(f"{vec_env:>8} {n_envs:>6} {result.steps / wall:>8.0f} {wall:>7.1f}", flush=True)


if __name__ == "__main__":
    main()
