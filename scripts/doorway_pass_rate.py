"""How many people pass the door of the doorway scenario within its time limit.

Usage: ``python scripts/doorway_pass_rate.py [--episodes 50] [--seed 0] [--planner dwa]
[--scenario doorway]``

A person uses the door when its start and the end of its route lie on different sides of
the dividing wall (``--wall X0 X1``, the wall's faces, default 5.95 6.05 m); it passes
when its centre gets beyond the far face. Each seed runs twice, every episode for the
scenario's whole time limit:

* ``robot``: the robot drives its task with the planner (``dwa``) and people react to it
  (collisions do not end the episode; once the robot is at its goal it stays there);
* ``no robot``: the robot is parked in the bottom-left corner, out of everyone's way, and
  invisible to people (``crowd={"robot_reaction": 0.0}``).

It prints, for each seed and run, the people using the door, how many passed and when the
last one passed, then the rate over all episodes (the target is >= 90 % with the robot).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import numpy as np

from srpb_gym.env import SRPBNavEnv
from srpb_gym.planners import make_planner

PARKED = {"start": (0.45, 0.45, 0.0), "goal": (0.45, 1.5, 0.0)}  # out of everyone's way


def door_users(layout, wall: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the walkers whose route crosses the wall, and the side (+1: right to left,
    -1: left to right) each goes."""
    users, sides = [], []
    for i, person in enumerate(layout.people):
        x0, x1 = person.position[0], person.route[-1][0]
        if x0 > wall[1] and x1 < wall[0]:
            users.append(i), sides.append(1.0)
        elif x0 < wall[0] and x1 > wall[1]:
            users.append(i), sides.append(-1.0)
    return np.array(users, dtype=np.int64), np.array(sides)


def run_episode(
    env: SRPBNavEnv, planner, seed: int, wall: tuple[float, float], drive: bool
) -> tuple[int, int, float, str]:
    """(people using the door, people that passed it, time of the last pass [s], the robot's
    outcome) of one episode simulated for the scenario's whole time limit."""
    obs, _ = env.reset(seed=seed, options=None if drive else PARKED)
    sim = env.sim
    users, sides = door_users(sim.layout, wall)
    passed = np.zeros(len(users), dtype=bool)
    last = 0.0
    if drive:
        planner.reset(env.knowledge())
    outcome, running = "parked", True
    stop = np.zeros((1, 3))
    while sim.t < sim.layout.time_limit - 1e-9:
        if running and drive:
            obs, _, terminated, truncated, _ = env.step(planner.act(obs, env.knowledge()))
            running = not (terminated or truncated)
            if not running:
                outcome = "goal" if terminated else "timeout"
        else:
            sim.step(stop)
        x = sim.crowd.position[users, 0]
        beyond = np.where(sides > 0, x < wall[0], x > wall[1])
        if np.any(beyond & ~passed):
            last = sim.t
        passed |= beyond
    if drive and running:
        outcome = "timeout"
    return len(users), int(passed.sum()), last, outcome


def main(argv: Sequence[str] | None = None) -> int:
    """Run both cases over ``--episodes`` seeds and print the pass rates."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=50, metavar="N")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="first seed")
    parser.add_argument("--planner", default="dwa", help="planner driving the robot")
    parser.add_argument("--scenario", default="doorway", help="scenario name or YAML file")
    parser.add_argument("--wall", type=float, nargs=2, default=(5.95, 6.05), metavar=("X0", "X1"),
                        help="x of the dividing wall's faces [m]")  # fmt: skip
    parser.add_argument("--quiet", action="store_true", help="print the totals only")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    wall = (min(args.wall), max(args.wall))
    cases = (("robot", True, None), ("no robot", False, {"robot_reaction": 0.0}))
    started = time.perf_counter()
    for name, drive, crowd in cases:
        env = SRPBNavEnv(args.scenario, collision="continue", crowd=crowd)
        planner = make_planner(args.planner) if drive else None
        label = f"{name} ({args.planner})" if drive else name
        users = passed = full = at_goal = 0
        latest = 0.0
        for seed in range(args.seed, args.seed + args.episodes):
            n, k, last, outcome = run_episode(env, planner, seed, wall, drive)
            users, passed, full = users + n, passed + k, full + (k == n)
            at_goal, latest = at_goal + (outcome == "goal"), max(latest, last)
            if not args.quiet:
                print(f"{label:>12} seed {seed:3d}: {k}/{n} passed, last at {last:5.1f} s, "
                      f"robot: {outcome}")  # fmt: skip
        env.close()
        rate = 100.0 * passed / users if users else float("nan")
        robot = f"; robot at its goal in {at_goal}/{args.episodes}" if drive else ""
        print(f"{label}: {passed}/{users} people passed the door within the time limit "
              f"({rate:.1f} %); all of them in {full}/{args.episodes} episodes; the last pass "
              f"at {latest:.1f} s at the latest{robot}")  # fmt: skip
    print(f"{time.perf_counter() - started:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
