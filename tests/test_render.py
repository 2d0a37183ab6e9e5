"""The pygame renderer: off-screen frames, where things are drawn, the window, the extra."""

from __future__ import annotations

import math
import re
import subprocess
import sys

import numpy as np
import pytest

from srpb_gym.metrics import kernels
from srpb_gym.render import (
    INSTALL_HINT,
    OTHER_ROBOT,
    ROBOT_COLOR,
    Renderer,
    covariance_ellipses,
    formation_ellipses,
    personal_space_contours,
)
from srpb_gym.scenarios import load_scenario, sample
from srpb_gym.sim.layout import EpisodeLayout, RobotLayout
from srpb_gym.simulation import Simulation

W, H = 720, 540


@pytest.fixture
def headless(monkeypatch):
    """SDL's dummy video driver, set before pygame is imported (or its display started)."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    monkeypatch.setenv("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    return pytest.importorskip("pygame")


def _simulation(name: str, steps: int = 0, seed: int = 0) -> Simulation:
    scenario = load_scenario(name)
    sim = Simulation.from_scenario(scenario)
    sim.reset(sample(scenario, np.random.default_rng(seed)), np.random.default_rng(seed))
    for _ in range(steps):
        sim.step([[0.4, 0.0, 0.1]], 0.0)
    return sim


def _pixel(frame: np.ndarray, renderer: Renderer, x: float, y: float) -> tuple[int, ...]:
    px, py = renderer.world_to_pixel(x, y)
    return tuple(int(c) for c in frame[py, px])


@pytest.mark.parametrize("name", ["crowd", "corridor"])
def test_rgb_array_frame(headless, name):
    sim = _simulation(name, steps=20)
    renderer = Renderer("rgb_array", W, H)
    frame = renderer.render(sim, 0, {"m_psi": 12.5, "m_fsi": 0.0, "m_dir": 3.25})
    assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
    assert frame.flags.c_contiguous
    colours = np.unique(frame.reshape(-1, 3), axis=0)
    assert len(colours) > 20  # walls, people, robot, text, ...
    again = renderer.render(sim)
    assert again is not frame and not np.shares_memory(again, frame)
    renderer.close()


@pytest.mark.parametrize("name", ["crowd", "corridor"])
def test_robot_drawn_where_it_is(headless, name):
    sim = _simulation(name)
    renderer = Renderer("rgb_array", W, H)
    x0, y0 = sim.world.robot_pose[0, :2].copy()
    first = renderer.render(sim)
    assert _pixel(first, renderer, x0, y0) == ROBOT_COLOR
    for _ in range(30):
        sim.step([[0.5, 0.0, 0.0]], 0.0)
    x1, y1 = sim.world.robot_pose[0, :2]
    assert math.hypot(x1 - x0, y1 - y0) > 2 * sim.robot_config.radius
    later = renderer.render(sim)
    assert renderer.world_to_pixel(x1, y1) != renderer.world_to_pixel(x0, y0)
    assert _pixel(later, renderer, x1, y1) == ROBOT_COLOR
    assert _pixel(later, renderer, x0, y0) != ROBOT_COLOR


def test_y_up_and_equal_scale(headless):
    sim = _simulation("crowd")
    renderer = Renderer("rgb_array", W, H)
    renderer.render(sim)
    xmin, ymin, xmax, ymax = sim.layout.bounds
    (ax, ay), (bx, by) = renderer.world_to_pixel(xmin, ymin), renderer.world_to_pixel(xmax, ymax)
    assert bx > ax and by < ay  # x to the right, y up
    assert abs((bx - ax) / (xmax - xmin) - (ay - by) / (ymax - ymin)) < 0.1
    assert 0 <= ax < bx < W and 0 <= by < ay < H


def test_chosen_robot_is_highlighted(headless):
    walls = np.array([[0, 0, 8, 0], [8, 0, 8, 6], [8, 6, 0, 6], [0, 6, 0, 0]], dtype=float)
    robots = (
        RobotLayout((2.0, 2.0, 0.0), (6.0, 2.0, 0.0)),
        RobotLayout((2.0, 4.0, 0.0), (6.0, 4.0, 0.0)),
    )
    sim = Simulation()
    sim.reset(EpisodeLayout(walls, robots, bounds=(0, 0, 8, 6)), np.random.default_rng(0))
    renderer = Renderer("rgb_array", W, H)
    frame = renderer.render(sim, robot=1)
    assert _pixel(frame, renderer, 2.0, 4.0) == ROBOT_COLOR
    assert _pixel(frame, renderer, 2.0, 2.0) == OTHER_ROBOT
    with pytest.raises(IndexError):
        renderer.render(sim, robot=2)


def test_panel_values_are_drawn(headless):
    sim = _simulation("crowd", steps=5)
    renderer = Renderer("rgb_array", W, H)
    plain = renderer.render(sim)
    with_panel = renderer.render(sim, 0, {"m_psi": 42.0, "m_fsi": 7.5})
    changed = np.argwhere((plain != with_panel).any(axis=2))
    assert changed.size
    # the values are written in the panel strip, outside the world's drawing area
    xmax_px, _ = renderer.world_to_pixel(sim.layout.bounds[2], 0.0)
    assert (changed[:, 1] > xmax_px).all()


def test_world_to_pixel_needs_a_frame(headless):
    with pytest.raises(RuntimeError, match="render"):
        Renderer("rgb_array").world_to_pixel(0.0, 0.0)


def test_bad_mode():
    with pytest.raises(ValueError, match="render_mode"):
        Renderer("ansi")


def test_missing_pygame_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "pygame", None)  # "import pygame" now fails
    with pytest.raises(ImportError, match=re.escape(INSTALL_HINT)) as info:
        Renderer("rgb_array")
    gym_error = pytest.importorskip("gymnasium.error")
    assert isinstance(info.value, gym_error.DependencyNotInstalled)


def test_human_mode_opens_and_closes(headless):
    pygame = headless
    sim = _simulation("crowd", steps=3)
    renderer = Renderer("human", W, H, fps=1000)
    assert renderer.render(sim, 0, {"m_psi": 1.0}) is None
    assert pygame.display.get_surface() is not None
    assert pygame.display.get_surface().get_size() == (W, H)
    assert renderer.render(sim) is None
    renderer.close()
    assert not pygame.display.get_init()
    renderer.close()  # twice is fine


def test_import_does_not_import_pygame():
    code = "import sys, srpb_gym, srpb_gym.render; print('pygame' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# ---------------------------------------------------------------------- geometry
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
    sim = _simulation("fformation")
    ellipses = formation_ellipses(sim.crowd)
    assert ellipses.shape == (len(sim.crowd.formation_members), 5)
    for members, (cx, cy, a, b, _) in zip(sim.crowd.formation_members, ellipses):
        np.testing.assert_allclose([cx, cy], sim.crowd.position[members].mean(axis=0))
        assert a > 0 and b > 0
