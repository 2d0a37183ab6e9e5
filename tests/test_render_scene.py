"""The renderer's geometry and scene, in pixels, without pygame."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from srpb_gym.metrics import kernels
from srpb_gym.render import (
    ROBOT_PALETTE,
    Scene,
    covariance_ellipses,
    fit_view,
    formation_ellipses,
    grid_lines,
    panel_layout,
    panel_values,
    personal_space_contours,
    robot_colors,
    scene_primitives,
)
from srpb_gym.render.style import BOTTOM_STRIP, COLUMN, LEGEND, ROW, SIDE_STRIP
from srpb_gym.scenarios import load_scenario, sample
from srpb_gym.sim.layout import EpisodeLayout, PersonLayout, RobotLayout
from srpb_gym.sim.robot import RobotConfig
from srpb_gym.simulation import Simulation

BOX = np.array([[0, 0, 8, 0], [8, 0, 8, 6], [8, 6, 0, 6], [0, 6, 0, 0]], dtype=float)


def _scenario(name: str, steps: int = 0, seed: int = 0) -> Simulation:
    scenario = load_scenario(name)
    sim = Simulation.from_scenario(scenario)
    sim.reset(sample(scenario, np.random.default_rng(seed)), np.random.default_rng(seed))
    for _ in range(steps):
        sim.step([[0.4, 0.0, 0.1]], 0.0)
    return sim


def _box(robots: int = 1, people=(), radius: float = 0.275, tolerance: float = 0.2) -> Simulation:
    """An 8 m x 6 m room with ``robots`` robots at x = 2 m facing +x, goals at x = 6 m."""
    layout = EpisodeLayout(
        BOX,
        tuple(RobotLayout((2.0, 1.0 + i, 0.0), (6.0, 1.0 + i, 0.5 * i)) for i in range(robots)),
        people=tuple(people),
        goal_tolerance=tolerance,
        bounds=(0.0, 0.0, 8.0, 6.0),
    )
    sim = Simulation(robot=RobotConfig(radius=radius))
    sim.reset(layout, np.random.default_rng(0))
    return sim


# ---------------------------------------------------------------------- view
def test_view_maps_bounds_y_up_at_one_scale():
    view = fit_view((-2.0, 1.0, 6.0, 7.0), 720, 540)
    (ax, ay), (bx, by) = view.px([[-2.0, 1.0], [6.0, 7.0]]).tolist()
    assert bx > ax and by < ay  # x to the right, y up
    assert abs((bx - ax) - 8.0 * view.scale) <= 1 and abs((ay - by) - 6.0 * view.scale) <= 1
    x, y, w, h = view.world
    assert x <= ax < bx <= x + w and y <= by < ay <= y + h
    assert view.panel == (720 - SIDE_STRIP, 0, SIDE_STRIP, 540)  # a wide world: panel beside


def test_view_puts_a_wide_world_above_the_panel():
    view = fit_view((0.0, 0.0, 30.0, 4.0), 720, 540)
    assert view.panel == (0, 540 - BOTTOM_STRIP, 720, BOTTOM_STRIP)
    assert view.world == (0, 0, 720, 540 - BOTTOM_STRIP)


def test_grid_lines_every_metre():
    view = fit_view((0.0, 0.0, 8.0, 6.0), 720, 540)
    lines = grid_lines(view, (0.0, 0.0, 8.0, 6.0))
    assert lines.shape == (9 + 7, 2, 2)
    np.testing.assert_array_equal(lines[1, 0], view.px([1.0, 0.0]))


# ---------------------------------------------------------------------- outlines [m]
def test_personal_space_contour_is_the_metric_level_set():
    """At every contour point the m_psi kernel (paper semantics) reads the contour level."""
    xy = np.array([[1.0, 2.0], [-3.0, 0.5], [0.0, 0.0]])
    yaw = np.array([0.7, -2.5, math.pi])
    velocity = np.array([[0.8, 0.6], [0.0, 0.0], [-0.2, 0.1]])
    contours = personal_space_contours(xy, yaw, velocity, level=0.5, n=36)
    assert contours.shape == (3, 36, 2)
    n = contours.shape[1]
    for p in range(3):
        rx, ry = contours[p, :, 0].copy(), contours[p, :, 1].copy()
        psi, dirv = np.empty(n), np.empty(n)
        rep = np.ones(n)
        zeros = np.zeros(n)
        kernels.person_terms(
            rx, ry, zeros, zeros, np.arange(n), xy[p, 0] * rep, xy[p, 1] * rep, yaw[p] * rep,
            velocity[p, 0] * rep, velocity[p, 1] * rep, zeros, zeros, zeros, zeros,
            3.3, 0.5, 0.275, 0.28, False, psi, dirv,
        )  # fmt: skip
        np.testing.assert_allclose(psi, 0.5, atol=1e-9)


def test_personal_space_is_longer_in_front():
    contour = personal_space_contours(np.zeros((1, 2)), np.zeros(1), np.zeros((1, 2)), n=4)[0]
    # points at phi = -pi, -pi/2, 0, pi/2: behind, right, ahead, left
    k = 2.0 * math.log(2.0)
    np.testing.assert_allclose(contour[2], [math.sqrt(k * 0.5), 0.0], atol=1e-12)
    np.testing.assert_allclose(contour[0], [-math.sqrt(k * 0.25), 0.0], atol=1e-12)
    np.testing.assert_allclose(abs(contour[1, 1]), math.sqrt(k / 3.0), atol=1e-12)


def test_covariance_ellipse_is_at_sigma():
    rng = np.random.default_rng(1)
    m = rng.normal(size=(5, 2, 2))
    cov = m @ m.transpose(0, 2, 1) + 0.01 * np.eye(2)
    xy = rng.normal(size=(5, 2))
    pts = covariance_ellipses(xy, cov, sigma=2.0, n=16)
    d = pts - xy[:, None, :]
    maha = np.einsum("kni,kij,knj->kn", d, np.linalg.inv(cov), d)
    np.testing.assert_allclose(maha, 4.0, rtol=1e-9)


def test_formation_ellipses_follow_the_members():
    sim = _scenario("fformation")
    ellipses = formation_ellipses(sim.crowd)
    assert ellipses.shape == (len(sim.crowd.formation_members), 5)
    for members, (cx, cy, a, b, _) in zip(sim.crowd.formation_members, ellipses):
        np.testing.assert_allclose([cx, cy], sim.crowd.position[members].mean(axis=0))
        assert a > 0 and b > 0


# ---------------------------------------------------------------------- scene [px]
def test_person_drawn_where_it_is_with_its_space_ahead():
    person = PersonLayout((5.0, 3.5), 0.0, ((7.0, 3.5),), radius=0.3)
    sim = _box(people=[person])
    scene = scene_primitives(sim)
    view = scene.view
    x, y = sim.crowd.position[0]
    expected = (view.left + (x - 0.0) * view.scale, view.top + (6.0 - y) * view.scale)
    np.testing.assert_allclose(scene.people.center[0], expected, atol=0.5)
    assert scene.people.radius[0] == round(0.3 * view.scale)
    nose = scene.people.nose[0] - scene.people.center[0]
    assert nose[0] > 0 and abs(nose[1]) <= 1  # facing +x: the heading line points right
    contour = scene.personal_space[0] - scene.people.center[0]
    assert contour.shape == (40, 2)
    ahead, behind = contour[:, 0].max(), -contour[:, 0].min()
    assert ahead > 1.3 * behind  # farther ahead than behind (sqrt 2 for a standing person)


def test_robot_size_is_the_configured_one():
    for radius in (0.2, 0.45):
        sim = _box(radius=radius)
        scene = scene_primitives(sim)
        assert scene.robots.body.radius.tolist() == [round(radius * scene.view.scale)]
        np.testing.assert_array_equal(scene.robots.body.center[0], scene.view.px([2.0, 1.0]))


def test_goal_tolerance_is_the_given_one():
    sim = _box(tolerance=0.3)
    scale = scene_primitives(sim).view.scale
    assert scene_primitives(sim).robots.goals.radius.tolist() == [round(0.3 * scale)]
    assert scene_primitives(sim, goal_tolerance=0.5).robots.goals.radius.tolist() == [
        round(0.5 * scale)
    ]


def test_every_robot_has_its_colour_and_goal():
    n = 4
    sim = _box(robots=n)
    scene = scene_primitives(sim, robot=2)
    robots = scene.robots
    assert robots.highlight == 2 and robots.order[-1] == 2 and sorted(robots.order) == [0, 1, 2, 3]
    assert len({c.fill for c in robots.colors}) == n  # one colour each
    assert len({c.goal for c in robots.colors}) == n
    assert robots.colors[0].fill == ROBOT_PALETTE[0][0]
    assert robots.body.center.shape == (n, 2) and robots.goals.center.shape == (n, 2)
    for i in range(n):
        np.testing.assert_array_equal(robots.goals.center[i], scene.view.px([6.0, 1.0 + i]))
        np.testing.assert_array_equal(robots.body.center[i], scene.view.px([2.0, 1.0 + i]))
    # goal heading lines point along each goal's yaw (0.5 i rad): right and, from 1 on, up
    direction = robots.goals.tip - robots.goals.center
    assert (direction[:, 0] > 0).all() and direction[0, 1] == 0 and (direction[1:, 1] < 0).all()
    assert robot_colors(len(ROBOT_PALETTE)) == robot_colors(0)  # the palette repeats


def test_scene_of_a_crowd():
    sim = _scenario("fformation", steps=10)
    scene = scene_primitives(sim)
    assert isinstance(scene, Scene)
    assert scene.walls.shape == (sim.walls.shape[0], 2, 2)
    assert scene.formations.shape[0] == len(sim.crowd.formation_members)
    assert scene.personal_space.shape[0] == scene.people.center.shape[0] == sim.n_people
    assert scene.trail.shape == (sim.robots[0].record.n_samples, 2)
    assert scene.lidar.shape[0] > 0 and scene.lidar.dtype == np.int64
    tracks = sim.robots[0].tracker.tracks()
    assert scene.tracks.ids.tolist() == tracks.ids.tolist()
    assert scene.tracks.outline.shape[:1] == scene.tracks.center.shape[:1] == tracks.ids.shape
    with pytest.raises(IndexError):
        scene_primitives(sim, robot=1)


def test_empty_room_scene():
    scene = scene_primitives(_box())
    assert scene.people.center.shape == (0, 2) and scene.personal_space.shape[0] == 0
    assert scene.formations.shape[0] == 0 and scene.tracks.ids.shape == (0,)
    assert scene.trail.shape == (0, 2)  # one sample so far: no trail yet


def test_panel_layout():
    sim = _box(robots=2)
    values = panel_values(sim, 1, {"m_psi": 12.345, "t": 9.0, "big": 12345.0})
    assert values == [("t", "0.0 s"), ("robot", "2 / 2"), ("m_psi", "12.35"), ("big", "1.234e+04")]
    side = panel_layout((530, 0, 190, 540), values)
    assert [r.name for r in side] == [v[0] for v in values] + [e[0] for e in LEGEND]
    assert {r.x for r in side} == {542} and [r.y for r in side[:2]] == [10, 10 + ROW]
    below = panel_layout((0, 422, 720, 118), values)
    legend = below[len(values) :]
    assert legend[0].x == 12 + COLUMN and legend[0].y == 432  # a column of its own
    assert all(422 <= r.y <= 540 - ROW for r in below)


def test_scene_needs_no_pygame():
    code = (
        "import sys, numpy as np; from srpb_gym.render import scene_primitives; "
        "from srpb_gym.scenarios import load_scenario, sample; "
        "from srpb_gym.simulation import Simulation; s = load_scenario('crowd'); "
        "sim = Simulation.from_scenario(s); g = np.random.default_rng(0); "
        "sim.reset(sample(s, g), g); scene_primitives(sim); print('pygame' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
