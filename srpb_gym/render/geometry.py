"""The renderer's geometry, plain numpy: outlines in the world [m] and the world-to-pixel view.

The outlines are those the SRPB metrics use: :func:`personal_space_contours` (the level set
of ``m_psi``'s asymmetric Gaussian), :func:`formation_ellipses` (the O-spaces ``m_fsi``
fits), and :func:`covariance_ellipses` of the tracks; :func:`ellipse_points` samples
ellipses. :func:`fit_view` places the world's bounds beside (or above) the panel at one
scale; :class:`View` maps world points to pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from srpb_gym.metrics.episode import group_ellipses
from srpb_gym.metrics.params import MetricParams
from srpb_gym.render.style import BOTTOM_STRIP, MARGIN, SIDE_STRIP

Rect = tuple[int, int, int, int]  # x, y, width, height [px]


# ---------------------------------------------------------------------- outlines [m]
def personal_space_contours(
    xy: ArrayLike, yaw: ArrayLike, velocity: ArrayLike, level: float = 0.5, n: int = 40
) -> NDArray[np.float64]:
    """(P, n, 2) closed contours [m] where each person's personal-space Gaussian equals
    ``level``; ``xy`` (P, 2) [m], ``yaw`` (P,) [rad], ``velocity`` (P, 2) [m/s].

    The model of ``m_psi`` (:func:`srpb_gym.metrics.kernels.person_terms`, paper semantics,
    no tracking covariance): variance max(2 speed, 0.5) m^2 ahead, 2/3 of it sideways and
    half of it behind, rotated by the person's yaw. In the person's frame the level set is
    u^2 / var_head + w^2 / var_side = -2 ln(level): two half-ellipses joined at the sides.
    Point k sits at angle -pi + 2 pi k / n around the person (k = n/2: straight ahead).
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


def ellipse_points(ellipses: ArrayLike, n: int = 48) -> NDArray[np.float64]:
    """(G, n, 2) outline points of ellipses given as rows (cx [m], cy [m], a [m], b [m],
    theta [rad]): semi-axis a along theta, b across it."""
    e = np.asarray(ellipses, dtype=np.float64).reshape(-1, 5)
    t = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    u = np.abs(e[:, 2:3]) * np.cos(t)
    w = np.abs(e[:, 3:4]) * np.sin(t)
    return _rotate_about(e[:, :2], e[:, 4], u, w)


def covariance_ellipses(
    xy: ArrayLike, covariance: ArrayLike, sigma: float = 2.0, n: int = 24
) -> NDArray[np.float64]:
    """(K, n, 2) ``sigma``-sigma ellipses [m] of (K, 2, 2) position covariances [m^2]
    around ``xy`` (K, 2) [m]."""
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
    """(F, 5) O-space ellipse (cx [m], cy [m], a [m], b [m], theta [rad]) of every
    F-formation of ``crowd`` (a :class:`~srpb_gym.sim.crowd.Crowd`) at its members' current
    positions, as the ``m_fsi`` metric fits it; formations it cannot fit are left out."""
    groups = [np.asarray(m, dtype=np.int64) for m in crowd.formation_members if len(m)]
    if not groups:
        return np.empty((0, 5))
    size = np.array([g.size for g in groups], dtype=np.int64)
    start = np.cumsum(size) - size
    members = np.concatenate(groups)
    px = np.ascontiguousarray(crowd.position[:, 0], dtype=np.float64)
    py = np.ascontiguousarray(crowd.position[:, 1], dtype=np.float64)
    ellipses, _ = group_ellipses(px, py, members, start, size, params or MetricParams(), reference)
    return ellipses[np.isfinite(ellipses).all(axis=1)]


def _rotate_about(
    center: NDArray[np.float64], angle: NDArray[np.float64], u: ArrayLike, w: ArrayLike
) -> NDArray[np.float64]:
    """Points (u, w) of each row's local frame, rotated by ``angle`` and moved to ``center``."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    out = np.empty((center.shape[0], np.shape(u)[-1], 2))
    out[:, :, 0] = center[:, 0:1] + c * u - s * w
    out[:, :, 1] = center[:, 1:2] + s * u + c * w
    return out


# ---------------------------------------------------------------------- view [px]
@dataclass(frozen=True)
class View:
    """World-to-pixel transform (x to the right, y up, one scale) and the screen areas."""

    scale: float  # px per m
    left: float  # px column of x = xmin
    top: float  # px row of y = ymax
    xmin: float  # m
    ymax: float  # m
    world: Rect  # the world's drawing area
    panel: Rect  # the panel's area

    def px(self, xy: ArrayLike) -> NDArray[np.int64]:
        """Pixel (column, row) of world points (..., 2) [m], rounded to the nearest pixel."""
        xy = np.asarray(xy, dtype=np.float64)
        u = self.left + (xy[..., 0] - self.xmin) * self.scale
        v = self.top + (self.ymax - xy[..., 1]) * self.scale
        return np.rint(np.stack((u, v), axis=-1)).astype(np.int64)

    def length(self, metres: ArrayLike, minimum: int = 0) -> NDArray[np.int64]:
        """Lengths [m] in whole pixels, at least ``minimum``."""
        px = np.rint(np.asarray(metres, dtype=np.float64) * self.scale)
        return np.maximum(px, minimum).astype(np.int64)


def fit_view(bounds: ArrayLike, width: int, height: int) -> View:
    """The view of world ``bounds`` (xmin, ymin, xmax, ymax) [m] in a ``width`` x ``height``
    px frame: the largest equal scale with the panel on the right or at the bottom, the
    side panel unless the bottom one gives a scale over 1/0.9 times larger; centred."""
    xmin, ymin, xmax, ymax = (float(b) for b in np.ravel(bounds))
    w, h = max(xmax - xmin, 1e-6), max(ymax - ymin, 1e-6)
    side = min((width - SIDE_STRIP - 2 * MARGIN) / w, (height - 2 * MARGIN) / h)
    below = min((width - 2 * MARGIN) / w, (height - BOTTOM_STRIP - 2 * MARGIN) / h)
    if side >= 0.9 * below:
        area: Rect = (0, 0, width - SIDE_STRIP, height)
        panel: Rect = (width - SIDE_STRIP, 0, SIDE_STRIP, height)
        scale = side
    else:
        area = (0, 0, width, height - BOTTOM_STRIP)
        panel, scale = (0, height - BOTTOM_STRIP, width, BOTTOM_STRIP), below
    scale = max(scale, 1e-3)
    left = area[0] + 0.5 * (area[2] - w * scale)
    top = area[1] + 0.5 * (area[3] - h * scale)
    return View(scale, left, top, xmin, ymax, area, panel)


def grid_lines(view: View, bounds: ArrayLike) -> NDArray[np.int64]:
    """(N, 2, 2) px end points of the 1 m grid lines (whole metres) inside ``bounds`` [m]."""
    xmin, ymin, xmax, ymax = (float(b) for b in np.ravel(bounds))
    xs, ys = np.arange(math.ceil(xmin), xmax + 1e-9), np.arange(math.ceil(ymin), ymax + 1e-9)
    lines = [((x, ymin), (x, ymax)) for x in xs] + [((xmin, y), (xmax, y)) for y in ys]
    return view.px(np.array(lines, dtype=np.float64).reshape(-1, 2, 2))
