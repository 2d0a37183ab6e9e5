"""The pygame layer: draws a :class:`~srpb_gym.render.scene.Scene` and the panel, off-screen
(``rgb_array``) or into a window (``human``). pygame is imported when a :class:`Renderer`
is built, never with the package."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium.error import DependencyNotInstalled
from numpy.typing import NDArray

from srpb_gym.metrics.params import MetricParams
from srpb_gym.render.geometry import View, fit_view, grid_lines
from srpb_gym.render.scene import (
    Discs,
    Scene,
    panel_layout,
    panel_values,
    scene_primitives,
)
from srpb_gym.render.style import (
    BACKGROUND,
    BOTTOM_STRIP,
    COLUMN,
    GRID,
    HALO,
    LIDAR,
    MUTED,
    OSPACE_EDGE,
    OSPACE_FILL,
    PANEL,
    PERSON,
    PERSON_EDGE,
    PERSONAL_SPACE,
    SIDE_STRIP,
    TEXT,
    TRACK,
    TRAIL,
    WALL,
    Color,
)

if TYPE_CHECKING:
    from srpb_gym.simulation import Simulation

INSTALL_HINT = 'pip install "pygame-ce>=2.5"'
RENDER_MODES: tuple[str, ...] = ("rgb_array", "human")


class RenderDependencyError(DependencyNotInstalled, ImportError):
    """pygame (pygame-ce, a dependency of srpb-gym) cannot be imported; the message says
    what to install."""


def import_pygame(headless: bool) -> Any:
    """pygame, imported now; ``headless`` picks SDL's dummy video driver on Linux when
    there is no display and ``SDL_VIDEODRIVER`` is unset."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    no_display = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if headless and sys.platform.startswith("linux") and no_display:
        os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    try:
        import pygame
    except ImportError as err:
        raise RenderDependencyError(f"rendering needs pygame-ce: {INSTALL_HINT}") from err
    return pygame


class Renderer:
    """Draws a :class:`~srpb_gym.simulation.Simulation` top-down with pygame.

    ``render_mode`` "rgb_array": :meth:`render` returns a fresh (height, width, 3) uint8
    array, drawn off-screen (no window, no display needed). "human": :meth:`render` draws
    into a window at most ``fps`` times per second and returns ``None``; closing the window
    stops the drawing (``window_closed`` becomes true). ``width`` and ``height`` in px.
    Raises :class:`RenderDependencyError` (an ``ImportError``) if pygame cannot be imported.
    """

    def __init__(
        self, render_mode: str, width: int = 720, height: int = 540, fps: int = 10
    ) -> None:
        if render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES}, got {render_mode!r}")
        if width < 2 * SIDE_STRIP or height < 2 * BOTTOM_STRIP:
            raise ValueError(f"{width}x{height} px is too small to render into")
        self.render_mode, self.width, self.height, self.fps = render_mode, width, height, fps
        self._pg = pg = import_pygame(headless=render_mode == "rgb_array")
        # pygame-ce's anti-aliased circle; plain pygame (same module name) has none
        self._aacircle = getattr(pg.draw, "aacircle", pg.draw.circle)
        pg.font.init()
        self._font = pg.font.Font(None, 22)
        self._small = pg.font.Font(None, 16)
        self._canvas = pg.Surface((width, height), depth=32)
        self._background: Any = None
        self._background_key: tuple | None = None
        self._view: View | None = None
        self._labels: dict[Any, Any] = {}
        self._window: Any = None
        self._clock: Any = None
        self.window_closed = False

    # ------------------------------------------------------------------ public
    def world_to_pixel(self, x: float, y: float) -> tuple[int, int]:
        """Pixel (column, row) of world point (x, y) [m] in the last rendered frame."""
        if self._view is None:
            raise RuntimeError("world_to_pixel needs a rendered frame (call render first)")
        px, py = self._view.px(np.array([x, y]))
        return int(px), int(py)

    def scene(
        self,
        sim: Simulation,
        robot: int = 0,
        goal_tolerance: float | Sequence[float] | None = None,
        params: MetricParams | None = None,
    ) -> Scene:
        """What :meth:`render` would draw now, in this renderer's pixels (see
        :func:`~srpb_gym.render.scene.scene_primitives`)."""
        view = fit_view(sim.layout.bounds, self.width, self.height)
        return scene_primitives(sim, robot, view, goal_tolerance, params)

    def render(
        self,
        sim: Simulation,
        robot: int = 0,
        panel: Mapping[str, float] | None = None,
        goal_tolerance: float | Sequence[float] | None = None,
    ) -> NDArray[np.uint8] | None:
        """Draw the current state of ``sim`` seen by robot ``robot`` (highlighted; its
        trail, lidar hits and tracks are shown). ``panel``: named values listed beside the
        time (e.g. running ``m_psi``, ``m_fsi``, ``m_dir``). ``goal_tolerance`` [m], one or
        one per robot: the goal circles' radius (default: the layout's)."""
        if self.render_mode == "human" and self.window_closed:
            return None
        if not 0 <= robot < sim.n_robots:
            raise IndexError(f"robot {robot} out of range for {sim.n_robots} robots")
        self._prepare_background(sim)
        scene = scene_primitives(sim, robot, self._view, goal_tolerance)
        self._draw_world(scene)
        self._draw_panel(panel_values(sim, robot, panel))
        if self.render_mode == "rgb_array":
            return _surface_rgb(self._canvas)
        self._show()
        return None

    def close(self) -> None:
        """Close the window (if any); the renderer can still draw off-screen afterwards."""
        if self._window is not None:
            self._pg.display.quit()
            self._window = None

    # ------------------------------------------------------------------ frame
    def _prepare_background(self, sim: Simulation) -> None:
        """The view and the static layer (grid, panel area), rebuilt when the layout changes."""
        bounds = tuple(float(b) for b in sim.layout.bounds)
        key = (bounds, self.width, self.height)
        if key == self._background_key:
            return
        self._view = view = fit_view(bounds, self.width, self.height)
        pg = self._pg
        bg = pg.Surface((self.width, self.height))
        bg.fill(BACKGROUND)
        for a, b in grid_lines(view, bounds).tolist():
            pg.draw.line(bg, GRID, a, b)
        bg.fill(PANEL, pg.Rect(view.panel))
        self._background, self._background_key = bg, key

    def _draw_world(self, scene: Scene) -> None:
        pg, canvas = self._pg, self._canvas
        canvas.blit(self._background, (0, 0))
        canvas.set_clip(pg.Rect(scene.view.world))
        for pts in scene.formations.tolist():
            pg.draw.polygon(canvas, OSPACE_FILL, pts)
        self._lines(OSPACE_EDGE, scene.formations)
        self._lines(PERSONAL_SPACE, scene.personal_space)
        self._draw_walls(scene.walls, scene.wall_width)
        if scene.trail.shape[0] >= 2:
            pg.draw.lines(canvas, TRAIL, False, scene.trail.tolist(), 3)
        self._draw_goals(scene)
        for p in scene.lidar.tolist():
            pg.draw.circle(canvas, LIDAR, p, 2)
        self._bodies(scene.people, range(scene.people.radius.shape[0]), PERSON, PERSON_EDGE, 2)
        self._draw_tracks(scene)
        self._draw_robots(scene)
        canvas.set_clip(None)

    # ------------------------------------------------------------------ world layers
    def _lines(self, color: Color, polylines: NDArray[np.int64]) -> None:
        """Anti-aliased closed outlines of (N, M, 2) pixel polylines."""
        aalines = self._pg.draw.aalines
        for pts in polylines.tolist():
            aalines(self._canvas, color, True, pts)

    def _draw_walls(self, walls: NDArray[np.int64], width: int) -> None:
        line, circle, canvas = self._pg.draw.line, self._pg.draw.circle, self._canvas
        for a, b in walls.tolist():
            line(canvas, WALL, a, b, width)
            circle(canvas, WALL, a, width // 2)
            circle(canvas, WALL, b, width // 2)

    def _draw_goals(self, scene: Scene) -> None:
        """Every robot's goal in its colour: tolerance circle, heading line and cross; the
        highlighted robot's (drawn last) with its tolerance disc filled."""
        pg, canvas, robots = self._pg, self._canvas, scene.robots
        goals = robots.goals
        center, tip = goals.center.tolist(), goals.tip.tolist()
        for i in robots.order:
            color, r = robots.colors[i].goal, int(goals.radius[i])
            if i == robots.highlight:
                pg.draw.circle(canvas, robots.colors[i].goal_fill, center[i], r)
            pg.draw.circle(canvas, color, center[i], r, 2)
            pg.draw.line(canvas, color, center[i], tip[i], 2)
            self._cross(center[i], int(goals.arm[i]), color, 2)

    def _draw_tracks(self, scene: Scene) -> None:
        tracks, arm = scene.tracks, 4
        self._lines(TRACK, tracks.outline)
        for tid, (cx, cy) in zip(tracks.ids.tolist(), tracks.center.tolist()):
            self._cross((cx, cy), arm + 1, HALO, 4)
            self._cross((cx, cy), arm, TRACK, 2)
            label = self._cached(("id", tid), lambda t=tid: self._haloed(str(t), TRACK))
            self._canvas.blit(label, (cx + arm + 2, cy - arm - 12))

    def _draw_robots(self, scene: Scene) -> None:
        """Every robot in its own colour, the highlighted one on top and, when there are
        several, ringed."""
        robots = scene.robots
        for i in robots.order:
            colors = robots.colors[i]
            self._bodies(robots.body, [i], colors.fill, colors.edge, 3)
        if len(robots.colors) > 1:
            i = robots.highlight
            center, r = robots.body.center[i].tolist(), int(robots.body.radius[i])
            self._aacircle(self._canvas, robots.colors[i].edge, center, r + 5, 2)

    def _bodies(self, discs: Discs, which: Any, fill: Color, edge: Color, width: int) -> None:
        """Filled discs ``which`` with an outline and a heading line ``width`` px wide."""
        pg, canvas = self._pg, self._canvas
        center, tail, nose = discs.center.tolist(), discs.tail.tolist(), discs.nose.tolist()
        for i in which:
            r = int(discs.radius[i])
            pg.draw.circle(canvas, fill, center[i], r)
            self._aacircle(canvas, edge, center[i], r, 2)
            pg.draw.line(canvas, edge, tail[i], nose[i], width)

    def _cross(self, center: Sequence[int], arm: int, color: Color, width: int = 1) -> None:
        (cx, cy), line = center, self._pg.draw.line
        line(self._canvas, color, (cx - arm, cy - arm), (cx + arm, cy + arm), width)
        line(self._canvas, color, (cx - arm, cy + arm), (cx + arm, cy - arm), width)

    def _cached(self, key: Any, make: Callable[[], Any]) -> Any:
        """A text surface made once (legend labels, names, track ids)."""
        if key not in self._labels:
            if len(self._labels) > 1024:
                self._labels.clear()
            self._labels[key] = make()
        return self._labels[key]

    def _haloed(self, text: str, color: Color) -> Any:
        """Small text with a light outline, readable on any layer."""
        pg = self._pg
        halo = self._small.render(text, True, HALO)
        out = pg.Surface((halo.get_width() + 2, halo.get_height() + 2), pg.SRCALPHA)
        for dx, dy in ((0, 1), (2, 1), (1, 0), (1, 2)):
            out.blit(halo, (dx, dy))
        out.blit(self._small.render(text, True, color), (1, 1))
        return out

    # ------------------------------------------------------------------ panel
    def _draw_panel(self, values: Sequence[tuple[str, str]]) -> None:
        """The values, then the legend, in the panel area."""
        canvas, font = self._canvas, self._font
        canvas.set_clip(self._pg.Rect(self._view.panel))
        for row in panel_layout(self._view.panel, values):
            x, y = row.x, row.y
            if row.icon is not None:
                self._icon(row.icon, x + 8, y + 7)
                canvas.blit(self._name(row.name, MUTED), (x + 24, y))
                continue
            if row.name:
                canvas.blit(self._name(row.name, TEXT), (x, y))
            if row.value:
                text = font.render(row.value, True, TEXT)  # changes every frame: not cached
                canvas.blit(text, (x + COLUMN - 24 - text.get_width(), y))
        canvas.set_clip(None)

    def _name(self, text: str, color: Color) -> Any:
        return self._cached((text, color), lambda: self._font.render(text, True, color))

    def _icon(self, icon: tuple[str, Color, Color | None], x: int, y: int) -> None:
        """A legend symbol centred at (x, y) [px]."""
        pg, canvas = self._pg, self._canvas
        kind, color, fill = icon
        if kind == "disc":
            pg.draw.circle(canvas, fill, (x, y), 6)
            self._aacircle(canvas, color, (x, y), 6, 2)
        elif kind == "ring":
            if fill is not None:
                pg.draw.ellipse(canvas, fill, (x - 8, y - 5, 16, 10))
            pg.draw.ellipse(canvas, color, (x - 8, y - 5, 16, 10), 1)
        elif kind == "cross":
            self._cross((x, y), 4, color, 2)
        elif kind == "dot":
            pg.draw.circle(canvas, color, (x, y), 2)
        else:
            pg.draw.line(canvas, color, (x - 8, y), (x + 8, y))

    # ------------------------------------------------------------------ window
    def _show(self) -> None:
        pg = self._pg
        if self._window is None:
            pg.display.init()
            self._window = pg.display.set_mode((self.width, self.height))
            pg.display.set_caption("srpb-gym")
            self._clock = pg.time.Clock()
        for event in pg.event.get():
            if event.type == pg.QUIT:
                self.window_closed = True
                self.close()
                return
        self._window.blit(self._canvas, (0, 0))
        pg.display.flip()
        self._clock.tick(self.fps)


def _surface_rgb(surface: Any) -> NDArray[np.uint8]:
    """A new C-ordered (height, width, 3) uint8 copy of a 32-bit ``surface``'s pixels."""
    w, h = surface.get_size()
    buffer = surface.get_buffer()
    rows = np.frombuffer(buffer, np.uint8).reshape(h, surface.get_pitch())
    pixels = rows[:, : 4 * w].reshape(h, w, 4)
    frame = np.empty((h, w, 3), dtype=np.uint8)
    for c, shift in enumerate(surface.get_shifts()[:3]):
        byte = shift // 8 if sys.byteorder == "little" else 3 - shift // 8
        frame[:, :, c] = pixels[:, :, byte]
    del pixels, rows, buffer  # unlocks the surface
    return frame
