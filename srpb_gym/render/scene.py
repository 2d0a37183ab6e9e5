"""What a frame shows, in pixels: a :class:`Scene` computed from a simulation, no pygame.

:func:`scene_primitives` turns the state of a :class:`~srpb_gym.simulation.Simulation`
into plain numpy arrays of pixel coordinates (walls, O-spaces, personal-space contours,
people, the chosen robot's trail, lidar hits and tracks, every robot and goal with its own
colour); :func:`panel_layout` places the panel's rows. The pygame layer only draws them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from srpb_gym.metrics.params import MetricParams
from srpb_gym.render.geometry import (
    Rect,
    View,
    covariance_ellipses,
    ellipse_points,
    fit_view,
    formation_ellipses,
    personal_space_contours,
)
from srpb_gym.render.style import COLUMN, LEGEND, ROW, Color, RobotColors, robot_colors

if TYPE_CHECKING:
    from srpb_gym.simulation import Simulation

Pixels = NDArray[np.int64]

WIDTH, HEIGHT = 720, 540  # px, the default frame
PERSON_NOSE = 1.55  # heading line tip, in body radii from the centre
ROBOT_NOSE = 1.6
ROBOT_NOSE_FROM = 0.4  # the robot's heading line starts this far out (fraction of the tip)
GOAL_ARROW = 0.3  # m, the goal's heading line reaches this far beyond its tolerance circle


@dataclass(frozen=True)
class Discs:
    """Circular bodies [px]: centres (N, 2), radii (N,), heading lines ``tail`` -> ``nose``
    (N, 2) each."""

    center: Pixels
    radius: Pixels
    tail: Pixels
    nose: Pixels


@dataclass(frozen=True)
class Goals:
    """Goal markers [px], one per robot: centre (R, 2), tolerance circle radius (R,), tip of
    the goal heading line (R, 2), half-size of the centre cross (R,)."""

    center: Pixels
    radius: Pixels
    tip: Pixels
    arm: Pixels


@dataclass(frozen=True)
class Robots:
    """Every robot in index order: its body, its colours and its goal. ``highlight`` is the
    robot whose view is shown (trail, lidar, tracks, panel); ``order`` draws it last."""

    body: Discs
    goals: Goals
    colors: tuple[RobotColors, ...]
    highlight: int

    @property
    def order(self) -> tuple[int, ...]:
        """Robot indices in drawing order: the others by index, then the highlighted one."""
        n = len(self.colors)
        return (*(i for i in range(n) if i != self.highlight), self.highlight)


@dataclass(frozen=True)
class Tracks:
    """The highlighted robot's tracks: ids (K,), centres (K, 2) [px] and 2-sigma position
    covariance outlines (K, n, 2) [px]."""

    ids: NDArray[np.int64]
    center: Pixels
    outline: Pixels


@dataclass(frozen=True)
class Scene:
    """One frame's world layer in pixel coordinates of ``view``; polylines are (N, M, 2)."""

    view: View
    walls: Pixels  # (S, 2, 2) segment end points
    wall_width: int  # px
    formations: Pixels  # (F, n, 2) O-space outlines (filled)
    personal_space: Pixels  # (P, n, 2) closed contours
    people: Discs
    trail: Pixels  # (T, 2) the highlighted robot's path so far
    lidar: Pixels  # (L, 2) the highlighted robot's lidar hit points
    tracks: Tracks
    robots: Robots


def scene_primitives(
    sim: Simulation,
    robot: int = 0,
    view: View | None = None,
    goal_tolerance: float | Sequence[float] | None = None,
    params: MetricParams | None = None,
) -> Scene:
    """The current state of ``sim`` as seen by robot ``robot``, in pixels of ``view``
    (default: the layout's bounds fitted to a 720 x 540 px frame).

    Robot sizes are ``sim.robot_config.radius``; ``goal_tolerance`` [m], one for all robots
    or one per robot, defaults to the layout's; ``params`` gives the personal-space level
    and the O-space fit (default :class:`~srpb_gym.metrics.params.MetricParams`).
    """
    if not 0 <= robot < sim.n_robots:
        raise IndexError(f"robot {robot} out of range for {sim.n_robots} robots")
    view = view or fit_view(sim.layout.bounds, WIDTH, HEIGHT)
    params = params or MetricParams()
    crowd, state = sim.crowd, sim.robots[robot]
    if crowd.formation_members:
        formations = view.px(ellipse_points(formation_ellipses(crowd, params)))
    else:
        formations = _none(0, 48, 2)
    contours = personal_space_contours(
        crowd.position, crowd.yaw, crowd.velocity, params.personal_space_threshold
    )
    return Scene(
        view=view,
        walls=view.px(sim.walls.reshape(-1, 2, 2)),
        wall_width=max(3, round(0.06 * view.scale)),
        formations=formations,
        personal_space=view.px(contours),
        people=_discs(view, crowd.position, crowd.yaw, crowd.radius, PERSON_NOSE, 0.0, 2),
        trail=_trail(view, state.record),
        lidar=_lidar(view, sim, robot),
        tracks=_tracks(view, state.tracker.tracks()),
        robots=_robots(view, sim, robot, goal_tolerance),
    )


def _none(*shape: int) -> Pixels:
    return np.zeros(shape, dtype=np.int64)


def _discs(
    view: View,
    xy: ArrayLike,
    yaw: ArrayLike,
    radius: ArrayLike,
    nose: float,
    tail: float,
    minimum: int,
) -> Discs:
    """Bodies of ``radius`` [m] (at least ``minimum`` px) at ``xy`` [m] facing ``yaw``
    [rad]; the heading line ends ``nose`` radii ahead of the centre and starts ``tail`` of
    the way from the centre to that end."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    yaw = np.asarray(yaw, dtype=np.float64).reshape(-1)
    r = np.broadcast_to(np.asarray(radius, dtype=np.float64), yaw.shape)
    heading = np.column_stack((np.cos(yaw), np.sin(yaw)))
    center = view.px(xy)
    tip = view.px(xy + nose * r[:, None] * heading)
    start = np.rint(center + tail * (tip - center)).astype(np.int64)
    return Discs(center, view.length(r, minimum), start, tip)


def _trail(view: View, record: Any) -> Pixels:
    if record.n_samples < 2:
        return _none(0, 2)
    xy = np.column_stack((record.robot_col("x"), record.robot_col("y")))
    return view.px(xy)


def _lidar(view: View, sim: Simulation, robot: int) -> Pixels:
    state = sim.robots[robot]
    if state.scan.size == 0:
        return _none(0, 2)
    x, y, yaw = (float(v) for v in sim.world.robot_pose[robot])
    hits = state.scan < state.lidar.config.range_max
    return view.px(state.lidar.hit_points(x, y, yaw, state.scan)[hits].reshape(-1, 2))


def _tracks(view: View, tracks: Any) -> Tracks:
    ids = np.asarray(tracks.ids, dtype=np.int64)
    if ids.shape[0] == 0:
        return Tracks(ids, _none(0, 2), _none(0, 24, 2))
    outline = covariance_ellipses(tracks.xy, tracks.covariance)
    return Tracks(ids, view.px(tracks.xy), view.px(outline))


def _robots(
    view: View, sim: Simulation, robot: int, goal_tolerance: float | Sequence[float] | None
) -> Robots:
    n, pose = sim.n_robots, sim.world.robot_pose
    body = _discs(
        view, pose[:, :2], pose[:, 2], sim.robot_config.radius, ROBOT_NOSE, ROBOT_NOSE_FROM, 3
    )
    if goal_tolerance is None:
        goal_tolerance = sim.layout.goal_tolerance
    tolerance = np.broadcast_to(np.asarray(goal_tolerance, dtype=np.float64), (n,))
    goals = np.array([state.goal[:3] for state in sim.robots], dtype=np.float64).reshape(n, 3)
    heading = np.column_stack((np.cos(goals[:, 2]), np.sin(goals[:, 2])))
    tip = goals[:, :2] + (tolerance + GOAL_ARROW)[:, None] * heading
    radius = view.length(tolerance, 2)
    marks = Goals(view.px(goals[:, :2]), radius, view.px(tip), np.maximum(radius // 2, 5))
    return Robots(body, marks, tuple(robot_colors(i) for i in range(n)), robot)


# ---------------------------------------------------------------------- panel
@dataclass(frozen=True)
class PanelRow:
    """One panel line at (x, y) [px, top left]: a name and a value, or a legend entry
    (``icon``: symbol, colour, fill)."""

    x: int
    y: int
    name: str
    value: str = ""
    icon: tuple[str, Color, Color | None] | None = None


def panel_values(
    sim: Simulation, robot: int, panel: Mapping[str, float] | None = None
) -> list[tuple[str, str]]:
    """The panel's (name, text) pairs: the time [s], which robot when there are several,
    then ``panel``'s values (a key "t" is left out)."""
    values = [("t", f"{sim.t:.1f} s")]
    if sim.n_robots > 1:
        values.append(("robot", f"{robot + 1} / {sim.n_robots}"))
    values += [(str(k), format_value(v)) for k, v in (panel or {}).items() if k != "t"]
    return values


def panel_layout(
    rect: Rect,
    values: Sequence[tuple[str, str]],
    legend: Sequence[tuple[str, str, Color, Color | None]] = LEGEND,
) -> list[PanelRow]:
    """Rows of ``values`` then ``legend`` flowing down the panel ``rect`` in columns; in a
    strip below the world (wider than high) the legend starts a column of its own."""
    x0, y0, w, h = rect
    top, bottom = y0 + 10, y0 + h - 6
    x, y = x0 + 12, top
    rows = []
    for name, value in values:
        x, y = _flow(x, y, top, bottom)
        rows.append(PanelRow(x, y, name, value))
        y += ROW
    if w > h:
        x, y = x + COLUMN, top
    else:
        y += ROW // 2
    for name, symbol, color, fill in legend:
        x, y = _flow(x, y, top, bottom)
        rows.append(PanelRow(x, y, name, icon=(symbol, color, fill)))
        y += ROW
    return rows


def _flow(x: int, y: int, top: int, bottom: int) -> tuple[int, int]:
    """Where the next panel row goes: here, or at the top of the next column if full."""
    return (x + COLUMN, top) if y + ROW > bottom else (x, y)


def format_value(value: float) -> str:
    """A panel value: two decimals, or four significant digits from 1000 on."""
    v = float(value)
    if not math.isfinite(v):
        return str(v)
    return f"{v:.2f}" if abs(v) < 1000 else f"{v:.4g}"
