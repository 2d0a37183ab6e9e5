"""Do people walk into a robot they can see? A robot parked where it starts (zero action
for the whole episode) in every packaged scenario: in how many episodes does anyone touch
it, with the Wilson 95 % interval of that rate, how close do people come (the
smallest gap between a person's body and the robot's, median over episodes) and how far
is anyone pushed back (``info["people_pushed_back"]``: the episodes with a walker moved
more than 1 m against the way it walks, and the largest distance).

With ``--robot-reaction 0`` people do not see robots (the invisible robot of CrowdNav) and
walk into a parked one, which shows what the count measures. ``--backing-gap`` sets the
crowd's ``robot_backing_gap`` (default: the crowd's default).

    python benchmarks/people.py [--episodes 100] [--seed 3000000] [--workers 2]
        [--robot-reaction 1.0] [--backing-gap 0.3]
"""

from __future__ import annotations

import argparse
import itertools
from concurrent.futures import ProcessPoolExecutor

import gymnasium as gym
import numpy as np

import srpb_gym  # noqa: F401  (registers the ids)
from srpb_gym.evaluation.intervals import wilson
from srpb_gym.registration import SCENARIO_IDS
from srpb_gym.seeds import VALIDATION


def parked(env_id: str, seeds: range, crowd: dict[str, float]
           ) -> tuple[int, list[float], list[float]]:  # fmt: skip
    """(episodes in which a person touched the parked robot, smallest gap per episode,
    largest distance anyone was pushed back per episode)."""
    env = gym.make(env_id, crowd=crowd)
    action = np.zeros(env.action_space.shape, np.float32)
    touched, gaps, back = 0, [], []
    for seed in seeds:
        env.reset(seed=seed)
        sim = env.unwrapped.sim
        reach = sim.robot_config.radius + sim.robot_config.bumper + sim.crowd.radius
        gap, hit, done = np.inf, False, False
        while not done:
            _, _, terminated, truncated, info = env.step(action)
            offset = sim.crowd.position - sim.world.robot_pose[0, :2]
            if len(offset):
                gap = min(gap, float((np.hypot(*offset.T) - reach).min()))
            hit |= bool(info["collision"])
            done = terminated or truncated
        touched += hit
        gaps.append(gap)
        back.append(info["people_pushed_back"])
    env.close()
    return touched, gaps, back


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=VALIDATION.start)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--robot-reaction", type=float, default=1.0)
    parser.add_argument("--backing-gap", type=float, default=None)
    args = parser.parse_args()
    crowd = {"robot_reaction": args.robot_reaction}
    if args.backing_gap is not None:
        crowd["robot_backing_gap"] = args.backing_gap
    chunks = max(args.workers, 1) * 2
    bounds = np.linspace(0, args.episodes, chunks + 1).astype(int)
    print(f"robot parked where it starts, {args.episodes} episodes per scenario from seed "
          f"{args.seed}, crowd {crowd}")  # fmt: skip
    print(f"{'scenario':22} {'touched':>8} {'rate [Wilson 95 %]':>22} {'median gap [m]':>15} "
          f"{'pushed back > 1 m':>18} {'most [m]':>9}")  # fmt: skip
    with ProcessPoolExecutor(args.workers) as pool:
        for env_id in SCENARIO_IDS:
            jobs = [pool.submit(parked, env_id, range(args.seed + a, args.seed + b), crowd)
                    for a, b in itertools.pairwise(bounds) if b > a]  # fmt: skip
            touched, gaps, back = 0, [], []
            for job in jobs:
                t, g, b = job.result()
                touched, gaps, back = touched + t, gaps + g, back + b
            low, high = wilson(touched, args.episodes)
            rate = f"{100 * touched / args.episodes:.0f} % [{low:.1f}-{high:.1f}]"
            pushed = sum(b > 1.0 for b in back)
            print(f"{env_id:22} {touched:>4}/{args.episodes:<3} {rate:>22} "
                  f"{np.median(gaps):>15.2f} {pushed:>14}/{args.episodes:<3} "
                  f"{max(back):>9.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
