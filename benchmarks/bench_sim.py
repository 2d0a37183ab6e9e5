"""Control steps per second of the simulation core, and start-up time of a fresh process.

A step is the whole pipeline: command limits, social force, 4 physics substeps, lidar (181
beams), people detector, tracker, and one sample appended to the tracked and ground-truth
SRPB records. Commands are random (held for 1 s); episodes reset at the time limit.

    python benchmarks/bench_sim.py [--steps 20000] [--profile]

``crowd-20`` is the crowd scenario with a layout of exactly 20 people. After the rates it
prints where one step's time goes (microseconds per step, each part timed around its call
in the pipeline, best of 3 runs): physics (``World.step``: pymunk substeps and the batch
reads and writes), crowd (``Crowd.desired_velocity`` and ``Crowd.sync``), sensing (lidar,
obstacle distance, detection), tracker and records, and the rest of ``Simulation.step``
(command limits, frame changes, measured velocity, bookkeeping).
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable

import numpy as np

from srpb_gym.scenarios import load_scenario, sample
from srpb_gym.sim.crowd import Crowd
from srpb_gym.sim.world import World
from srpb_gym.simulation import Simulation

# parts of a step: (label, [(class, method), ...]); "total" is the whole step
PARTS = (
    ("physics", [(World, "step")]),
    ("crowd", [(Crowd, "desired_velocity"), (Crowd, "sync")]),
    ("sensing", [(Simulation, "_sense")]),
    ("tracker", [(Simulation, "_track")]),
    ("records", [(Simulation, "_record")]),
    ("total", [(Simulation, "step")]),
)

STARTUP = (
    "import time; t0 = time.perf_counter(); import numpy as np; "
    "from srpb_gym.scenarios import load_scenario, sample; "
    "from srpb_gym.simulation import Simulation; from srpb_gym.metrics import evaluate; "
    "sim = Simulation(); sim.reset(sample(load_scenario('crowd'), np.random.default_rng(0)), "
    "np.random.default_rng(0)); [sim.step([[0.3, 0.0, 0.1]], 0.0) for _ in range(5)]; "
    "evaluate(sim.robots[0].record); print(time.perf_counter() - t0)"
)


def layouts(name: str, people: int | None, count: int = 64) -> list:
    """Sampled layouts of a scenario (only those with exactly ``people`` people if given)."""
    scenario = load_scenario(name)
    out, seed = [], 0
    while len(out) < count:
        lay = sample(scenario, np.random.default_rng(seed))
        seed += 1
        n = len(lay.people) + sum(len(f.members) for f in lay.formations)
        if people is None or n == people:
            out.append(lay)
    return out


def run(lays: list, steps: int) -> float:
    """Steps per second over ``steps`` control steps with random commands."""
    sim = Simulation()
    rng = np.random.default_rng(0)
    limit = int(lays[0].time_limit / sim.config.control_dt)
    cmd = np.zeros((1, 3))
    t0 = time.perf_counter()
    for k in range(steps):
        if k % limit == 0:
            sim.reset(lays[(k // limit) % len(lays)], np.random.default_rng(k))
        if k % 10 == 0:
            cmd[0] = rng.uniform([-0.1, 0.0, -1.05], [0.5, 0.0, 1.05])
        sim.step(cmd, 0.0)
    return steps / (time.perf_counter() - t0)


def _timed(fn: Callable, acc: list[int]) -> Callable:
    clock = time.perf_counter_ns

    def wrapper(*args, **kwargs):
        t0 = clock()
        out = fn(*args, **kwargs)
        acc[0] += clock() - t0
        return out

    return wrapper


def breakdown(lays: list, steps: int) -> dict[str, float]:
    """Microseconds per control step spent in each of :data:`PARTS` (best of 3 runs), plus
    "other": the total less the parts. The parts are timed by wrapping their methods."""
    acc = {label: [0] for label, _ in PARTS}
    saved = []
    for label, methods in PARTS:
        for cls, name in methods:
            saved.append((cls, name, cls.__dict__[name]))
            setattr(cls, name, _timed(cls.__dict__[name], acc[label]))
    best: dict[str, float] = {}
    try:
        run(lays, steps // 10)
        for _ in range(3):
            for a in acc.values():
                a[0] = 0
            run(lays, steps)
            if not best or acc["total"][0] < best["total"] * 1e3 * steps:
                best = {label: a[0] / 1e3 / steps for label, a in acc.items()}
    finally:
        for cls, name, fn in saved:
            setattr(cls, name, fn)
    best["other"] = best["total"] - sum(v for k, v in best.items() if k != "total")
    return best


def startup() -> tuple[float, float]:
    """Seconds to import, build and step a crowd episode in a fresh process: with an empty
    numba cache (kernels compiled) and with the cache that run left (kernels loaded)."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        times = []
        for _ in range(2):
            out = subprocess.run([sys.executable, "-c", STARTUP], env=env, check=True,
                                 capture_output=True, text=True)  # fmt: skip
            times.append(float(out.stdout.strip()))
    return times[0], times[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--profile", action="store_true", help="print a profile of crowd-20")
    parser.add_argument("--no-startup", action="store_true", help="skip the start-up timing")
    args = parser.parse_args()
    cases = {"corridor": layouts("corridor", None), "crowd-20": layouts("crowd", 20)}
    run(cases["crowd-20"], 200)  # load every kernel before timing
    for name, lays in cases.items():
        best = max(run(lays, args.steps) for _ in range(3))
        print(f"{name:>10}: {best:7.0f} control steps/s (best of 3 x {args.steps})")
    for name, lays in cases.items():
        parts = breakdown(lays, max(args.steps // 4, 100))
        text = ", ".join(f"{k} {v:.1f}" for k, v in parts.items() if k != "total")
        print(f"{name:>10}: {parts['total']:.1f} us per step (timed parts): {text}")
    if not args.no_startup:
        cold, warm = startup()
        print(f"start-up of a fresh process (import, build, 5 steps, evaluate): "
              f"{cold:.1f} s with an empty numba cache, {warm:.2f} s with the cache")  # fmt: skip
    if args.profile:
        profiler = cProfile.Profile()
        profiler.runcall(run, cases["crowd-20"], args.steps)
        pstats.Stats(profiler).sort_stats("tottime").print_stats(18)


if __name__ == "__main__":
    main()
