"""How long planners take over the last metres to their goals, and where their failures end,
read from the episode records of an ``srpb-gym eval`` output folder.

    srpb-gym eval --env SRPB-Crowd-v0 --robots 3 --policy ppo-crowd-srpb-3robots \\
        --episodes 100 --seed 3000000 --env-kwargs 'observation={lidar_encoding: log, \\
        lidar_groups: 0.0001}' --out runs/val-3robots
    python scripts/last_metres.py runs/val-3robots --radius 0.5

For every (environment, planner, robot) of the folder's ``episodes.csv`` it reads each
episode's ground-truth record (``episodes/<env>/<planner>/*_gt.npz``) and prints: the
episodes and successes; over the successes, the median and 90th percentile of the time
from the first sample within ``--radius`` of the goal's position to the end (a robot that
reaches the goal's position and then turns onto its heading spends that turn here); the
failures that end within ``--radius`` of the goal's position, and among them those within
its position tolerance (``--tolerance``) with the median of their heading errors. The goal
is the one of the record's last sample.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import sys
from collections import defaultdict
from collections.abc import Sequence

import numpy as np

from srpb_gym.angles import wrap_angle
from srpb_gym.errors import InputError
from srpb_gym.evaluation.stats import read_episodes
from srpb_gym.metrics.io_npz import load_record
from srpb_gym.metrics.record import R


@functools.lru_cache(maxsize=64)
def _listing(where: str) -> tuple[str, ...]:
    """The ground-truth record files of one records folder (read once)."""
    return tuple(n for n in os.listdir(where) if n.endswith("_gt.npz"))


def record_path(folder: str, env: str, planner: str, seed: int, robot: str) -> str:
    """The ground-truth record of one episode row (``robot`` empty: a single-robot run).
    Records are named ``<scenario>_seed<seed>[_robot<r>]_gt.npz``; the scenario is found
    among the files, as ``SRPB-Mix-v0`` names each episode after the scenario it drew."""
    where = os.path.join(folder, "episodes", env, planner)
    tail = f"_seed{seed}" + (f"_robot{robot}" if robot != "" else "") + "_gt.npz"
    try:
        names = [n for n in _listing(where) if n.endswith(tail)]
    except OSError:
        raise InputError(f"no episode records for {env} / {planner} (the eval output's "
                         "records are needed)", where) from None  # fmt: skip
    if len(names) != 1:
        raise InputError(f"expected one record ending in {tail}, found {len(names)}", where)
    return os.path.join(where, names[0])


def last_metres(path: str, radius: float) -> tuple[float, float, float]:
    """(time [s] from the first sample within ``radius`` of the goal's position to the end,
    or NaN when none is; the last sample's distance to the goal's position [m]; its heading
    error [rad]) of the ground-truth record at ``path``."""
    robot = load_record(path).robot
    gx, gy, gyaw = robot[-1, R["goal_x"]], robot[-1, R["goal_y"]], robot[-1, R["goal_yaw"]]
    dist = np.hypot(robot[:, R["x"]] - gx, robot[:, R["y"]] - gy)
    near = np.flatnonzero(dist < radius)
    t = robot[:, R["t"]]
    spent = float(t[-1] - t[near[0]]) if near.size else math.nan
    return spent, float(dist[-1]), abs(float(wrap_angle(gyaw - robot[-1, R["yaw"]])))


def summarise(folder: str, radius: float, tolerance: float) -> list[str]:
    """One line per (environment, planner, robot) of the eval output ``folder``."""
    groups: dict[tuple[str, str, str], list[tuple[bool, float, float, float]]]
    groups = defaultdict(list)
    for row in read_episodes(os.path.join(folder, "episodes.csv")):
        key = (row.env, row.planner, "" if row.robot is None else str(row.robot))
        path = record_path(folder, row.env, row.planner, row.seed, key[2])
        groups[key].append((row.is_success, *last_metres(path, radius)))
    out = []
    for (env, planner, robot), episodes in groups.items():
        spent = np.array([s for ok, s, _, _ in episodes if ok])
        failed = [(d, h) for ok, _, d, h in episodes if not ok]
        near = [(d, h) for d, h in failed if d < radius]
        at = [h for d, h in near if d <= tolerance]
        who = f"{env} {planner}" + (f" robot {robot}" if robot != "" else "")
        timing = "no successes"
        if spent.size:
            timing = (f"last {radius:g} m: median {np.nanmedian(spent):.1f} s, 90th "
                      f"percentile {np.nanpercentile(spent, 90):.1f} s")  # fmt: skip
        heading = f" (median heading error {np.median(at):.2f} rad)" if at else ""
        out.append(f"{who}: {spent.size}/{len(episodes)} at the goal; {timing}; "
                   f"{len(near)} of {len(failed)} failures end within {radius:g} m of the "
                   f"goal, {len(at)} within {tolerance:g} m{heading}")  # fmt: skip
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", help="an srpb-gym eval output folder")
    parser.add_argument("--radius", type=float, default=0.5, help="m (default 0.5)")
    parser.add_argument("--tolerance", type=float, default=0.2,
                        help="m, the goal's position tolerance (default 0.2)")  # fmt: skip
    args = parser.parse_args(argv)
    for name in ("radius", "tolerance"):
        if not (math.isfinite(getattr(args, name)) and getattr(args, name) > 0):
            parser.error(f"--{name} must be > 0, got {getattr(args, name)}")
    try:
        lines = summarise(args.folder, args.radius, args.tolerance)
    except InputError as exc:
        print(f"last_metres.py: error: {exc}", file=sys.stderr)
        return 2
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
