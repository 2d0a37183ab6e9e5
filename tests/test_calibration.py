"""The crowd calibration (docs/crowd.md): the harness steps people as the environment does,
its measures are right on known inputs, and the model's figures hold their published
values at the reduced size of ``calibration.SMALL`` (the full size: benchmarks/calibration.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from srpb_gym.scenarios import sampler
from srpb_gym.scenarios.schema import WalkerParams
from srpb_gym.sim import calibration as cal
from srpb_gym.sim import calibration_setups as setups
from srpb_gym.sim.layout import EpisodeLayout
from srpb_gym.simulation import SimConfig, Simulation


def test_defaults_are_the_environments():
    sim = SimConfig()
    assert (sim.control_dt, sim.physics_dt) == (cal.CONTROL_DT, cal.PHYSICS_DT)
    assert not sim.crowd_every_substep  # simulate() updates the crowd once per control step
    params, walkers = WalkerParams(), cal.Walkers()
    assert walkers.preferred_speed == params.preferred_speed
    assert walkers.radius == params.radius
    assert walkers.relaxation_time == params.relaxation_time
    assert setups.GROUP_GAP == sampler.GROUP_GAP


def test_simulate_steps_people_as_the_simulation_does():
    people = setups.ring_people(30, 3.0, 5.0, cal.Walkers(), np.random.default_rng(3))
    walls = setups.ring_walls(3.0, 5.0)
    sim = Simulation()
    sim.reset(EpisodeLayout(walls=walls, robots=(), people=tuple(people), time_limit=5.0),
              np.random.default_rng(5))  # fmt: skip
    xy = [sim.world.people_xy.copy()]
    for _ in range(30):
        sim.step(np.zeros((0, 3)))
        xy.append(sim.world.people_xy.copy())
    traj = cal.simulate(people, walls, 3.0, None, np.random.default_rng(5))
    np.testing.assert_array_equal(traj.xy, np.array(xy))


def test_spread_people_do_not_overlap_and_stay_inside():
    rng = np.random.default_rng(0)
    people = setups.ring_people(250, 5.0, 8.0, cal.Walkers(), rng)  # 3.3 people per m^2
    xy = np.array([p.position for p in people])
    radius = np.array([p.radius for p in people])
    d = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1)) + np.eye(len(xy)) * 9.0
    assert (d >= radius[:, None] + radius[None] - 1e-3).all()
    r = np.hypot(xy[:, 0], xy[:, 1])
    assert (r - radius > 5.0).all() and (r + radius < 8.0).all()
    for p in people:  # each loops around on its own circle, anticlockwise, from where it is
        assert p.loop and len(p.route) == 12
        lane = np.hypot(*np.array(p.route).T)
        assert np.allclose(lane, lane[0])
        assert lane[0] >= min(np.hypot(*p.position), 8.0 - p.radius - 0.05) - 1e-9
        assert lane[0] * math.cos(math.pi / 12) - p.radius >= 5.0 + 0.05 - 1e-9  # legs clear
        first = np.arctan2(p.route[0][1], p.route[0][0]) - np.arctan2(p.position[1], p.position[0])
        assert 0.0 < first % (2 * np.pi) <= 2 * np.pi / 12 + 1e-9


def test_weidmann_speed():
    assert cal.weidmann_speed(5.4) == pytest.approx(0.0)
    assert cal.weidmann_speed(1.0) == pytest.approx(1.34 * (1 - math.exp(-1.913 * (1 - 1 / 5.4))))
    assert cal.weidmann_speed(0.01) == pytest.approx(1.34)
    np.testing.assert_allclose(cal.weidmann_speed(np.array([0.5, 2.0, 3.0])),
                               [1.298, 0.606, 0.331], atol=1e-3)  # fmt: skip


def test_lane_order_of_lanes_and_of_mixing():
    x = np.tile(np.arange(10.0) * 0.6, 4)
    y = np.repeat(np.arange(4.0) * 0.6, 10)
    lanes = np.repeat([1, -1, 1, -1], 10)
    assert cal.lane_order(np.stack([x, y], axis=1), lanes) == pytest.approx(1.0)
    checker = np.where((np.arange(40) + np.repeat(np.arange(4), 10)) % 2 == 0, 1, -1)
    assert cal.lane_order(np.stack([x, y], axis=1), checker) < 0.2
    assert math.isnan(cal.lane_order(np.array([[0.0, 0.0], [0.0, 5.0]]), np.array([1, -1])))


def test_check_bands():
    check = cal.Check.within("v", 1.1, 1.0, 0.2, "src", "m/s", relative=True)
    assert check.ok and check.tolerance == "+-20 %"
    assert not cal.Check.within("v", 1.25, 1.0, 0.2, "src", relative=True).ok
    assert cal.Check.at_least("x", 0.2, 0.1, 0.1, "src").ok
    assert not cal.Check.at_most("x", 0.0, -0.1, -0.1, "src").ok


# --- the model's figures at the reduced size ------------------------------------------------


def _failures(result) -> str:
    return "; ".join(f"{c.quantity}: {c.model:.3f} not in [{c.low:.3f}, {c.high:.3f}]"
                     for c in result.checks if not c.ok)  # fmt: skip


@pytest.mark.parametrize("name", list(cal.MEASUREMENTS))
def test_figure_holds_its_published_value(name):
    result = cal.calibrate(small=True, only=(name,))[name]
    assert result.checks
    assert all(c.ok for c in result.checks), _failures(result)
