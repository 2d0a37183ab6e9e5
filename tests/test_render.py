"""The pygame renderer: off-screen frames, where things are drawn, the window, the import."""

from __future__ import annotations

import math
import re
import subprocess
import sys

import numpy as np
import pytest

from srpb_gym.render import INSTALL_HINT, ROBOT_COLOR, Renderer, robot_colors
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


def _two_robots() -> Simulation:
    walls = np.array([[0, 0, 8, 0], [8, 0, 8, 6], [8, 6, 0, 6], [0, 6, 0, 0]], dtype=float)
    robots = (
        RobotLayout((2.0, 2.0, 0.0), (6.0, 2.0, 0.0)),
        RobotLayout((2.0, 4.0, 0.0), (6.0, 4.0, 0.0)),
    )
    sim = Simulation()
    sim.reset(EpisodeLayout(walls, robots, bounds=(0, 0, 8, 6)), np.random.default_rng(0))
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


def test_frame_draws_the_scene(headless):
    """The pixels at the scene's primitives have the primitives' colours."""
    sim = _simulation("crowd", steps=5)
    renderer = Renderer("rgb_array", W, H)
    frame = renderer.render(sim)
    scene = renderer.scene(sim)
    cx, cy = scene.robots.body.center[0]
    r = int(scene.robots.body.radius[0])
    assert tuple(frame[cy, cx + r // 2]) == ROBOT_COLOR
    assert tuple(frame[cy, cx + r + 3]) != ROBOT_COLOR  # no bigger than its radius
    gx, gy = scene.robots.goals.center[0]
    assert tuple(frame[gy, gx]) == robot_colors(0).goal  # the goal cross


def test_y_up_and_equal_scale(headless):
    sim = _simulation("crowd")
    renderer = Renderer("rgb_array", W, H)
    renderer.render(sim)
    xmin, ymin, xmax, ymax = sim.layout.bounds
    (ax, ay), (bx, by) = renderer.world_to_pixel(xmin, ymin), renderer.world_to_pixel(xmax, ymax)
    assert bx > ax and by < ay  # x to the right, y up
    assert abs((bx - ax) / (xmax - xmin) - (ay - by) / (ymax - ymin)) < 0.1
    assert 0 <= ax < bx < W and 0 <= by < ay < H


def test_every_robot_in_its_colour_the_chosen_one_ringed(headless):
    sim = _two_robots()
    renderer = Renderer("rgb_array", W, H)
    ring = renderer.scene(sim).robots.body.radius[0] + 5
    for chosen, other in ((1, 0), (0, 1)):
        frame = renderer.render(sim, robot=chosen)
        for i, y in ((0, 2.0), (1, 4.0)):
            assert _pixel(frame, renderer, 2.0, y) == robot_colors(i).fill
            assert _pixel(frame, renderer, 6.0, y) == robot_colors(i).goal  # goal cross
        px, py = renderer.world_to_pixel(2.0, 2.0 + 2.0 * chosen)
        assert tuple(frame[py - ring, px]) == robot_colors(chosen).edge
        px, py = renderer.world_to_pixel(2.0, 2.0 + 2.0 * other)
        assert tuple(frame[py - ring, px]) != robot_colors(other).edge
    with pytest.raises(IndexError):
        renderer.render(sim, robot=2)


def test_goal_tolerance_as_given(headless):
    sim = _two_robots()
    renderer = Renderer("rgb_array", W, H)
    small = renderer.render(sim, 0, goal_tolerance=0.2)
    large = renderer.render(sim, 0, goal_tolerance=[0.6, 0.2])
    px, py = renderer.world_to_pixel(6.0, 2.0 + 0.4)  # inside 0.6 m only
    assert tuple(small[py, px]) != tuple(large[py, px]) == robot_colors(0).goal_fill


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


def test_plain_pygame_without_aacircle(headless, monkeypatch):
    """pygame (not -ce) installs the same module without draw.aacircle: still draws."""
    monkeypatch.delattr(headless.draw, "aacircle")
    sim = _simulation("crowd", steps=3)
    renderer = Renderer("rgb_array", W, H)
    frame = renderer.render(sim, 0, {"m_psi": 1.0})
    assert _pixel(frame, renderer, *sim.world.robot_pose[0, :2]) == ROBOT_COLOR


def test_world_to_pixel_needs_a_frame(headless):
    with pytest.raises(RuntimeError, match="render"):
        Renderer("rgb_array").world_to_pixel(0.0, 0.0)


def test_bad_mode_and_size():
    with pytest.raises(ValueError, match="render_mode"):
        Renderer("ansi")
    with pytest.raises(ValueError, match="too small"):
        Renderer("rgb_array", 200, 200)


def test_missing_pygame_says_what_to_install(monkeypatch):
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
