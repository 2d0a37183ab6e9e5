"""Calibration of the walking people against published pedestrian data.

Each measurement simulates people with the environment's own machinery, a
:class:`~srpb_gym.sim.crowd.Crowd` in a :class:`~srpb_gym.sim.world.World` without robots,
one crowd update per control step of :data:`CONTROL_DT` and :data:`PHYSICS_DT` physics
substeps (the defaults of ``srpb_gym.simulation.SimConfig``), and returns a plain result
with one :class:`Check` per figure: the value measured, the published one, the tolerance,
the source and whether it passes. ``docs/crowd.md`` describes the sources, the set-ups and
the measures; ``benchmarks/calibration.py`` runs them all at full size.

* :func:`free_walking`: speeds of people walking alone (Weidmann 1993).
* :func:`fundamental_diagram`: speed against density of one-way flow in a ring corridor
  (Weidmann 1993).
* :func:`group_shape`: the shape of walking groups of three, alone and meeting a
  counterflow (Moussaid et al. 2010).
* :func:`lane_formation`: the lane order parameter of two crowds passing through each
  other in a corridor, against random mixing (Rex & Loewen 2008).
* :func:`passing_distance`: the smallest distance of two strangers passing head-on
  (Olivier et al. 2012).

All randomness comes from a seeded :class:`numpy.random.Generator`. The people's parameter
ranges are a :class:`Walkers`; its defaults are the scenario defaults
(``srpb_gym.scenarios.schema.WalkerParams``, a test checks).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from srpb_gym.sim.calibration_setups import (
    CONTROL_DT,
    DEFAULT_WALKERS,
    PHYSICS_DT,
    Walkers,
    corridor_people,
    corridor_walls,
    group_layout,
    ring_people,
    ring_walls,
    simulate,
)
from srpb_gym.sim.crowd import SocialForceConfig
from srpb_gym.sim.layout import PersonLayout

__all__ = [
    "CONTROL_DT",
    "PHYSICS_DT",
    "Check",
    "FreeWalking",
    "FundamentalDiagram",
    "GroupShape",
    "Lanes",
    "Passing",
    "Walkers",
    "calibrate",
    "free_walking",
    "fundamental_diagram",
    "group_shape",
    "lane_formation",
    "lane_order",
    "passing_distance",
    "simulate",
    "weidmann_speed",
]

FAR = 80.0  # [m] how far beyond the end of a corridor the walkers' goals lie

# the sources, short (docs/crowd.md gives them in full)
WEIDMANN = "Weidmann 1993"
FREE_SPEED, FREE_SD = 1.34, 0.26  # [m/s] Weidmann 1993; Buchmueller & Weidmann 2006
JAM_DENSITY, WEIDMANN_GAMMA = 5.4, 1.913  # [1/m^2], [1/m^2] the Kladek formula's constants
MOUSSAID = "Moussaid et al. 2010, Fig. 4, Table 1"
REX_LOEWEN = "Rex & Loewen 2008 (order parameter)"
OLIVIER = "Olivier et al. 2012"


def weidmann_speed(density: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
    """Walking speed [m/s] of one-way flow at ``density`` [1/m^2] (Weidmann 1993)."""
    rho = np.asarray(density, dtype=np.float64)
    v = FREE_SPEED * (1.0 - np.exp(-WEIDMANN_GAMMA * (1.0 / rho - 1.0 / JAM_DENSITY)))
    return float(v) if v.ndim == 0 else v


@dataclass(frozen=True)
class Check:
    """One figure: the model's value against the published one.

    It passes when ``low <= model <= high``; ``tolerance`` says the band in words.
    """

    quantity: str
    model: float
    published: float
    tolerance: str
    low: float
    high: float
    source: str
    unit: str = ""

    @property
    def ok(self) -> bool:
        return bool(self.low <= self.model <= self.high)

    @classmethod
    def within(cls, quantity: str, model: float, published: float, tolerance: float,
               source: str, unit: str = "", relative: bool = False) -> Check:  # fmt: skip
        """Within ``tolerance`` of ``published`` (a share of it when ``relative``)."""
        band = tolerance * abs(published) if relative else tolerance
        text = f"+-{tolerance * 100:.0f} %" if relative else f"+-{tolerance:g} {unit}".strip()
        return cls(quantity, float(model), published, text, published - band, published + band,
                   source, unit)  # fmt: skip

    @classmethod
    def at_most(cls, quantity: str, model: float, published: float, limit: float,
                source: str, unit: str = "") -> Check:  # fmt: skip
        """At most ``limit`` (``published`` is the value the limit stands for)."""
        return cls(quantity, float(model), published, f"<= {limit:g} {unit}".strip(), -math.inf,
                   limit, source, unit)  # fmt: skip

    @classmethod
    def at_least(cls, quantity: str, model: float, published: float, limit: float,
                 source: str, unit: str = "") -> Check:  # fmt: skip
        """At least ``limit``."""
        return cls(quantity, float(model), published, f">= {limit:g} {unit}".strip(), limit,
                   math.inf, source, unit)  # fmt: skip


# --- 1. free walking speed -----------------------------------------------------------------


@dataclass(frozen=True)
class FreeWalking:
    """Realised speeds of people walking alone: mean and sd over people [m/s], and the
    uniform preferred-speed range whose mean and sd are the published ones."""

    mean: float
    sd: float
    preferred_mean: float
    preferred_sd: float
    matching_range: tuple[float, float]
    checks: tuple[Check, ...]


def free_walking(
    config: SocialForceConfig | None = None, walkers: Walkers = DEFAULT_WALKERS, people: int = 400,
    duration: float = 12.0, warmup: float = 4.0, seed: int = 0,
) -> FreeWalking:  # fmt: skip
    """``people`` walkers, each alone (farther apart than the interaction range), walk
    straight on; their speed is measured after ``warmup`` seconds."""
    cfg = config if config is not None else SocialForceConfig()
    rng = np.random.default_rng(seed)
    speed, radius, tau = walkers.draw(rng, people)
    spacing = cfg.interaction_range + 2.0
    y = spacing * np.arange(people)
    crowd = [PersonLayout((0.0, float(y[i])), 0.0, ((FAR, float(y[i])),),
                          preferred_speed=float(speed[i]), radius=float(radius[i]),
                          relaxation_time=float(tau[i]))
             for i in range(people)]  # fmt: skip
    traj = simulate(crowd, np.zeros((0, 4)), duration, cfg, rng)
    v = np.hypot(*np.moveaxis(traj.velocity[round(warmup / traj.dt) :], -1, 0)).mean(axis=0)
    half = math.sqrt(3.0) * FREE_SD
    source = f"{WEIDMANN}; Buchmueller & Weidmann 2006"
    pairs = (("mean", v.mean(), FREE_SPEED), ("sd", v.std(), FREE_SD))
    checks = tuple(Check.within(f"free walking speed, {name}", value, ref, 0.05, source, "m/s")
                   for name, value, ref in pairs)  # fmt: skip
    return FreeWalking(float(v.mean()), float(v.std()), float(speed.mean()), float(speed.std()),
                       (FREE_SPEED - half, FREE_SPEED + half), checks)  # fmt: skip


# --- 2. fundamental diagram ----------------------------------------------------------------


@dataclass(frozen=True)
class FundamentalDiagram:
    """Mean speed along the corridor [m/s] at each density [1/m^2], with Weidmann's, and the
    share of person-steps moving backwards (faster than 0.05 m/s against the flow)."""

    density: tuple[float, ...]
    speed: tuple[float, ...]
    published: tuple[float, ...]
    backward: tuple[float, ...]
    checks: tuple[Check, ...]


def fundamental_diagram(
    config: SocialForceConfig | None = None, walkers: Walkers = DEFAULT_WALKERS,
    densities: Sequence[float] = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0), inner: float = 8.5,
    outer: float = 11.5, warmup: float = 20.0, duration: float = 40.0, seed: int = 0,
    tolerance: float = 0.2,
) -> FundamentalDiagram:  # fmt: skip
    """One-way flow around an annular corridor (``inner``, ``outer`` radii [m]) with as many
    people as the density asks for in the whole annulus (no one enters or leaves), each
    on its own lane (:func:`~srpb_gym.sim.calibration_setups.ring_people`); after
    ``warmup`` seconds, the mean speed along the corridor (the angular speed times the
    radius) over ``duration`` seconds."""
    area = math.pi * (outer**2 - inner**2)
    walls = ring_walls(inner, outer)
    rows = []
    for rho in densities:
        rng = np.random.default_rng((seed, round(1000 * rho)))
        n = round(rho * area)
        traj = simulate(ring_people(n, inner, outer, walkers, rng), walls, warmup + duration,
                        config, rng)  # fmt: skip
        xy = traj.xy[round(warmup / traj.dt) :]
        theta = np.unwrap(np.arctan2(xy[..., 1], xy[..., 0]), axis=0)
        r = np.hypot(xy[..., 0], xy[..., 1])
        v = np.diff(theta, axis=0) * 0.5 * (r[1:] + r[:-1]) / traj.dt
        rows.append((n / area, float(v.mean()), float((v < -0.05).mean())))
    density, speed, backward = (tuple(col) for col in zip(*rows))
    published = tuple(float(weidmann_speed(d)) for d in density)
    checks = tuple(Check.within(f"speed at {d:.2f} p/m^2", v, round(w, 3), tolerance, WEIDMANN,
                                "m/s", relative=True)
                   for d, v, w in zip(density, speed, published))  # fmt: skip
    return FundamentalDiagram(density, speed, published, backward, checks)


# --- 3. walking groups ---------------------------------------------------------------------


@dataclass(frozen=True)
class GroupShape:
    """Shape of walking groups of three at each counterflow density [1/m^2]: ``lag``, the
    middle member's position along the walking direction relative to the mean of the outer
    two [m] (negative: behind, a V; near 0: abreast); ``across`` and ``along``, the group's
    extent across and along the walking direction [m]; ``local_density``, the counterflow's
    density [1/m^2] within 2 m of the group's centre over the frames measured."""

    density: tuple[float, ...]
    lag: tuple[float, ...]
    across: tuple[float, ...]
    along: tuple[float, ...]
    local_density: tuple[float, ...]
    checks: tuple[Check, ...]


def group_shape(
    config: SocialForceConfig | None = None, walkers: Walkers = DEFAULT_WALKERS,
    densities: Sequence[float] = (0.0, 0.25, 0.5, 1.0), groups: int = 4, runs: int = 6,
    length: float = 60.0, width: float = 5.0, seed: int = 0, abreast: float = 0.1,
    behind: float = 0.1, moderate: float = 0.5,
) -> GroupShape:  # fmt: skip
    """``groups`` groups of three, 15 m apart, walk along a corridor of ``width`` [m]
    towards a crowd of each density that fills its first ``length`` metres and walks the
    other way (``runs`` times). The shape is averaged over the frames in which a group is
    inside the oncoming crowd (its density within 2 m of the group's centre at least half
    the crowd's; without a crowd: the frames after 3 s within those ``length`` metres).
    Checks: abreast (``|lag| <= abreast``) at the lowest density, a V (``lag <= -behind``)
    at the density ``moderate``."""
    rows = []
    spacing = 15.0
    start = -spacing * groups - 10.0  # the corridor's open end behind the groups
    walls = corridor_walls(start, length + 10.0, width)
    for rho in densities:
        n = round(rho * length * width)
        sums = np.zeros(5)
        for run in range(runs):
            rng = np.random.default_rng((seed, round(1000 * rho), run))
            people = group_layout(groups, rng, walkers, width, length + FAR, spacing)
            m = len(people)
            if n:
                people += corridor_people(n, (0.0, 0.0, length, width), -1, walkers, rng, width,
                                          start - FAR)  # fmt: skip
            xy = simulate(people, walls, (length - start) / 2.0 + 10.0, config, rng).xy[30:]
            members = xy[:, :m].reshape(len(xy), groups, 3, 2)
            order = np.argsort(members[..., 1], axis=2)  # by y: right, middle, left
            x = np.take_along_axis(members[..., 0], order, axis=2)
            y = np.take_along_axis(members[..., 1], order, axis=2)
            center = members.mean(axis=2)  # (T, G, 2)
            d = np.hypot(*np.moveaxis(center[:, :, None] - xy[:, None, m:], -1, 0))
            near = (d < 2.0).sum(axis=2) / (4.0 * math.pi)
            inside = near >= 0.5 * rho if n else (center[..., 0] > 0.0) & (center[..., 0] < length)
            measures = (x[..., 1] - 0.5 * (x[..., 0] + x[..., 2]), y[..., 2] - y[..., 0],
                        x.max(axis=2) - x.min(axis=2), near)  # fmt: skip
            sums += [inside.sum(), *(a[inside].sum() for a in measures)]
        rows.append([rho, *(sums[1:] / max(sums[0], 1.0))])
    density, lag, across, along, local = (tuple(float(v) for v in col) for col in zip(*rows))
    checks = [Check.within(f"group of 3 lag, alone ({density[0]:g} p/m^2)", lag[0], 0.0,
                           abreast, MOUSSAID + " (abreast)", "m")]  # fmt: skip
    if moderate in density:
        k = density.index(moderate)
        v_shape = MOUSSAID + " (V: middle behind)"
        checks.append(Check.at_most(f"group of 3 lag, counterflow {moderate:g} p/m^2", lag[k],
                                    -behind, -behind, v_shape, "m"))  # fmt: skip
    return GroupShape(density, lag, across, along, local, tuple(checks))


# --- 4. lanes ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Lanes:
    """Lane order parameter of two opposite crowds where they overlap, averaged over the
    frames: the model's and that of the same positions with the walking directions shuffled
    (random mixing); ``excess`` = order - random."""

    order: float
    random: float
    excess: float
    frames: int
    checks: tuple[Check, ...]


def lane_order(
    xy: NDArray[np.float64], sign: NDArray[np.int64], band: float = 0.5, reach: float = 3.0,
) -> float:  # fmt: skip
    """Order parameter (Rex & Loewen 2008) of people at ``xy`` (P, 2) walking in direction
    ``sign`` (P,) along x: the mean over people of ((same - other) / (same + other))^2,
    counting the others within ``band`` [m] across and ``reach`` [m] along (people without
    any are left out); 1 in perfect lanes, about 1 / (neighbours) for random mixing."""
    d = np.abs(xy[:, None, :] - xy[None, :, :])
    near = (d[..., 1] < band) & (d[..., 0] < reach)
    np.fill_diagonal(near, False)
    same = (near & (sign[:, None] == sign[None, :])).sum(axis=1)
    total = near.sum(axis=1)
    seen = total > 0
    if not seen.any():
        return math.nan
    return float((((2 * same - total)[seen] / total[seen]) ** 2).mean())


def lane_formation(
    config: SocialForceConfig | None = None, walkers: Walkers = DEFAULT_WALKERS,
    density: float = 1.0, width: float = 4.0, block: float = 12.0, runs: int = 4,
    seed: int = 0, shuffles: int = 20, min_people: int = 10, excess: float = 0.1,
) -> Lanes:  # fmt: skip
    """Two crowds of ``density`` [1/m^2], each ``block`` m long, start face to face in a
    corridor of ``width`` and walk through each other (``runs`` times). In every frame
    (every 0.5 s) in which at least ``min_people`` stand where they overlap (between the
    5th percentile of the left-going crowd's x and the 95th of the right-going one's),
    :func:`lane_order` of those people against the mean over ``shuffles`` random
    relabellings. Passes when the order exceeds random mixing by ``excess``."""
    n = round(density * block * width)
    length = 2.0 * block + 2.0
    sign = np.repeat([1, -1], n)
    walls = corridor_walls(-2.0 * length, 3.0 * length, width)
    order, base = [], []
    for run in range(runs):
        rng = np.random.default_rng((seed, run))
        people = corridor_people(n, (0.0, 0.0, block, width), 1, walkers, rng, width,
                                 length + FAR)  # fmt: skip
        people += corridor_people(n, (block + 2.0, 0.0, length, width), -1, walkers, rng,
                                  width, -FAR)  # fmt: skip
        for frame in simulate(people, walls, 2.0 * length / 1.2, config, rng).xy[::5]:
            lo = np.quantile(frame[n:, 0], 0.05)
            hi = np.quantile(frame[:n, 0], 0.95)
            zone = (frame[:, 0] >= lo) & (frame[:, 0] <= hi)
            if zone.sum() < min_people or (sign[zone] > 0).all() or (sign[zone] < 0).all():
                continue
            order.append(lane_order(frame[zone], sign[zone]))
            base.append(np.nanmean([lane_order(frame[zone], rng.permutation(sign[zone]))
                                    for _ in range(shuffles)]))  # fmt: skip
    phi, rand = float(np.nanmean(order)), float(np.nanmean(base))
    checks = (Check.at_least("lane order above random mixing", phi - rand, excess, excess,
                             REX_LOEWEN),)  # fmt: skip
    return Lanes(phi, rand, phi - rand, len(order), checks)


# --- 5. passing distance -------------------------------------------------------------------


@dataclass(frozen=True)
class Passing:
    """Smallest centre distance [m] of two people passing head-on: mean and sd over the
    pairs, and the mean gap between their bodies (centre distance less the radii)."""

    mean: float
    sd: float
    gap: float
    checks: tuple[Check, ...]


def passing_distance(
    config: SocialForceConfig | None = None, walkers: Walkers = DEFAULT_WALKERS, pairs: int = 100,
    offset: float = 0.2, start: float = 16.0, seed: int = 0, published: float = 1.0,
    tolerance: float = 0.2,
) -> Passing:  # fmt: skip
    """``pairs`` pairs of strangers, each alone in open space (pairs farther apart than the
    interaction range), start ``start`` m apart and walk towards each other on lines up to
    ``offset`` m apart (uniform); the smallest distance of each pair's centres."""
    cfg = config if config is not None else SocialForceConfig()
    rng = np.random.default_rng(seed)
    spacing = cfg.interaction_range + 5.0
    speed, radius, tau = walkers.draw(rng, 2 * pairs)
    lateral = rng.uniform(-offset, offset, pairs)
    people = []
    for k in range(pairs):
        for j, (x, end) in enumerate(((0.0, start + FAR), (start, -FAR))):
            y = spacing * k + (0.5 - j) * lateral[k]
            i = 2 * k + j
            people.append(PersonLayout((x, y), 0.0 if j == 0 else math.pi, ((end, y),),
                                       preferred_speed=float(speed[i]), radius=float(radius[i]),
                                       relaxation_time=float(tau[i])))  # fmt: skip
    xy = simulate(people, np.zeros((0, 4)), 2.0 * start / 1.5, cfg, rng).xy
    gap = xy[:, 0::2] - xy[:, 1::2]
    closest = np.hypot(gap[..., 0], gap[..., 1]).min(axis=0)
    body = closest - radius[0::2] - radius[1::2]
    checks = (Check.within("passing distance, centres", closest.mean(), published, tolerance,
                           OLIVIER, "m", relative=True),)  # fmt: skip
    return Passing(float(closest.mean()), float(closest.std()), float(body.mean()), checks)


# --- all of them ---------------------------------------------------------------------------

#: the keyword arguments of each measurement at the reduced size of the tests (each
#: measurement's defaults are the full size)
SMALL: dict[str, dict[str, object]] = {
    "free_walking": {"people": 100, "duration": 8.0},
    "fundamental_diagram": {"warmup": 10.0, "duration": 10.0},
    "group_shape": {"densities": (0.0, 0.5), "runs": 4},
    "lane_formation": {"block": 8.0, "runs": 3},
    "passing_distance": {"pairs": 40},
}
MEASUREMENTS: dict[str, Callable[..., object]] = {
    "free_walking": free_walking,
    "fundamental_diagram": fundamental_diagram,
    "group_shape": group_shape,
    "lane_formation": lane_formation,
    "passing_distance": passing_distance,
}


def calibrate(
    config: SocialForceConfig | None = None, walkers: Walkers = DEFAULT_WALKERS,
    small: bool = False, seed: int = 0, only: Sequence[str] = (),
) -> dict[str, object]:  # fmt: skip
    """Every measurement (or those named in ``only``) by name, at full size or at the
    reduced size of :data:`SMALL`; each result has its ``checks``."""
    out = {}
    for name, measure in MEASUREMENTS.items():
        if not only or name in only:
            extra = SMALL[name] if small else {}
            out[name] = measure(config, walkers, seed=seed, **extra)
    return out
