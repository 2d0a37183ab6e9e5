"""The crowd's ``robot_reaction`` option: a multiplier on every person's reaction to robots
(0: robots are invisible to people), integrated with explicit Euler (no physics engine)."""

from __future__ import annotations

import numpy as np
import pytest

from srpb_gym.errors import InputError
from srpb_gym.sim.crowd import Crowd, SocialForceConfig
from srpb_gym.sim.layout import FormationLayout, PersonLayout

DT = 0.1
NO_WALLS = np.zeros((0, 4))
WALKER = PersonLayout((0.0, 0.0), 0.0, ((10.0, 0.0),), preferred_speed=1.0)
FORMATION = FormationLayout((0.0, 0.0), ((-0.7, 0.0), (0.7, 0.0)))


def simulate(people, formations, robot_xy, config, steps=80, seed=3):
    """Positions (steps + 1, P, 2) with one parked robot at ``robot_xy`` (or none)."""
    crowd = Crowd(config)
    rng = np.random.default_rng(seed)
    crowd.reset(people, formations, NO_WALLS, rng)
    rxy = np.array([robot_xy], dtype=np.float64).reshape(-1, 2)
    rvel, rrad = np.zeros_like(rxy), np.full(len(rxy), 0.3)
    pos = crowd.position.copy()
    out = [pos.copy()]
    for k in range(steps):
        v = crowd.desired_velocity(k * DT, DT, rxy, rvel, rrad, NO_WALLS, rng).copy()
        pos += v * DT
        crowd.sync(pos, v)
        out.append(pos.copy())
    return np.array(out)


def test_invisible_robot_leaves_a_walker_on_its_line():
    in_path = (4.0, 0.1)  # parked just off the walker's line, ahead of it
    alone = simulate([WALKER], (), (), SocialForceConfig())
    unseen = simulate([WALKER], (), in_path, SocialForceConfig(robot_reaction=0.0))
    seen = simulate([WALKER], (), in_path, SocialForceConfig(robot_reaction=1.0))
    np.testing.assert_array_equal(unseen, alone)  # exactly the walk without a robot
    assert np.abs(alone[:, 0, 1]).max() < 1e-9  # a straight line
    assert np.abs(seen[:, 0, 1]).max() > 0.2  # it steps aside
    ahead = seen[:, 0, 0] < in_path[0]
    assert np.hypot(*(seen[ahead, 0] - in_path).T).min() > 0.5  # ... before reaching it


def test_invisible_robot_leaves_formation_members_in_place():
    near = (1.2, 0.0)  # beside the right member
    config = {"formation_robot_reaction": 1.0}
    alone = simulate([], [FORMATION], (), SocialForceConfig(**config))
    unseen = simulate([], [FORMATION], near, SocialForceConfig(robot_reaction=0.0, **config))
    seen = simulate([], [FORMATION], near, SocialForceConfig(robot_reaction=1.0, **config))
    np.testing.assert_array_equal(unseen, alone)  # the same jitter, no robot
    assert alone[-1, 1, 0] - seen[-1, 1, 0] > 0.03  # the right member leans away from it


def test_global_reaction_multiplies_each_persons_own():
    robot = (4.0, 0.1)
    half = PersonLayout((0.0, 0.0), 0.0, ((10.0, 0.0),), preferred_speed=1.0, robot_reaction=0.5)
    doubled = simulate([half], (), robot, SocialForceConfig(robot_reaction=2.0))
    nominal = simulate([WALKER], (), robot, SocialForceConfig(robot_reaction=1.0))
    np.testing.assert_array_equal(doubled, nominal)  # 0.5 x 2 = 1 x 1
    scripted = PersonLayout((0.0, 0.0), 0.0, ((10.0, 0.0),), robot_reaction=0.0)
    ignored = simulate([scripted], (), robot, SocialForceConfig(robot_reaction=5.0))
    assert np.abs(ignored[:, 0, 1]).max() < 1e-9  # 0 stays 0
    # formation members: formation_robot_reaction (default 0) times the option
    members = simulate([], [FORMATION], (1.2, 0.0), SocialForceConfig(robot_reaction=5.0))
    still = simulate([], [FORMATION], (), SocialForceConfig(robot_reaction=5.0))
    np.testing.assert_array_equal(members, still)


def test_robot_reaction_option_is_checked():
    assert SocialForceConfig().robot_reaction == 1.0
    assert SocialForceConfig.from_spec({"robot_reaction": 0.0}).robot_reaction == 0.0
    with pytest.raises(InputError, match="robot_reaction"):
        SocialForceConfig.from_spec({"robot_reaction": -1.0}, path="crowd")
    with pytest.raises(InputError, match="robot_reaction"):
        SocialForceConfig.from_spec({"robot_reaction": float("nan")}, path="crowd")
