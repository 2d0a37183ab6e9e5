"""Training throughput of the two shared-policy multi-robot recipes side by side, in one
run: stable-baselines3 PPO on ``SharedPolicyVecEnv`` (``training/multi_robot.py``) and
RLlib PPO on ``ParallelPettingZooEnv`` (``training/rllib_multi_robot.py``), on the same
scenario and robots, with the same PPO update: the SB3 recipe's rollout of 2048
robot-steps (1024 per robot slot with one environment of 2 robots), minibatches of 64 and
10 epochs; RLlib's batch counts environment steps, ``--batch`` 1024 of 2 robots.

    python benchmarks/bench_multi_robot_train.py [--scenario corridor] [--robots 2] \\
        [--steps 4096] [--env-runners 1]

Environment steps (every robot in the episode moved once) and robot-steps per second of
wall time, sampling and learning together; for RLlib over its iterations, without
``ray.init`` and building the algorithm (printed apart). The two count a little
differently: SB3 ends every robot's episode at the first robot's end, RLlib lets the others
go on, so a step moves fewer robots on average there.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # training/ is not installed

import ray

from training import multi_robot, rllib_multi_robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="corridor")
    ap.add_argument("--robots", type=int, default=2)
    ap.add_argument("--steps", type=int, default=4096, help="robot-steps per recipe")
    ap.add_argument("--batch", type=int, default=1024,
                    help="RLlib: environment steps per update")  # fmt: skip
    ap.add_argument("--env-runners", type=int, default=1)
    args = ap.parse_args()
    print(f"{args.scenario}, {args.robots} robots, {args.steps} robot-steps, RLlib batch "
          f"{args.batch} env steps; {os.cpu_count()} CPU cores; load average "
          f"{os.getloadavg()[0]:.2f}")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        started = time.perf_counter()
        folder = multi_robot.train(args.scenario, args.robots, 1, args.steps,
                                   os.path.join(tmp, "sb3"))  # fmt: skip
        total = time.perf_counter() - started
        run = json.loads((folder / "run.json").read_text())
        robot_steps, wall = run["steps"], run["wall_time_s"]
        print(f"SB3   shared policy: {robot_steps / args.robots / wall:7.0f} env steps/s "
              f"(counted as robot-steps / robots), {robot_steps / wall:7.0f} robot-steps/s "
              f"over {wall:.1f} s ({total:.1f} s with set-up)")  # fmt: skip
        started = time.perf_counter()
        ray.init(num_cpus=os.cpu_count(), include_dashboard=False, log_to_driver=False,
                 configure_logging=False)  # fmt: skip
        try:
            iterations = max(1, round(args.steps / (args.batch * args.robots)))
            record = rllib_multi_robot.train(
                args.scenario, args.robots, args.env_runners, 1, iterations,
                os.path.join(tmp, "rllib"), batch=args.batch, minibatch=64, epochs=10,
                log=lambda line: None,
            )  # fmt: skip
        finally:
            ray.shutdown()
        total = time.perf_counter() - started
        print(f"RLlib shared policy: {record['env_steps_per_s']:7.0f} env steps/s, "
              f"{record['agent_steps_per_s']:7.0f} robot-steps/s over "
              f"{record['wall_time_s']:.1f} s ({total:.1f} s with ray.init and set-up; "
              f"{iterations} iterations, {args.env_runners} env runner(s))")  # fmt: skip


if __name__ == "__main__":
    main()
