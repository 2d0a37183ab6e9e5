"""Episodes per second of an evaluation sweep on the process pool and on Ray, with 1 and 2
local workers, in one run, and Ray's overhead per episode.

Each configuration runs the same episodes (``--episodes`` seeds of every ``--planner`` on
``--env``) through ``srpb_gym.evaluation.run_evaluation`` into a fresh folder, timed from
the call to its return: worker start, warm-up, episodes, tables and figures, as
``srpb-gym eval`` spends them, after an untimed one-episode run that pays this process's
one-time costs (imports, loading the compiled kernels, plotting). Ray is started once
(``ray.init(num_cpus=W)``, timed apart) and its worker processes start inside the timed
run, as the pool's do:

    python benchmarks/bench_ray.py [--env SRPB-Corridor-v0] [--planner dwa] \\
        [--episodes 16] [--workers 1 2]

The overhead per episode is (Ray's wall time - the pool's) / episodes, for each number
of workers. docs/scaling.md holds the figures and the model built on them.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import ray

from srpb_gym.evaluation import resolve_config, run_evaluation


def timed_run(env: str, planners: list[str], episodes: int, workers: int, backend: str,
              folder: str) -> float:  # fmt: skip
    config = resolve_config([env], planners, episodes=episodes, workers=workers, out=folder,
                            backend=backend, log=None)  # fmt: skip
    started = time.perf_counter()
    outcome = run_evaluation(config, log=lambda line: None, progress=False)
    wall = time.perf_counter() - started
    assert not outcome.interrupted and outcome.finished == episodes * len(planners)
    return wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="SRPB-Corridor-v0")
    ap.add_argument("--planner", nargs="+", default=["dwa"])
    ap.add_argument("--episodes", type=int, default=16, help="per planner")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = ap.parse_args()
    n = args.episodes * len(args.planner)
    print(f"{args.env}, {', '.join(args.planner)}: {n} episodes per run; "
          f"{os.cpu_count()} CPU cores; load average {os.getloadavg()[0]:.2f}")  # fmt: skip
    print(f"{'workers':>7}  {'pool s':>8}  {'pool ep/s':>9}  {'ray s':>8}  {'ray ep/s':>9}  "
          f"{'overhead/episode':>16}")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        # untimed: this process's one-time costs (imports, compiled kernels, plotting)
        timed_run(args.env, args.planner, 1, 1, "process", os.path.join(tmp, "warm"))
        for w in args.workers:
            pool = timed_run(args.env, args.planner, args.episodes, w, "process",
                             os.path.join(tmp, f"pool{w}"))  # fmt: skip
            started = time.perf_counter()
            ray.init(num_cpus=w, include_dashboard=False, log_to_driver=False,
                     configure_logging=False)  # fmt: skip
            start = time.perf_counter() - started
            try:
                on_ray = timed_run(args.env, args.planner, args.episodes, w, "ray",
                                   os.path.join(tmp, f"ray{w}"))  # fmt: skip
            finally:
                ray.shutdown()
            print(f"{w:>7}  {pool:>8.1f}  {n / pool:>9.3f}  {on_ray:>8.1f}  {n / on_ray:>9.3f}  "
                  f"{1000 * (on_ray - pool) / n:>13.0f} ms   (ray.init: {start:.1f} s)",
                  flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
