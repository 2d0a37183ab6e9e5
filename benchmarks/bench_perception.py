"""Time the lidar scan and the people detector on a corridor-like scene.

A 30 m corridor with doors and clutter (10 wall segments), 20 people and the robot. Prints
microseconds per ``Lidar.scan`` (181 beams, and the 360-beam "wide" preset) and per
``PeopleDetector.detect`` (20 people, camera and lidar presets), next to a loop of pymunk
``Space.segment_query_first`` calls, one per beam, for the same scan in the same run; then
the simulation's per-robot sensing call (:func:`srpb_gym.perception.sensing.sense`).

    python benchmarks/bench_perception.py [--repeat 2000] [--seed 0]
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import numpy as np
import pymunk

from srpb_gym.perception import Lidar, PeopleDetector
from srpb_gym.perception.sensing import sense

N_PEOPLE = 20


def corridor(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, int]:
    """segs (10, 4), circles (people then the robot) and the robot's circle index."""
    segs = np.array([
        [-2.0, -2.0, 30.0, -2.0], [-2.0, 2.0, 30.0, 2.0], [-2.0, -2.0, -2.0, 2.0],
        [30.0, -2.0, 30.0, 2.0], [6.0, -2.0, 6.0, -0.8], [12.0, 2.0, 12.0, 0.9],
        [18.0, -2.0, 18.5, -1.0], [22.0, 1.0, 23.0, 1.0], [9.0, -1.5, 9.5, -1.5],
        [25.0, 0.5, 25.0, -0.5],
    ])  # fmt: skip
    people = rng.uniform([0.5, -1.7], [28.0, 1.7], (N_PEOPLE, 2))
    circles = np.vstack([np.column_stack([people, np.full(N_PEOPLE, 0.25)]), [[0.0, 0.0, 0.3]]])
    return segs, circles, N_PEOPLE


def pymunk_space(segs: np.ndarray, circles: np.ndarray, skip: int) -> pymunk.Space:
    space = pymunk.Space()
    for x0, y0, x1, y1 in segs:
        space.add(pymunk.Segment(space.static_body, (x0, y0), (x1, y1), 0.0))
    for j, (x, y, r) in enumerate(circles):
        if j != skip:
            space.add(pymunk.Circle(space.static_body, r, (x, y)))
    return space


def pymunk_scan(space: pymunk.Space, x: float, y: float, yaw: float, lidar: Lidar) -> np.ndarray:
    """The same scan as ``lidar.scan`` without noise, one pymunk query per beam."""
    range_max = lidar.config.range_max
    out = np.full(lidar.n_beams, range_max)
    query = pymunk.ShapeFilter()
    for b, a in enumerate(lidar.angles):
        end = (x + range_max * math.cos(yaw + a), y + range_max * math.sin(yaw + a))
        hit = space.segment_query_first((x, y), end, 0.0, query)
        if hit is not None:
            out[b] = hit.alpha * range_max
    return out


def time_us(fn: Callable[[int], object], repeat: int) -> float:
    """Best of 5 rounds of ``repeat`` calls, microseconds per call (after a warm-up)."""
    fn(0)
    best = math.inf
    for _ in range(5):
        start = time.perf_counter()
        for i in range(repeat):
            fn(i)
        best = min(best, time.perf_counter() - start)
    return best / repeat * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    segs, circles, skip = corridor(rng)
    poses = np.column_stack([rng.uniform(-1.0, 20.0, 64), rng.uniform(-1.0, 1.0, 64),
                             rng.uniform(-math.pi, math.pi, 64)])  # fmt: skip
    space = pymunk_space(segs, circles, skip)
    people_xy = np.ascontiguousarray(circles[:N_PEOPLE, :2])
    people_yaw = rng.uniform(-math.pi, math.pi, N_PEOPLE)
    people_circle = np.arange(N_PEOPLE)
    print(f"scene: {len(segs)} wall segments, {len(circles)} circles ({N_PEOPLE} people)")

    for preset in ("default", "wide"):
        lidar = Lidar(preset)
        out = np.empty(lidar.n_beams)

        def scan(i: int, lidar: Lidar = lidar, out: np.ndarray = out) -> np.ndarray:
            x, y, yaw = poses[i % 64]
            return lidar.scan(x, y, yaw, segs, circles, skip, rng, out)

        def reference(i: int, lidar: Lidar = lidar) -> np.ndarray:
            x, y, yaw = poses[i % 64]
            return pymunk_scan(space, x, y, yaw, lidar)

        ours = time_us(scan, args.repeat)
        theirs = time_us(reference, max(args.repeat // 20, 10))
        print(f"Lidar.scan [{preset}, {lidar.n_beams} beams]: {ours:8.2f} us/scan   "
              f"pymunk segment_query_first loop: {theirs:9.1f} us/scan   "
              f"speed-up x{theirs / ours:.0f}")  # fmt: skip

    for preset in ("camera", "lidar"):
        detector = PeopleDetector(preset)

        def detect(i: int, detector: PeopleDetector = detector) -> object:
            x, y, yaw = poses[i % 64]
            return detector.detect(x, y, yaw, people_xy, people_yaw, circles, skip,
                                   people_circle, segs, rng)  # fmt: skip

        print(
            f"PeopleDetector.detect [{preset}, {N_PEOPLE} people]: "
            f"{time_us(detect, args.repeat):8.2f} us/call"
        )

    # what the simulation calls per robot: the draws, then one compiled call
    lidar, detector, dist = Lidar("default"), PeopleDetector("camera"), np.zeros(len(poses))

    def sensing(i: int) -> int:
        lidar.draw(rng)
        detector.draw(rng, N_PEOPLE)
        return sense(poses, i % 64, segs, circles, skip, True, dist, *lidar.arrays,
                     people_xy, people_yaw, people_circle, *detector.arrays)  # fmt: skip

    print(f"sense [default lidar, camera, {N_PEOPLE} people, draws included]: "
          f"{time_us(sensing, args.repeat):8.2f} us/call (Lidar.scan + obstacle distance + "
          "PeopleDetector.detect, as the simulation runs them)")  # fmt: skip


if __name__ == "__main__":
    main()
