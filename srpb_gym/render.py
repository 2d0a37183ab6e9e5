"""A pygame renderer of a :class:`~srpb_gym.simulation.Simulation`, top-down.

Drawn for one chosen robot: walls, people with their heading and personal-space contour
(the ``personal_space_threshold`` level set of Kirby's asymmetric Gaussian used by
``m_psi``), the O-spaces of the F-formations (the ellipses ``m_fsi`` uses), the robot's
tracks with their 2-sigma position covariance and ids, its lidar hit points and
trajectory, every robot and goal (with its tolerance circle and heading), and a side or
bottom panel with the time and any values the caller passes (running SRPB metrics).

pygame (``pip install "srpb-gym[render]"``) is imported only when a :class:`Renderer` is
built, never with the package. The geometry helpers (:func:`personal_space_contours`,
:func:`ellipse_points`, :func:`covariance_ellipses`, :func:`formation_ellipses`) are plain
numpy and need no pygame.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from srpb_gym.metrics.episode import group_ellipses
from srpb_gym.metrics.params import MetricParams

if TYPE_CHECKING:
    from srpb_gym.simulation import Simulation

try:  # the error gymnasium users expect, and still an ImportError
    from gymnasium.error import DependencyNotInstalled as _GymMissing
except ImportError:  # pragma: no cover - gymnasium is a dependency
    _GymMissing = ImportError  # type: ignore[misc, assignment]

INSTALL_HINT = 'pip install "srpb-gym[render]"'
RENDER_MODES: tuple[str, ...] = ("rgb_array", "human")

Color = tuple[int, int, int]
BACKGROUND: Color = (250, 250, 247)
GRID: Color = (229, 229, 224)
WALL: Color = (70, 70, 72)
PERSON: Color = (72, 125, 200)
PERSON_EDGE: Color = (30, 60, 112)
PERSONAL_SPACE: Color = (146, 184, 234)
OSPACE_FILL: Color = (238, 228, 247)
OSPACE_EDGE: Color = (146, 92, 186)
TRACK: Color = (0, 150, 112)
HALO: Color = (255, 255, 255)
LIDAR: Color = (226, 52, 60)
ROBOT_COLOR: Color = (245, 134, 20)
ROBOT_EDGE: Color = (110, 55, 0)
OTHER_ROBOT: Color = (178, 178, 184)
TRAIL: Color = (246, 188, 128)
GOAL: Color = (38, 156, 62)
GOAL_FILL: Color = (214, 238, 216)
OTHER_GOAL: Color = (140, 160, 144)
PANEL: Color = (236, 238, 243)
TEXT: Color = (36, 38, 46)
MUTED: Color = (108, 110, 122)

MARGIN = 12  # px around the world
SIDE_STRIP = 190  # px, panel width when it sits on the right
BOTTOM_STRIP = 118  # px, panel height when it sits at the bottom
ROW = 21  # px, panel line height
COLUMN = 168  # px, panel column width
# panel legend: label, symbol, colour, fill
LEGEND: tuple[tuple[str, str, Color, Color | None], ...] = (
    ("robot", "disc", ROBOT_EDGE, ROBOT_COLOR),
    ("goal", "cross", GOAL, None),
    ("person", "disc", PERSON_EDGE, PERSON),
    ("personal space", "ring", PERSONAL_SPACE, None),
    ("O-space", "ring", OSPACE_EDGE, OSPACE_FILL),
    ("track (2 sigma)", "cross", TRACK, None),
    ("lidar hit", "dot", LIDAR, None),
    ("grid 1 m", "line", MUTED, None),
)


class RenderDependencyError(_GymMissing, ImportError):  # type: ignore[misc]
    """pygame is not installed; the message names the extra to install."""


def _import_pygame(headless: bool) -> Any:
    """pygame, imported now; ``headless`` picks SDL's dummy video driver if no display."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    no_display = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if headless and sys.platform.startswith("linux") and no_display:
        os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    try:
        import pygame
    except ImportError as err:
        raise RenderDependencyError(f"rendering needs pygame (pygame-ce): {INSTALL_HINT}") from err
    return pygame


# ---------------------------------------------------------------------- geometry (numpy)
def personal_space_contours(
    xy: NDArray[np.float64],
    yaw: NDArray[np.float64],
    velocity: NDArray[np.float64],
    level: float = 0.5,
    n: int = 40,
) -> NDArray[np.float64]:
    """(P, n, 2) closed contours where each person's personal-space Gaussian equals ``level``.

    The model of ``m_psi`` (:func:`srpb_gym.metrics.kernels.person_terms`, paper semantics,
    no tracking covariance): variance max(2 speed, 0.5) m^2 ahead, 2/3 of it sideways and
    half of it behind, rotated by the person's yaw. In the person's frame the level set is
    u^2 / var_head + w^2 / var_side = -2 ln(level): two half-ellipses joined at the sides.
    """
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    speed = np.hypot(*np.asarray(velocity, dtype=np.float64).reshape(-1, 2).T)
    var_front = np.maximum(2.0 * speed, 0.5)[:, None]
    phi = np.linspace(-math.pi, math.pi, n, endpoint=False)
    var_head = np.where(np.abs(phi) <= 0.5 * math.pi, var_front, 0.5 * var_front)
    k = -2.0 * math.log(level)
    u = np.sqrt(k * var_head) * np.cos(phi)
    w = np.sqrt(k * var_front * 2.0 / 3.0) * np.sin(phi)
    return _rotate_about(xy, np.asarray(yaw, dtype=np.float64).reshape(-1), u, w)


def ellipse_points(ellipses: NDArray[np.float64], n: int = 48) -> NDArray[np.float64]:
    """(G, n, 2) outline points of ellipses given as rows (cx, cy, a, b, theta)."""
    e = np.asarray(ellipses, dtype=np.float64).reshape(-1, 5)
    t = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    u = np.abs(e[:, 2:3]) * np.cos(t)
    w = np.abs(e[:, 3:4]) * np.sin(t)
    return _rotate_about(e[:, :2], e[:, 4], u, w)


def covariance_ellipses(
    xy: NDArray[np.float64], covariance: NDArray[np.float64], sigma: float = 2.0, n: int = 24
) -> NDArray[np.float64]:
    """(K, n, 2) ``sigma``-sigma ellipses of (K, 2, 2) position covariances around ``xy``."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    c = np.asarray(covariance, dtype=np.float64).reshape(-1, 2, 2)
    sxx, syy, sxy = c[:, 0, 0], c[:, 1, 1], 0.5 * (c[:, 0, 1] + c[:, 1, 0])
    # eigenvalues mid +- rad; the larger one along theta
    mid, rad = 0.5 * (sxx + syy), np.hypot(0.5 * (sxx - syy), sxy)
    theta = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    a, b = sigma * np.sqrt(np.maximum(mid + rad, 0.0)), sigma * np.sqrt(np.maximum(mid - rad, 0.0))
    return ellipse_points(np.column_stack((xy, a, b, theta)), n)


def formation_ellipses(
    crowd: Any, params: MetricParams | None = None, reference: bool = False
) -> NDArray[np.float64]:
    """(F, 5) O-space ellipse (cx, cy, a, b, theta) of every F-formation of ``crowd`` at its
    members' current positions, as the ``m_fsi`` metric fits it."""
    groups = [np.asarray(m, dtype=np.int64) for m in crowd.formation_members if len(m)]
    if not groups:
        return np.empty((0, 5))
    size = np.array([g.size for g in groups], dtype=np.int64)
    start = np.cumsum(size) - size
    members = np.concatenate(groups)
    px = np.ascontiguousarray(crowd.position[:, 0], dtype=np.float64)
    py = np.ascontiguousarray(crowd.position[:, 1], dtype=np.float64)
    params = params or MetricParams()
    ellipses, _ = group_ellipses(px, py, members, start, size, params, reference)
    return ellipses[np.isfinite(ellipses).all(axis=1)]


def _rotate_about(center, angle, u, w) -> NDArray[np.float64]:
    """Points (u, w) of each row's local frame, rotated by ``angle`` and moved to ``center``."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    out = np.empty((center.shape[0], np.shape(u)[-1], 2))
    out[:, :, 0] = center[:, 0:1] + c * u - s * w
    out[:, :, 1] = center[:, 1:2] + s * u + c * w
    return out


# ---------------------------------------------------------------------- layout
@dataclass(frozen=True)
class _View:
    """World-to-pixel transform and the screen areas of the world and the panel."""

    scale: float  # px per m
    left: float  # px of x = xmin
    top: float  # px of y = ymax
    xmin: float
    ymax: float
    world: tuple[int, int, int, int]  # x, y, w, h of the world's area
    panel: tuple[int, int, int, int]

    def px(self, xy: NDArray[np.float64]) -> NDArray[np.int64]:
        """Pixel coordinates of world points (..., 2)."""
        xy = np.asarray(xy, dtype=np.float64)
        u = self.left + (xy[..., 0] - self.xmin) * self.scale
        v = self.top + (self.ymax - xy[..., 1]) * self.scale
        return np.rint(np.stack((u, v), axis=-1)).astype(np.int64)


def _fit_view(bounds: tuple[float, ...], width: int, height: int) -> _View:
    """Equal-scale fit of ``bounds`` beside (or above) the panel, whichever is larger."""
    xmin, ymin, xmax, ymax = (float(b) for b in bounds)
    w, h = max(xmax - xmin, 1e-6), max(ymax - ymin, 1e-6)
    side = min((width - SIDE_STRIP - 2 * MARGIN) / w, (height - 2 * MARGIN) / h)
    below = min((width - 2 * MARGIN) / w, (height - BOTTOM_STRIP - 2 * MARGIN) / h)
    if side >= 0.9 * below:
        area, panel = (
            (0, 0, width - SIDE_STRIP, height),
            (width - SIDE_STRIP, 0, SIDE_STRIP, height),
        )
        scale = side
    else:
        area = (0, 0, width, height - BOTTOM_STRIP)
        panel, scale = (0, height - BOTTOM_STRIP, width, BOTTOM_STRIP), below
    scale = max(scale, 1e-3)
    left = area[0] + 0.5 * (area[2] - w * scale)
    top = area[1] + 0.5 * (area[3] - h * scale)
    return _View(scale, left, top, xmin, ymax, area, panel)


# ---------------------------------------------------------------------- renderer
class Renderer:
    """Draws a :class:`~srpb_gym.simulation.Simulation` with pygame.

    ``render_mode`` "rgb_array": :meth:`render` returns a fresh (height, width, 3) uint8
    array (off-screen; SDL's dummy video driver is chosen when there is no display and
    ``SDL_VIDEODRIVER`` is unset). "human": :meth:`render` draws into a window at most
    ``fps`` times per second and returns ``None``; closing the window stops the drawing
    (``window_closed`` becomes true). Raises :class:`RenderDependencyError` (an
    ``ImportError``) without pygame.
    """

    def __init__(
        self, render_mode: str, width: int = 720, height: int = 540, fps: int = 10
    ) -> None:
        if render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES}, got {render_mode!r}")
        if width < 2 * SIDE_STRIP or height < 2 * BOTTOM_STRIP:
            raise ValueError(f"{width}x{height} px is too small to render into")
        self.render_mode, self.width, self.height, self.fps = render_mode, width, height, fps
        self._pg = pg = _import_pygame(headless=render_mode == "rgb_array")
        pg.font.init()
        self._font = pg.font.Font(None, 22)
        self._small = pg.font.Font(None, 16)
        self._canvas = pg.Surface((width, height), depth=32)
        self._background: Any = None
        self._background_key: tuple | None = None
        self._view: _View | None = None
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

    def render(
        self, sim: Simulation, robot: int = 0, panel: Mapping[str, float] | None = None
    ) -> np.ndarray | None:
        """Draw the current state of ``sim`` seen by robot ``robot``; ``panel``: named values
        listed beside the time (e.g. running ``m_psi``, ``m_fsi``, ``m_dir``)."""
        if self.render_mode == "human" and self.window_closed:
            return None
        if not 0 <= robot < sim.n_robots:
            raise IndexError(f"robot {robot} out of range for {sim.n_robots} robots")
        self._draw_frame(sim, robot, panel or {})
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
    def _draw_frame(self, sim: Simulation, robot: int, panel: Mapping[str, float]) -> None:
        pg, canvas = self._pg, self._canvas
        self._prepare_background(sim)
        canvas.blit(self._background, (0, 0))
        canvas.set_clip(pg.Rect(self._view.world))
        state = sim.robots[robot]
        self._draw_formations(sim)
        self._draw_personal_space(sim)
        self._draw_walls(canvas, sim.walls)
        self._draw_trail(state.record)
        self._draw_goals(sim, robot)
        self._draw_lidar(sim, robot)
        self._draw_people(sim)
        self._draw_tracks(state.tracker.tracks())
        self._draw_robots(sim, robot)
        canvas.set_clip(None)
        self._draw_panel(sim, robot, panel)

    def _prepare_background(self, sim: Simulation) -> None:
        """The view and the static layer (grid, panel area), rebuilt when the layout changes."""
        bounds = tuple(float(b) for b in sim.layout.bounds)
        key = (bounds, self.width, self.height)
        if key == self._background_key:
            return
        self._view = view = _fit_view(bounds, self.width, self.height)
        bg = self._pg.Surface((self.width, self.height))
        bg.fill(BACKGROUND)
        xmin, ymin, xmax, ymax = bounds
        xs, ys = np.arange(math.ceil(xmin), xmax + 1e-9), np.arange(math.ceil(ymin), ymax + 1e-9)
        lines = [((x, ymin), (x, ymax)) for x in xs] + [((xmin, y), (xmax, y)) for y in ys]
        for a, b in view.px(np.array(lines).reshape(-1, 2, 2)).tolist():
            self._pg.draw.line(bg, GRID, a, b)
        bg.fill(PANEL, self._pg.Rect(view.panel))
        self._background, self._background_key = bg, key

    # ------------------------------------------------------------------ world layers
    def _lines(self, color: Color, polylines: NDArray[np.float64], closed: bool = True) -> None:
        """Anti-aliased outlines of (N, M, 2) world polylines."""
        aalines = self._pg.draw.aalines
        for pts in self._view.px(polylines).tolist():
            aalines(self._canvas, color, closed, pts)

    def _draw_walls(self, canvas: Any, walls: NDArray[np.float64]) -> None:
        width = max(3, round(0.06 * self._view.scale))
        for x0, y0, x1, y1 in self._view.px(walls.reshape(-1, 2, 2)).reshape(-1, 4).tolist():
            self._pg.draw.line(canvas, WALL, (x0, y0), (x1, y1), width)
            for p in ((x0, y0), (x1, y1)):
                self._pg.draw.circle(canvas, WALL, p, width // 2)

    def _draw_formations(self, sim: Simulation) -> None:
        if not sim.crowd.formation_members:
            return
        outlines = ellipse_points(formation_ellipses(sim.crowd))
        for pts in self._view.px(outlines).tolist():
            self._pg.draw.polygon(self._canvas, OSPACE_FILL, pts)
        self._lines(OSPACE_EDGE, outlines)

    def _draw_personal_space(self, sim: Simulation) -> None:
        crowd = sim.crowd
        if crowd.position.shape[0] == 0:
            return
        level = MetricParams().personal_space_threshold
        contours = personal_space_contours(crowd.position, crowd.yaw, crowd.velocity, level)
        self._lines(PERSONAL_SPACE, contours)

    def _draw_trail(self, record: Any) -> None:
        if record.n_samples < 2:
            return
        xy = np.column_stack((record.robot_col("x"), record.robot_col("y")))
        pts = self._view.px(xy).tolist()
        self._pg.draw.lines(self._canvas, TRAIL, False, pts, 3)

    def _draw_goals(self, sim: Simulation, robot: int) -> None:
        pg, view, canvas = self._pg, self._view, self._canvas
        tol = max(2, round(sim.layout.goal_tolerance * view.scale))
        goals = np.array([state.goal[:3] for state in sim.robots], dtype=np.float64)
        reach = sim.layout.goal_tolerance + 0.3
        tips = goals[:, :2] + reach * np.column_stack((np.cos(goals[:, 2]), np.sin(goals[:, 2])))
        order = [i for i in range(sim.n_robots) if i != robot] + [robot]
        for i, center, tip in zip(
            order, view.px(goals[order, :2]).tolist(), view.px(tips[order]).tolist()
        ):
            color = GOAL if i == robot else OTHER_GOAL
            if i == robot:
                pg.draw.circle(canvas, GOAL_FILL, center, tol)
            pg.draw.circle(canvas, color, center, tol, 2)
            pg.draw.line(canvas, color, center, tip, 2)
            self._cross(center, max(5, tol // 2), color, 2)

    def _draw_lidar(self, sim: Simulation, robot: int) -> None:
        state = sim.robots[robot]
        if state.scan.size == 0:
            return
        x, y, yaw = (float(v) for v in sim.world.robot_pose[robot])
        hits = state.scan < state.lidar.config.range_max
        pts = state.lidar.hit_points(x, y, yaw, state.scan)[hits]
        circle = self._pg.draw.circle
        for p in self._view.px(pts).tolist():
            circle(self._canvas, LIDAR, p, 2)

    def _draw_people(self, sim: Simulation) -> None:
        crowd, view = sim.crowd, self._view
        if crowd.position.shape[0] == 0:
            return
        radius = np.maximum(np.rint(crowd.radius * view.scale), 2).astype(int).tolist()
        center = view.px(crowd.position)
        nose = crowd.position + 1.55 * crowd.radius[:, None] * np.column_stack(
            (np.cos(crowd.yaw), np.sin(crowd.yaw))
        )
        self._bodies(center.tolist(), radius, view.px(nose).tolist(), PERSON, PERSON_EDGE)

    def _bodies(
        self, centers, radii, noses, fill: Color, edge: Color, start: float = 0.0, width: int = 2
    ) -> None:
        """Filled discs with an outline and a heading line from ``start`` of the way out."""
        pg, canvas = self._pg, self._canvas
        for (cx, cy), r, (nx, ny) in zip(centers, radii, noses):
            pg.draw.circle(canvas, fill, (cx, cy), r)
            pg.draw.aacircle(canvas, edge, (cx, cy), r, 2)
            sx, sy = cx + start * (nx - cx), cy + start * (ny - cy)
            pg.draw.line(canvas, edge, (round(sx), round(sy)), (nx, ny), width)

    def _draw_tracks(self, tracks: Any) -> None:
        if tracks.ids.shape[0] == 0:
            return
        self._lines(TRACK, covariance_ellipses(tracks.xy, tracks.covariance))
        arm = 4
        for tid, (cx, cy) in zip(tracks.ids.tolist(), self._view.px(tracks.xy).tolist()):
            self._cross((cx, cy), arm + 1, HALO, 4)
            self._cross((cx, cy), arm, TRACK, 2)
            label = self._cached(("id", tid), lambda t=tid: self._haloed(str(t), TRACK))
            self._canvas.blit(label, (cx + arm + 2, cy - arm - 12))

    def _draw_robots(self, sim: Simulation, robot: int) -> None:
        view, pose = self._view, sim.world.robot_pose
        r = max(3, round(sim.robot_config.radius * view.scale))
        heading = np.column_stack((np.cos(pose[:, 2]), np.sin(pose[:, 2])))
        noses = view.px(pose[:, :2] + 1.6 * sim.robot_config.radius * heading).tolist()
        centers = view.px(pose[:, :2]).tolist()
        order = [i for i in range(sim.n_robots) if i != robot] + [robot]
        for i in order:
            fill = ROBOT_COLOR if i == robot else OTHER_ROBOT
            self._bodies([centers[i]], [r], [noses[i]], fill, ROBOT_EDGE, start=0.4, width=3)

    def _cross(self, center, arm: int, color: Color, width: int = 1) -> None:
        (cx, cy), line = center, self._pg.draw.line
        line(self._canvas, color, (cx - arm, cy - arm), (cx + arm, cy + arm), width)
        line(self._canvas, color, (cx - arm, cy + arm), (cx + arm, cy - arm), width)

    def _cached(self, key: Any, make: Callable[[], Any]) -> Any:
        """A text surface made once (names, legend labels, track ids)."""
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
    def _draw_panel(self, sim: Simulation, robot: int, panel: Mapping[str, float]) -> None:
        """Time and ``panel`` values, then the legend (in its own columns below the world)."""
        x0, y0, w, h = self._view.panel
        self._canvas.set_clip(self._pg.Rect(x0, y0, w, h))
        values = [("t", f"{sim.t:.1f} s")]
        if sim.n_robots > 1:
            values.append(("robot", f"{robot + 1} / {sim.n_robots}"))
        values += [(str(k), _format(v)) for k, v in panel.items() if k != "t"]
        top, bottom = y0 + 10, y0 + h - 6
        x, y = x0 + 12, top
        for name, value in values:
            x, y = _flow(x, y, top, bottom)
            self._panel_row(x, y, name, value, None)
            y += ROW
        if w > h:  # a strip below the world: the legend starts a new column
            x, y = x + COLUMN, top
        else:
            y += ROW // 2
        for name, *icon in LEGEND:
            x, y = _flow(x, y, top, bottom)
            self._panel_row(x, y, name, "", icon)
            y += ROW
        self._canvas.set_clip(None)

    def _panel_row(self, x: int, y: int, name: str, value: str, icon) -> None:
        blit = self._canvas.blit
        if icon is not None:
            self._icon(icon[0], x + 8, y + 7, *icon[1:])
            blit(self._name(name, MUTED), (x + 24, y))
            return
        if name:
            blit(self._name(name, TEXT), (x, y))
        if value:
            text = self._font.render(value, True, TEXT)  # changes every frame: not cached
            blit(text, (x + COLUMN - 24 - text.get_width(), y))

    def _name(self, text: str, color: Color) -> Any:
        return self._cached((text, color), lambda: self._font.render(text, True, color))

    def _icon(self, kind: str, x: int, y: int, color: Color, fill: Color | None) -> None:
        """A legend symbol centred at (x, y)."""
        pg, canvas = self._pg, self._canvas
        if kind == "disc":
            pg.draw.circle(canvas, fill, (x, y), 6)
            pg.draw.aacircle(canvas, color, (x, y), 6, 2)
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


def _flow(x: int, y: int, top: int, bottom: int) -> tuple[int, int]:
    """Where the next panel row goes: here, or at the top of the next column if full."""
    return (x + COLUMN, top) if y + ROW > bottom else (x, y)


def _format(value: float) -> str:
    """A panel value: two decimals, or fewer digits for large numbers."""
    v = float(value)
    if not math.isfinite(v):
        return str(v)
    return f"{v:.2f}" if abs(v) < 1000 else f"{v:.4g}"
