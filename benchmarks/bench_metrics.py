"""Time the full SRPB metric set on a long synthetic episode.

100,000 robot samples at 10 Hz with 10 people and one 3-member F-formation at every sample
(1,000,000 person-samples, 100,000 group-samples). Prints the time of one `evaluate` call
(best of --repeat, after a warm-up that loads or compiles the kernels) and the throughput.

    python benchmarks/bench_metrics.py [--samples 100000] [--people 10] [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from srpb_gym.metrics import EpisodeRecord, evaluate


def synthetic_episode(samples: int, people: int, seed: int = 0) -> EpisodeRecord:
    """A robot crossing a room with walking people and a standing group of three."""
    rng = np.random.default_rng(seed)
    t = np.arange(samples) * 0.1
    robot = np.zeros((samples, 12))
    robot[:, 0] = t
    robot[:, 1] = np.cumsum(rng.uniform(0.0, 0.05, samples))
    robot[:, 2] = np.sin(t / 10.0)
    robot[:, 3] = rng.uniform(-np.pi, np.pi, samples)
    robot[:, 4:7] = rng.normal(0.2, 0.2, (samples, 3))
    robot[:, 7:10] = (robot[-1, 1], 0.0, 0.0)
    robot[:, 10] = rng.uniform(0.2, 3.0, samples)
    robot[:, 11] = rng.uniform(0.005, 0.02, samples)
    per = people + 3
    rows = np.zeros((samples, per, 9))
    rows[:, :, 0] = robot[:, 1:2] + rng.uniform(-4, 4, (samples, per))
    rows[:, :, 1] = rng.uniform(-4, 4, (samples, per))
    rows[:, :, 2] = rng.uniform(-np.pi, np.pi, (samples, per))
    rows[:, :, 3] = rows[:, :, 6] = rng.uniform(0.01, 0.1, (samples, per))
    rows[:, :, 7:9] = rng.normal(0, 0.7, (samples, per, 2))
    g = np.array([[0.0, 0.6], [0.55, -0.3], [-0.55, -0.3]])
    rows[:, people:, 0:2] = robot[:, None, 1:3] + 2.0 + g[None, :, :]
    rows[:, people:, 7:9] = 0.0
    sample = np.repeat(np.arange(samples), per)
    members = (np.arange(samples)[:, None] * per + people + np.arange(3)).ravel()
    return EpisodeRecord.from_arrays(
        robot, rows.reshape(-1, 9), sample, np.tile(np.arange(per), samples),
        np.arange(samples), np.zeros(samples, dtype=np.int64), np.full(samples, 3), members,
    )  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--people", type=int, default=10)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    t0 = time.perf_counter()
    evaluate(synthetic_episode(20, 2), "paper")  # load (or compile) the kernels
    evaluate(synthetic_episode(20, 2), "reference")
    warm = time.perf_counter() - t0
    record = synthetic_episode(args.samples, args.people)
    person_samples = record.people.shape[0]
    print(
        f"episode: {args.samples} samples, {person_samples} person-samples "
        f"({args.people} walking + 3 in a group), {record.group_sample.shape[0]} group-samples"
    )
    print(f"kernel warm-up (load or compile): {warm:.2f} s")
    for semantics in ("paper", "reference"):
        best = min(_timed(record, semantics) for _ in range(args.repeat))
        print(
            f"{semantics:>9}: {best:.3f} s per evaluate  "
            f"({person_samples / best / 1e6:.2f} M person-samples/s, "
            f"{args.samples / best / 1e3:.0f} k robot samples/s)"
        )


def _timed(record: EpisodeRecord, semantics: str) -> float:
    t0 = time.perf_counter()
    evaluate(record, semantics)
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
