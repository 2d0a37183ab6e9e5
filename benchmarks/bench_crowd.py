"""Time one crowd update (``Crowd.desired_velocity``) for 2, 10 and 20 people.

Each crowd has walkers on looping routes in a 10 m x 10 m room with 10 wall segments, one
moving robot, and two standing F-formations among the people (for 2 people: one walker and
one single-member formation). Prints microseconds per call (best of --repeat runs of
--steps calls each, after a warm-up that loads or compiles the kernels) and the cost of
``Crowd.sync``, for the default crowd (robots pushed back from any distance) and, side by
side, for people who back away from a robot only within ``--backing-gap`` and never walk
into one (``SocialForceConfig.robot_backing_gap``: a check of every person against every
robot in each update).

    python benchmarks/bench_crowd.py [--steps 5000] [--repeat 5] [--backing-gap 0.3]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from srpb_gym.sim.crowd import Crowd, SocialForceConfig
from srpb_gym.sim.layout import FormationLayout, PersonLayout


def room_walls() -> np.ndarray:
    """A 10 m square room (4 walls) with three short inner walls split in two (10 segments)."""
    outer = [[0, 0, 10, 0], [10, 0, 10, 10], [10, 10, 0, 10], [0, 10, 0, 0]]
    inner = [[3, 2, 3, 3], [3, 3, 3, 4], [7, 6, 7, 7], [7, 7, 7, 8], [4, 8, 5, 8], [5, 8, 6, 8]]
    return np.array(outer + inner, dtype=np.float64)


def crowd_layout(n: int, seed: int = 0) -> tuple[list[PersonLayout], list[FormationLayout]]:
    """``n`` people: walkers plus two F-formations (three members each when n >= 10)."""
    rng = np.random.default_rng(seed)
    size = 3 if n >= 10 else 1
    n_forms = 2 if n >= 10 else 1
    formations = []
    for f in range(n_forms):
        cx, cy = (2.0 + 6.0 * f, 8.5 - 6.0 * f)
        angles = np.linspace(0.0, 2 * np.pi, size, endpoint=False)
        members = tuple((cx + 0.6 * np.cos(a), cy + 0.6 * np.sin(a)) for a in angles)
        formations.append(FormationLayout((cx, cy), members))
    people = []
    for k in range(n - n_forms * size):
        group = 0 if k < 3 and n >= 10 else -1  # a walking group of three
        if group < 0 or k == 0:
            start = rng.uniform(1.0, 9.0, 2)
            route = tuple(tuple(rng.uniform(1.0, 9.0, 2)) for _ in range(3))
        xy = (start[0], start[1] + 0.7 * k) if group >= 0 else tuple(start)
        people.append(PersonLayout(xy, 0.0, route, loop=True, group=group))
    return people, formations


def time_crowd(n: int, steps: int, repeat: int, gap: float = math.inf) -> tuple[float, float]:
    """Best microseconds per desired_velocity and per sync call for ``n`` people (``gap``:
    the robot backing gap, m)."""
    people, formations = crowd_layout(n)
    crowd = Crowd(SocialForceConfig(robot_backing_gap=gap))
    rng = np.random.default_rng(1)
    walls = room_walls()
    crowd.reset(people, formations, walls, rng)
    robot_xy, robot_vel, robot_r = np.array([[1.0, 5.0]]), np.array([[0.3, 0.0]]), np.array([0.3])
    dt = 0.1
    pos = crowd.position.copy()
    best_v = best_s = float("inf")
    for _ in range(repeat):
        t_v = t_s = 0.0
        for k in range(steps):
            t0 = time.perf_counter()
            v = crowd.desired_velocity(k * dt, dt, robot_xy, robot_vel, robot_r, walls, rng)
            t1 = time.perf_counter()
            pos += v * dt
            t2 = time.perf_counter()
            crowd.sync(pos, v)
            t3 = time.perf_counter()
            t_v += t1 - t0
            t_s += t3 - t2
        best_v, best_s = min(best_v, t_v / steps), min(best_s, t_s / steps)
    return best_v * 1e6, best_s * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--backing-gap", type=float, default=0.3, metavar="M",
                        help="the finite robot backing gap timed beside the default")  # fmt: skip
    args = parser.parse_args()
    if not (args.backing_gap >= 0 and math.isfinite(args.backing_gap)):
        parser.error(f"--backing-gap must be a finite distance >= 0, got {args.backing_gap}")
    t0 = time.perf_counter()
    for gap in (math.inf, args.backing_gap):
        time_crowd(2, 10, 1, gap)  # load (or compile) the kernels
    print(f"warm-up (load or compile): {time.perf_counter() - t0:.2f} s")
    for n in (2, 10, 20):
        us_v, us_s = time_crowd(n, args.steps, args.repeat)
        gap_v, _ = time_crowd(n, args.steps, args.repeat, args.backing_gap)
        print(f"{n:3d} people: desired_velocity {us_v:6.2f} us/call (backing gap "
              f"{args.backing_gap:g} m: {gap_v:6.2f}, {gap_v / us_v:.2f}x), sync {us_s:5.2f} "
              "us/call")  # fmt: skip


if __name__ == "__main__":
    main()
