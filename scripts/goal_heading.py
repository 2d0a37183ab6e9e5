"""Does a learned policy fail at a goal because of the goal's heading? One robot alone on a
scenario's ``robots`` entry, the goal as drawn and the same goal turned by given angles.

    python scripts/goal_heading.py --model ppo-crowd-srpb-3robots --env SRPB-Crowd-v0 \
        --route 2 --turn 0 -90 --episodes 40 --seed 3000000

Each episode is drawn from its seed as ``gym.make(env, route=...)`` draws it (start, goal
and people); the robot then drives from that start to that goal with its yaw turned by
each ``--turn`` [deg] (0: the goal as drawn), with the same people. The policy observes
with the settings it was trained with. Prints, per turn, the successes with a Wilson 95 %
interval and how the failures ended (collisions, and timeouts within 0.2 m of the goal's
position).
"""

from __future__ import annotations

import argparse
import math
import sys

import gymnasium as gym

import srpb_gym  # noqa: F401  (registers the ids)
from srpb_gym.evaluation.intervals import wilson
from srpb_gym.models import model_names
from srpb_gym.models.shipped import model_path
from srpb_gym.planners import knowledge_for
from srpb_gym.planners.learned import LearnedPolicy


def run(policy: LearnedPolicy, env: gym.Env, seed: int, turn: float) -> tuple[bool, str, float]:
    """One episode of ``seed`` with the goal's yaw turned by ``turn`` [rad]: whether it
    succeeded, how it ended and the robot's last distance to the goal's position [m]."""
    base = env.unwrapped
    env.reset(seed=seed)
    drawn = base.sim.layout.robots[0]
    goal = (drawn.goal[0], drawn.goal[1], drawn.goal[2] + turn)
    obs, _ = env.reset(seed=seed, options={"start": drawn.start, "goal": goal})
    policy.reset(knowledge_for(policy, base.knowledge))
    done = False
    while not done:
        base.set_planning_time(0.001)
        obs, _, terminated, truncated, info = env.step(
            policy.act(obs, knowledge_for(policy, base.knowledge)))  # fmt: skip
        done = terminated or truncated
    x, y = base.knowledge().pose[:2]
    ended = "success" if info["is_success"] else "collision" if info["collision"] else "timeout"
    return bool(info["is_success"]), ended, math.hypot(x - goal[0], y - goal[1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", required=True, help=f"a model file or one of: "
                        f"{', '.join(model_names())}")  # fmt: skip
    parser.add_argument("--env", default="SRPB-Crowd-v0")
    parser.add_argument("--route", type=int, required=True, help="the robots entry driven")
    parser.add_argument("--turn", type=float, nargs="+", default=[0.0, -90.0], metavar="DEG")
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--seed", type=int, default=3_000_000)
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    path = model_path(args.model) if args.model in model_names() else args.model
    policy = LearnedPolicy(path)
    kwargs = {"observation": policy.observation_config} if policy.observation_config else {}
    try:
        env = gym.make(args.env, route=args.route, **kwargs)
    except ValueError as exc:
        parser.error(str(exc))
    print(f"{args.model} alone on {args.env} route {args.route}, {args.episodes} episodes "
          f"from seed {args.seed}")  # fmt: skip
    for turn in args.turn:
        ends = [run(policy, env, args.seed + k, math.radians(turn)) for k in range(args.episodes)]
        wins = sum(ok for ok, _, _ in ends)
        low, high = wilson(wins, len(ends)) or (0.0, 0.0)
        collisions = sum(end == "collision" for _, end, _ in ends)
        near = sum(end == "timeout" and d <= 0.2 for _, end, d in ends)
        timeouts = sum(end == "timeout" for _, end, _ in ends)
        print(f"goal yaw turned {turn:+6.1f} deg: {wins}/{len(ends)} at the goal "
              f"[{low:.1f}-{high:.1f} %], {collisions} collisions, {timeouts} "
              f"timeouts ({near} within 0.2 m of the goal's position)")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
