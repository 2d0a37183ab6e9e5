"""Behaviour of the social-force crowd, integrated with explicit Euler (no physics engine)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from srpb_gym.errors import InputError
from srpb_gym.sim import social_force as crowd_module
from srpb_gym.sim.crowd import (
    STANDING,
    STOPPED,
    WAITING,
    WALKING,
    Crowd,
    SocialForceConfig,
)
from srpb_gym.sim.layout import FormationLayout, PersonLayout

DT = 0.1
NO_WALLS = np.zeros((0, 4))


def robots(*xy: tuple[float, float], radius: float = 0.3, vel=(0.0, 0.0)):
    """(positions, velocities, radii) of standing or moving robots."""
    pos = np.array(xy, dtype=np.float64).reshape(-1, 2)
    return pos, np.tile(np.asarray(vel, dtype=np.float64), (len(pos), 1)), np.full(len(pos), radius)


def simulate(people=(), formations=(), walls=NO_WALLS, robot=None, duration=20.0, seed=0,
             config=None):  # fmt: skip
    """Positions (N+1, P, 2), yaws (N+1, P), states (N+1, P) and the crowd after ``duration``."""
    crowd = Crowd(config)
    rng = np.random.default_rng(seed)
    crowd.reset(people, formations, walls, rng)
    rxy, rvel, rrad = robot if robot is not None else robots()
    pos = crowd.position.copy()
    traj, yaws, states = [pos.copy()], [crowd.yaw.copy()], [crowd.state.copy()]
    for k in range(round(duration / DT)):
        v = crowd.desired_velocity(k * DT, DT, rxy, rvel, rrad, walls, rng).copy()
        pos += v * DT
        crowd.sync(pos, v)
        traj.append(pos.copy())
        yaws.append(crowd.yaw.copy())
        states.append(crowd.state.copy())
    return np.array(traj), np.array(yaws), np.array(states), crowd


def angle_diff(a, b):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


def crosses(p, q, wall) -> bool:
    """Whether segment p-q intersects the wall segment (touching counts)."""
    a, b = np.asarray(wall[:2]), np.asarray(wall[2:])

    def orient(u, v, w):
        return np.sign((v[0] - u[0]) * (w[1] - u[1]) - (v[1] - u[1]) * (w[0] - u[0]))

    return orient(p, q, a) != orient(p, q, b) and orient(a, b, p) != orient(a, b, q)


def test_route_followed_in_order_then_stops():
    route = ((4.0, 0.0), (4.0, 4.0), (0.0, 4.0))
    traj, _, states, _ = simulate([PersonLayout((0.0, 0.0), 0.0, route)], duration=20.0)
    xy = traj[:, 0]
    first_close = [int(np.argmax(np.hypot(*(xy - w).T) < 0.35)) for w in route]
    assert all(np.hypot(*(xy[k] - w)) < 0.35 for k, w in zip(first_close, route))
    assert first_close == sorted(first_close) and first_close[0] > 0
    assert states[-1, 0] == STOPPED
    assert np.hypot(*(xy[-1] - route[-1])) < 0.3
    assert np.abs(np.diff(xy[-30:], axis=0)).max() < 1e-3  # stands still


def test_looping_route_repeats():
    route = ((3.0, 0.0), (3.0, 3.0), (0.0, 0.0))
    traj, _, states, _ = simulate([PersonLayout((0.0, 0.0), 0.0, route, loop=True)], duration=40)
    d = np.hypot(*(traj[:, 0] - route[0]).T)
    visits = np.flatnonzero((d[1:] < 0.35) & (d[:-1] >= 0.35))
    assert len(visits) >= 3
    assert (states[1:, 0] == WALKING).all()


def test_head_on_in_corridor_no_overlap():
    walls = np.array([[-1.0, -1.0, 11.0, -1.0], [-1.0, 1.0, 11.0, 1.0]])
    people = [PersonLayout((0.0, 0.0), 0.0, ((10.0, 0.0),)),
              PersonLayout((10.0, 0.0), math.pi, ((0.0, 0.0),))]  # fmt: skip
    traj, _, states, _ = simulate(people, walls=walls, duration=20.0)
    gap = np.hypot(*(traj[:, 0] - traj[:, 1]).T)
    assert gap.min() > 0.5 - 0.01
    assert np.abs(traj[:, :, 1]).max() < 1.0 - 0.25 + 1e-9  # inside the corridor
    assert (states[-1] == STOPPED).all()
    assert np.hypot(*(traj[-1, 0] - (10.0, 0.0))) < 0.5
    assert np.hypot(*(traj[-1, 1] - (0.0, 0.0))) < 0.5


@pytest.mark.parametrize("y0", [0.0, 0.4, -0.7])
def test_walks_around_a_short_wall_never_through(y0):
    wall = np.array([[5.0, -1.0, 5.0, 1.0]])
    traj, _, _, _ = simulate([PersonLayout((0.0, y0), 0.0, ((10.0, y0),))], walls=wall,
                             duration=30.0)  # fmt: skip
    xy = traj[:, 0]
    assert not any(crosses(xy[k], xy[k + 1], wall[0]) for k in range(len(xy) - 1))
    assert np.hypot(*(xy[-1] - (10.0, y0))) < 0.5  # got around the end


def test_formation_members_hold_place_and_face_centre():
    centre = (3.0, 3.0)
    places = ((3.6, 3.0), (2.7, 3.52), (2.7, 2.48))
    form = FormationLayout(centre, places, jitter=0.02)
    traj, yaws, states, crowd = simulate(formations=[form], duration=60.0, seed=3)
    assert (states == STANDING).all()
    assert np.hypot(*(traj - np.array(places)).transpose(2, 0, 1)).max() < 0.1
    facing = np.arctan2(centre[1] - traj[..., 1], centre[0] - traj[..., 0])
    assert angle_diff(yaws, facing).max() < 0.3
    assert np.ptp(traj[:, 0, 0]) > 0.005  # they do move a little
    assert crowd.formation_of.tolist() == [0, 0, 0]
    np.testing.assert_array_equal(crowd.formation_members[0], [0, 1, 2])


def test_formation_members_hold_place_against_a_robot_by_default():
    form = FormationLayout((0.0, 0.0), ((0.6, 0.0), (-0.6, 0.0)), jitter=0.0)
    robot = robots((1.1, 0.0))
    traj, *_ = simulate(formations=[form], robot=robot, duration=5.0)
    assert np.abs(traj[-1, 0] - (0.6, 0.0)).max() < 1e-6
    config = SocialForceConfig(formation_robot_reaction=1.0)
    traj, *_ = simulate(formations=[form], robot=robot, duration=5.0, config=config)
    assert traj[-1, 0, 0] < 0.6 - 0.03  # pushed away from the robot


def test_walking_group_stays_together():
    route = ((20.0, 0.0), (20.0, 10.0))
    people = [PersonLayout((0.0, y), 0.0, route, group=7, preferred_speed=s)
              for y, s in ((-0.6, 1.0), (0.0, 1.4), (0.6, 1.2))]  # fmt: skip
    traj, _, states, crowd = simulate(people, duration=30.0)
    walking = (states == WALKING).all(axis=1)
    centre = traj.mean(axis=1, keepdims=True)
    spread = np.hypot(*(traj - centre).transpose(2, 0, 1)).max(axis=1)
    assert walking.sum() > 100
    assert spread[walking].max() < 1.5
    assert crowd.walking_group.tolist() == [0, 0, 0]


def test_group_id_used_once_counts_as_alone():
    people = [PersonLayout((0.0, 0.0), 0.0, ((1.0, 0.0),), group=4),
              PersonLayout((0.0, 2.0), 0.0, ((1.0, 2.0),), group=5),
              PersonLayout((0.0, 4.0), 0.0, ((1.0, 4.0),), group=5)]  # fmt: skip
    crowd = Crowd()
    crowd.reset(people, (), NO_WALLS)
    assert crowd.walking_group.tolist() == [-1, 0, 0]


@pytest.mark.parametrize("reaction", [0.0, 1.0])
def test_robot_reaction(reaction):
    person = PersonLayout((0.0, 0.0), 0.0, ((10.0, 0.0),), robot_reaction=reaction)
    traj, *_ = simulate([person], robot=robots((5.0, 0.0)), duration=15.0)
    gap = np.hypot(traj[:, 0, 0] - 5.0, traj[:, 0, 1])
    if reaction == 0.0:
        assert gap.min() < 0.1  # walks straight through the robot's position
        assert np.abs(traj[:, 0, 1]).max() < 1e-9
    else:
        assert gap.min() > 0.25 + 0.3 + 0.1  # keeps a distance
    assert np.hypot(*(traj[-1, 0] - (10.0, 0.0))) < 0.5


def test_start_delay():
    person = PersonLayout((0.0, 0.0), 1.0, ((5.0, 0.0),), start_delay=2.0)
    traj, yaws, states, _ = simulate([person], duration=5.0)
    k = round(2.0 / DT)
    assert (states[:k, 0] == WAITING).all() and states[k + 1, 0] == WALKING
    assert np.abs(traj[: k + 1, 0] - (0.0, 0.0)).max() < 1e-12
    assert np.all(yaws[: k + 1, 0] == 1.0)
    assert traj[k + 5, 0, 0] > 0.1


@pytest.mark.parametrize("speed", [0.6, 1.2])
def test_preferred_speed_on_free_walk(speed):
    person = PersonLayout((0.0, 0.0), 0.0, ((50.0, 0.0),), preferred_speed=speed)
    traj, yaws, _, _ = simulate([person], duration=15.0)
    v = np.hypot(*np.diff(traj[:, 0], axis=0).T) / DT
    assert abs(v[50:].mean() - speed) < 0.1 * speed
    assert np.all(np.abs(v[50:] - speed) < 0.1 * speed)
    assert angle_diff(yaws[-1, 0], 0.0) < 1e-6


def test_yaw_turns_smoothly_towards_motion():
    person = PersonLayout((0.0, 0.0), math.pi, ((5.0, 0.0),))
    _, yaws, _, _ = simulate([person], duration=3.0)
    error = angle_diff(yaws[:, 0], 0.0)
    assert angle_diff(yaws[1:, 0], yaws[:-1, 0]).max() < 1.0  # no jump to the new heading
    assert np.all(np.diff(error) <= 1e-12)  # turns steadily towards the motion
    assert error[-1] < 0.05


def mixed_scene():
    walls = np.array([[-2.0, -3.0, 12.0, -3.0], [-2.0, 3.0, 12.0, 3.0], [6.0, -0.5, 6.0, 0.5]])
    people = [
        PersonLayout((0.0, 0.0), 0.0, ((10.0, 0.0), (0.0, 1.0)), loop=True),
        PersonLayout((10.0, 0.5), math.pi, ((0.0, 0.5),), group=1),
        PersonLayout((10.0, -0.5), math.pi, ((0.0, -0.5),), group=1, start_delay=1.0),
    ]
    formations = [FormationLayout((4.0, 2.0), ((4.5, 2.0), (3.5, 2.0)))]
    return people, formations, walls  # fmt: skip


def test_same_seed_bit_identical_trajectories():
    people, formations, walls = mixed_scene()
    robot = robots((5.0, -1.0), vel=(0.2, 0.1))
    a = simulate(people, formations, walls, robot, duration=20.0, seed=11)
    b = simulate(people, formations, walls, robot, duration=20.0, seed=11)
    c = simulate(people, formations, walls, robot, duration=20.0, seed=12)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.array_equal(a[0][:, 3:], c[0][:, 3:])  # the jitter follows the rng


def test_no_nan_with_coincident_people():
    route = ((5.0, 0.0),)
    people = [PersonLayout((0.0, 0.0), 0.0, route, group=g) for g in (-1, -1, 2, 2)]
    form = FormationLayout((0.0, 0.0), ((0.0, 0.0), (0.0, 0.0)))
    traj, yaws, _, _ = simulate(people, [form], robot=robots((0.0, 0.0)), duration=10.0)
    assert np.isfinite(traj).all() and np.isfinite(yaws).all()
    assert np.hypot(*(traj[-1, 0] - traj[-1, 1])) > 0.3  # pushed apart


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(0.3, 1.8)),
                min_size=1, max_size=8),
       st.integers(0, 2**32 - 1))  # fmt: skip
def test_velocities_finite_and_capped(spec, seed):
    rng = np.random.default_rng(seed)
    people = [PersonLayout((x, y), 0.0, ((-x, -y), (x, -y)), loop=True, preferred_speed=s)
              for x, y, s in spec]  # fmt: skip
    forms = [FormationLayout((0.0, 0.0), ((0.5, 0.0), (-0.5, 0.0)))]
    walls = np.array([[-1.0, -1.0, 1.0, 1.0], [2.0, -4.0, 2.0, 4.0]])
    crowd = Crowd()
    crowd.reset(people, forms, walls, rng)
    vmax = np.array([1.3 * s for *_, s in spec] + [0.6, 0.6])
    pos = crowd.position.copy()
    rxy, rvel, rrad = robots((0.0, 0.0), vel=(0.5, 0.0))
    for k in range(30):
        v = crowd.desired_velocity(k * DT, DT, rxy, rvel, rrad)
        assert np.isfinite(v).all()
        assert (np.hypot(*v.T) <= vmax + 1e-9).all()
        pos += v * DT
        crowd.sync(pos, v.copy())


def test_state_views_are_read_only_and_ordered():
    people, formations, walls = mixed_scene()
    crowd = Crowd()
    crowd.reset(people, formations, walls, np.random.default_rng(0))
    assert crowd.position.shape == (5, 2) and crowd.radius.shape == (5,)
    assert crowd.formation_of.tolist() == [-1, -1, -1, 0, 0]
    assert crowd.walking_group.tolist() == [-1, 0, 0, -1, -1]
    np.testing.assert_array_equal(crowd.formation_centers, [[4.0, 2.0]])
    np.testing.assert_allclose(crowd.yaw[3:], [math.pi, 0.0], atol=1e-12)
    for arr in (crowd.position, crowd.velocity, crowd.yaw, crowd.state, crowd.formation_of):
        assert not arr.flags.writeable
    v = crowd.desired_velocity(0.0, DT, *robots())
    assert v.dtype == np.float64 and v.shape == (5, 2) and v.flags.c_contiguous
    with pytest.raises(ValueError, match="dt"):
        crowd.desired_velocity(0.0, 0.0, *robots())


def test_empty_crowd():
    crowd = Crowd()
    crowd.reset((), (), NO_WALLS)
    assert crowd.desired_velocity(0.0, DT, *robots((1.0, 1.0))).shape == (0, 2)
    crowd.sync(np.zeros((0, 2)), np.zeros((0, 2)))


def test_config_validation_and_spec():
    with pytest.raises(ValueError, match="person_range"):
        SocialForceConfig(person_range=0.0)
    with pytest.raises(ValueError, match="anisotropy"):
        SocialForceConfig(anisotropy=1.5)
    with pytest.raises(ValueError, match="evasion"):
        SocialForceConfig(evasion=-0.1)
    with pytest.raises(ValueError, match="finite"):
        SocialForceConfig(wall_strength=float("nan"))
    assert SocialForceConfig.from_spec(None) == SocialForceConfig()
    assert SocialForceConfig.from_spec({"preset": "default", "robot_range": 0.8}).robot_range == 0.8
    with pytest.raises(InputError, match="unknown key"):
        SocialForceConfig.from_spec({"bogus": 1.0}, path="crowd")


def test_kernel_parameter_indices_follow_the_fields():
    names = [f.name for f in dataclasses.fields(SocialForceConfig)]
    m = crowd_module
    expected = {"person_strength": m.A_P, "anisotropy": m.LAM, "wall_range": m.B_W,
                "ospace_strength": m.A_O, "group_gaze": m.BETA1, "waypoint_tolerance": m.TOL,
                "hold_damping": m.C_HOLD, "formation_robot_reaction": m.F_REACT,
                "yaw_min_speed": m.V_YAW, "robot_ttc_strength": m.K_TTC,
                "robot_ttc_margin": m.M_TTC, "door_approach": m.D_APPROACH,
                "door_wait_distance": m.D_WAIT, "robot_backing_gap": m.G_BACK}  # fmt: skip
    assert len(names) == m.G_BACK + 1
    assert all(names[index] == name for name, index in expected.items())
