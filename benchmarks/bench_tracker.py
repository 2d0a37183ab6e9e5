"""Time `KalmanTracker.step` with 2, 10 and 20 people walking in a room.

People walk towards random goals in a 10 m x 10 m room at 0.8-1.5 m/s, turning at most
1 rad/s. Each step every person is missed with probability 0.1, otherwise detected with
isotropic Gaussian position noise (std 0.05-0.15 m) and yaw noise (0.2 rad). The detections
are generated first; the timed loop only calls `step` (dt = 0.1 s). Prints the microseconds
per step (best of --repeat runs, after a warm-up that loads or compiles the kernels), the
mean number of tracks and the number of ids used.

    python benchmarks/bench_tracker.py [--steps 5000] [--repeat 5] [--people 2 10 20]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from srpb_gym.perception.tracker import KalmanTracker

DT = 0.1
ROOM = 10.0


def scene(people: int, steps: int, seed: int = 0) -> list[tuple[np.ndarray, ...]]:
    """Per step the detection arrays (xy, yaw, std) of ``people`` walking people."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(0, ROOM, (people, 2))
    goal = rng.uniform(0, ROOM, (people, 2))
    heading = rng.uniform(-np.pi, np.pi, people)
    speed = rng.uniform(0.8, 1.5, people)
    out = []
    for _ in range(steps):
        to_goal = goal - p
        arrived = np.hypot(to_goal[:, 0], to_goal[:, 1]) < 0.3
        goal[arrived] = rng.uniform(0, ROOM, (int(arrived.sum()), 2))
        turn = np.angle(np.exp(1j * (np.arctan2(to_goal[:, 1], to_goal[:, 0]) - heading)))
        heading += np.clip(turn, -1.0 * DT, 1.0 * DT)
        p += DT * speed[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=1)
        seen = rng.random(people) >= 0.1
        d = int(seen.sum())
        std = rng.uniform(0.05, 0.15, d)
        xy = p[seen] + rng.normal(0.0, 1.0, (d, 2)) * std[:, None]
        yaw = np.angle(np.exp(1j * (heading[seen] + rng.normal(0.0, 0.2, d))))
        out.append((xy, yaw, std))
    return out


def run(tracker: KalmanTracker, dets: list[tuple[np.ndarray, ...]]) -> tuple[float, float]:
    """Seconds for all steps, and the mean number of reported tracks."""
    tracker.reset()
    step = tracker.step
    total = 0
    t0 = time.perf_counter()
    for xy, yaw, std in dets:
        total += step(DT, xy, yaw, std)
    return time.perf_counter() - t0, total / len(dets)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--people", type=int, nargs="+", default=[2, 10, 20])
    args = ap.parse_args()
    tracker = KalmanTracker()
    run(tracker, scene(3, 50))  # warm-up: load or compile the kernels
    print(f"{'people':>6} {'us/step':>8} {'tracks':>7} {'ids':>5}")
    for people in args.people:
        dets = scene(people, args.steps, seed=people)
        best, mean_tracks = min(run(tracker, dets) for _ in range(args.repeat))
        us = best / args.steps * 1e6
        print(f"{people:6d} {us:8.2f} {mean_tracks:7.2f} {tracker.next_id:5d}")


if __name__ == "__main__":
    main()
