"""Calibration of the walking people against published pedestrian data (docs/crowd.md).

Runs every measurement of :mod:`srpb_gym.sim.calibration` at full size (``--small``: the
reduced size of the tests) and prints one table, ``quantity | model | published |
tolerance | source | ok``, then the speed-density points and the run time of each
measurement. The crowd parameters are the defaults unless changed:

    python benchmarks/calibration.py [--small] [--seed 0] [--only fundamental_diagram]
        [--set person_strength=3.0 --set anticipation_time=1.0]
        [--speed 0.89 1.79] [--radius 0.2 0.26] [--relaxation 0.4 0.6]

``--set NAME=VALUE`` replaces a field of ``SocialForceConfig``; ``--speed``, ``--radius``
and ``--relaxation`` the uniform ranges the walkers' preferred speed [m/s], body radius
[m] and relaxation time [s] are drawn from (default: the scenario defaults of
``WalkerParams``). Exits with 1 when a figure fails.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

from srpb_gym.scenarios.schema import WalkerParams
from srpb_gym.sim import calibration as cal
from srpb_gym.sim.crowd import SocialForceConfig


def parse_set(items: list[str]) -> dict[str, float]:
    """``NAME=VALUE`` pairs as a dict of floats."""
    out = {}
    for item in items:
        name, _, value = item.partition("=")
        out[name.strip()] = float(value)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--small", action="store_true", help="the reduced size of the tests")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", action="append", default=[], choices=sorted(cal.MEASUREMENTS))
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    defaults = WalkerParams()
    for name, default in (("speed", defaults.preferred_speed), ("radius", defaults.radius),
                          ("relaxation", defaults.relaxation_time)):  # fmt: skip
        parser.add_argument(f"--{name}", type=float, nargs=2, default=default, metavar=("LO", "HI"))
    args = parser.parse_args()
    config = SocialForceConfig(**parse_set(args.set))
    walkers = cal.Walkers(tuple(args.speed), tuple(args.radius), tuple(args.relaxation))
    changed = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)
               if getattr(config, f.name) != f.default}  # fmt: skip
    print(f"SocialForceConfig changes: {changed or 'none'}; {walkers}")
    results, times = {}, {}
    for name in cal.MEASUREMENTS:
        if args.only and name not in args.only:
            continue
        t0 = time.perf_counter()
        results.update(cal.calibrate(config, walkers, args.small, args.seed, only=(name,)))
        times[name] = time.perf_counter() - t0
    checks = [c for r in results.values() for c in r.checks]
    header = ("quantity", "model", "published", "tolerance", "source", "ok")
    rows = [(c.quantity, f"{c.model:.3f} {c.unit}".strip(), f"{c.published:g} {c.unit}".strip(),
             c.tolerance, c.source, "yes" if c.ok else "NO") for c in checks]  # fmt: skip
    widths = [max(len(r[k]) for r in [header, *rows]) for k in range(len(header))]
    for k, row in enumerate([header, *rows]):
        print(" | ".join(v.ljust(w) for v, w in zip(row, widths)).rstrip())
        if k == 0:
            print("-|-".join("-" * w for w in widths))
    if "free_walking" in results:
        r = results["free_walking"]
        lo, hi = r.matching_range
        print(f"\nfree walking: preferred speeds drawn {r.preferred_mean:.3f} +- "
              f"{r.preferred_sd:.3f} m/s; uniform [{lo:.2f}, {hi:.2f}] m/s has Weidmann's "
              "mean and sd")  # fmt: skip
    if "fundamental_diagram" in results:
        r = results["fundamental_diagram"]
        print("\ndensity [1/m^2] | model [m/s] | Weidmann [m/s] | model / Weidmann | backward")
        for d, v, w, b in zip(r.density, r.speed, r.published, r.backward):
            print(f"{d:15.2f} | {v:11.3f} | {w:14.3f} | {v / w:16.2f} | {b:8.3f}")
    if "group_shape" in results:
        r = results["group_shape"]
        print("\ncounterflow [1/m^2] | local [1/m^2] | lag [m] | across [m] | along [m]")
        for row in zip(r.density, r.local_density, r.lag, r.across, r.along):
            print("{:19.2f} | {:13.2f} | {:7.2f} | {:10.2f} | {:9.2f}".format(*row))
    if "lane_formation" in results:
        r = results["lane_formation"]
        print(f"\nlanes: order {r.order:.3f}, random mixing {r.random:.3f} ({r.frames} frames)")
    if "passing_distance" in results:
        r = results["passing_distance"]
        print(f"\npassing: closest centres {r.mean:.3f} +- {r.sd:.3f} m, body gap {r.gap:.3f} m")
    print("\nrun time: " + ", ".join(f"{k} {v:.1f} s" for k, v in times.items()))
    failed = sum(not c.ok for c in checks)
    print(f"{len(checks) - failed} of {len(checks)} figures pass")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
