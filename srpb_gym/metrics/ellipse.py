"""O-space ellipses of F-formations: Taubin's algebraic fit and its acceptance checks.

Taubin (1991) in Chernov's formulation, solved as the generalised eigenproblem
``P v = lambda Q v`` with the QZ algorithm (LAPACK ``dggev``), as the SRPB reference tool
does. Everything is batched over groups except the 5x5 ``dggev`` call itself (about 10 us).
The small-sample fallback ellipse lives in :func:`srpb_gym.metrics.kernels.fallback_ellipses`.

An ellipse is (centre x, centre y [m], semi-axis a along theta [m], semi-axis b [m],
theta [rad]).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import lapack


def taubin_fit(
    px: NDArray[np.float64], py: NDArray[np.float64], members: NDArray[np.int64],
    start: NDArray[np.int64], size: NDArray[np.int64],
) -> NDArray[np.float64]:  # fmt: skip
    """(G, 5) ellipses fitted to each group's member positions ``p[members[start:start+size]]``.

    Semi-axes are negative (or NaN) where the fitted conic is not an ellipse.
    """
    g = size.shape[0]
    if g == 0:
        return np.empty((0, 5))
    owner = np.repeat(np.arange(g), size)
    idx = members[np.repeat(start - np.cumsum(size) + size, size) + np.arange(size.sum())]
    x, y = px[idx], py[idx]
    mx = np.bincount(owner, x, g) / size
    my = np.bincount(owner, y, g) / size
    X, Y = x - mx[owner], y - my[owner]
    Z = np.stack((X * X, X * Y, Y * Y, X, Y, np.ones_like(X)), axis=1)
    M = np.add.reduceat(Z[:, :, None] * Z[:, None, :], np.cumsum(size) - size) / size[:, None, None]
    P = M[:, :5, :5].copy()
    P[:, :3, :3] -= M[:, :3, 5, None] * M[:, None, :3, 5]
    m16, m26, m36 = M[:, 0, 5], M[:, 1, 5], M[:, 2, 5]
    Q = np.zeros((g, 5, 5))
    Q[:, 0, 0], Q[:, 0, 1], Q[:, 1, 0] = 4 * m16, 2 * m26, 2 * m26
    Q[:, 1, 1], Q[:, 1, 2], Q[:, 2, 1] = m16 + m36, 2 * m26, 2 * m26
    Q[:, 2, 2], Q[:, 3, 3], Q[:, 4, 4] = 4 * m36, 1.0, 1.0
    v = _smallest_eigenvectors(P, Q)
    A, B, C, D, E = v.T
    F = -(A * m16 + B * m26 + C * m36)
    D, E, F = (
        D - 2 * A * mx - B * my,
        E - 2 * C * my - B * mx,
        F + A * mx * mx + C * my * my + B * mx * my - D * mx - E * my,
    )
    return conic_to_ellipse(A, B, C, D, E, F)


def _smallest_eigenvectors(P: NDArray[np.float64], Q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Eigenvector of the smallest finite real eigenvalue of each pencil (P, Q); NaN if none."""
    out = np.full((P.shape[0], 5), np.nan)
    for k in range(P.shape[0]):
        ar, ai, beta, _, vr, _, info = lapack.dggev(P[k], Q[k], compute_vl=0, compute_vr=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = ar / beta
        real = (ai == 0) & np.isfinite(lam)
        if info == 0 and real.any():
            j = np.flatnonzero(real)[np.argmin(lam[real])]
            out[k] = vr[:, j]
    return out


def conic_to_ellipse(A, B, C, D, E, F) -> NDArray[np.float64]:
    """(G, 5) ellipse parameters of the conics A x^2 + B xy + C y^2 + D x + E y + F = 0."""
    flip = np.where(A + C > 0, -1.0, 1.0)
    A, B, C, D, E, F = (flip * c for c in (A, B, C, D, E, F))
    with np.errstate(divide="ignore", invalid="ignore"):
        theta = 0.5 * np.arctan2(B, A - C)
        den = 4 * A * C - B * B
        cx = (B * E - 2 * C * D) / den
        cy = (B * D - 2 * A * E) / den
        f0 = A * cx * cx + B * cx * cy + C * cy * cy + D * cx + E * cy + F
        co, si = np.cos(theta), np.sin(theta)
        ra = f0 / (A * co * co + B * co * si + C * si * si)
        rb = f0 / (A * si * si - B * co * si + C * co * co)
        a = np.sign(-ra) * np.sqrt(np.abs(ra))
        b = np.sign(-rb) * np.sqrt(np.abs(rb))
    return np.stack((cx, cy, a, b, theta), axis=1)


def accept_fit(
    fits: NDArray[np.float64], px: NDArray[np.float64], py: NDArray[np.float64],
    members: NDArray[np.int64], start: NDArray[np.int64], size: NDArray[np.int64],
    reference: bool,
) -> NDArray[np.bool_]:  # fmt: skip
    """Whether each fitted ellipse is a plausible O-space for its members: no NaN, both
    semi-axes >= 1e-6 m, centre inside the members' bounding box around their mean, and
    extents under twice the members' spread (``reference``: semi-axes a, b against the
    x, y spreads; ``paper``: the ellipse's axis-aligned half-extents)."""
    g = size.shape[0]
    owner = np.repeat(np.arange(g), size)
    idx = members[np.repeat(start - np.cumsum(size) + size, size) + np.arange(size.sum())]
    x, y = px[idx], py[idx]
    mx, my = np.bincount(owner, x, g) / size, np.bincount(owner, y, g) / size
    hx, hy = np.zeros(g), np.zeros(g)
    np.maximum.at(hx, owner, np.abs(x - mx[owner]))
    np.maximum.at(hy, owner, np.abs(y - my[owner]))
    cx, cy, a, b, theta = fits.T
    ok = ~np.isnan(fits).any(axis=1) & (a >= 1e-6) & (b >= 1e-6)
    ok &= (mx - hx <= cx) & (cx <= mx + hx) & (my - hy <= cy) & (cy <= my + hy)
    if reference:
        return ok & (np.abs(a) < 2 * hx) & (np.abs(b) < 2 * hy)
    co2, si2 = np.cos(theta) ** 2, np.sin(theta) ** 2
    with np.errstate(invalid="ignore"):
        ext_x = np.sqrt(a * a * co2 + b * b * si2)
        ext_y = np.sqrt(a * a * si2 + b * b * co2)
    return ok & (ext_x < 2 * hx) & (ext_y < 2 * hy)
