"""Compiled per-sample SRPB kernels, shared by the episode metrics and the per-step reward.

Every kernel is a plain loop compiled by numba (``cache=True``: only the first process pays
the compile). Each one works on any number of rows, so the episode evaluation calls it once
for all person-samples of an episode and the environment once per step for the people it
tracks now. ``reference`` switches from the paper's equations to the reference tool's
behaviour (see ``METRICS.md`` of the SRPB specification and :mod:`srpb_gym.metrics`).

Conventions: robot arrays are indexed by sample ``n``; entity rows carry ``sample[i]``.
Angles in rad, lengths in m, covariances in m^2. ``gauss(dx, dy, sxx, sxy, syx, syy)`` is the
bivariate Gaussian normalised to 1 at its mean, ``exp(-0.5 d^T S^-1 d)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from srpb_gym.angles import wrap_angle

PI = math.pi
# Distance along the robot's heading line within which the reference tool searches for the
# intersection used by m_dir [m].
REFERENCE_DIR_SEARCH = 1000.0
# Radius of the 1-member O-space circle and fallback minor semi-axis in the reference tool [m].
REFERENCE_OCCUPANCY = 0.28


@njit(cache=True, inline="always", error_model="numpy")
def gauss(dx: float, dy: float, sxx: float, sxy: float, syx: float, syy: float) -> float:
    """exp(-0.5 d^T S^-1 d) for S = [[sxx, sxy], [syx, syy]]."""
    det = sxx * syy - sxy * syx
    q = (syy * dx * dx - (sxy + syx) * dx * dy + sxx * dy * dy) / det
    return math.exp(-0.5 * q)


@njit(cache=True, error_model="numpy")
def person_terms(
    rob_x, rob_y, rob_yaw, rob_speed, sample,
    px, py, pyaw, pvx, pvy, cxx, cxy, cyx, cyy,
    person_fov, robot_max_speed, robot_circumradius, occupancy_radius, reference,
    psi_out, dir_out,
):  # fmt: skip
    """Personal-space intrusion (psi) and heading-direction disturbance (dir) per row.

    Row i pairs person i with robot sample ``sample[i]``. ``rob_speed`` is the robot's
    linear speed hypot(vx, vy) [m/s]. Writes ``psi_out[i]`` and ``dir_out[i]``.
    """
    for i in range(px.shape[0]):
        n = sample[i]
        psi_out[i], dir_out[i] = person_pair(
            rob_x[n], rob_y[n], rob_yaw[n], rob_speed[n], px[i], py[i], pyaw[i], pvx[i],
            pvy[i], cxx[i], cxy[i], cyx[i], cyy[i], person_fov, robot_max_speed,
            robot_circumradius, occupancy_radius, reference,
        )  # fmt: skip


@njit(cache=True, inline="always", error_model="numpy")
def person_pair(
    rx, ry, ryaw, rspeed, hx, hy, hyaw, pvx, pvy, cxx, cxy, cyx, cyy,
    person_fov, robot_max_speed, robot_circumradius, occupancy_radius, reference,
):  # fmt: skip
    """(psi, dir) of one person for one robot state (see :func:`person_terms`)."""
    sigma_fov = person_fov / 4.0
    dist_scale = robot_circumradius + occupancy_radius
    ocp_var = (0.5 * occupancy_radius) ** 2
    c_off = 0.5 * (cxy + cyx)
    # --- personal space: Kirby's asymmetric Gaussian plus the tracking covariance
    dx, dy = rx - hx, ry - hy
    speed = math.hypot(pvx, pvy)
    var_front = max(2.0 * speed, 0.5)
    var_side = var_front * 2.0 / 3.0
    delta = wrap_angle(math.atan2(dy, dx) - hyaw)
    front = delta <= 0.5 * PI if reference else abs(delta) <= 0.5 * PI
    var_head = var_front if front else 0.5 * var_front
    ch, sh = math.cos(hyaw), math.sin(hyaw)
    rot_off = ch * sh * (var_head - var_side)
    sxx = ch * ch * var_head + sh * sh * var_side + cxx
    syy = sh * sh * var_head + ch * ch * var_side + cyy
    if reference:
        psi = gauss(dx, dy, sxx, rot_off + cxy, rot_off + cyx, syy)
    else:
        psi = gauss(dx, dy, sxx, rot_off + c_off, rot_off + c_off, syy)
    # --- heading straight into the person
    ex, ey = hx - rx, hy - ry
    d = math.hypot(ex, ey)
    phi = math.atan2(ey, ex)
    hcos, hsin = math.cos(ryaw), math.sin(ryaw)
    along = hcos * math.cos(phi) + hsin * math.sin(phi)
    direction = 0.0
    if along != 0.0:
        t = d / along  # robot -> intersection with the person's perpendicular line
        if (reference and abs(t) <= REFERENCE_DIR_SEARCH) or (not reference and t > 0.0):
            ix = rx + t * hcos - hx
            iy = ry + t * hsin - hy
            off = cxy if reference else c_off
            direction = gauss(ix, iy, ocp_var + cxx, off, off, ocp_var + cyy)
    fov = math.exp(-(delta * delta) / (2.0 * sigma_fov * sigma_fov))
    speed_factor = rspeed / robot_max_speed
    if reference:
        dirv = direction * fov * speed_factor / (d / dist_scale)
    elif d == 0.0:
        dirv = 1.0
    else:
        dirv = min(1.0, direction * fov * speed_factor / (d / dist_scale))
    return psi, dirv


@njit(cache=True, error_model="numpy")
def fallback_ellipses(
    px, py, members, start, size, occupancy_radius, reference, skip,
    cx_out, cy_out, a_out, b_out, th_out,
):  # fmt: skip
    """O-space ellipse of each group row by the small-sample rule (rows with ``skip`` set
    are left untouched). Semi-axes a, b [m], orientation theta [rad] in (-pi/2, pi/2]."""
    for g in range(start.shape[0]):
        if skip[g]:
            continue
        k0, k = start[g], size[g]
        mx, my = 0.0, 0.0
        for j in range(k):
            mx += px[members[k0 + j]]
            my += py[members[k0 + j]]
        mx /= k
        my /= k
        cx_out[g], cy_out[g] = mx, my
        if k == 1:
            r = REFERENCE_OCCUPANCY if reference else occupancy_radius
            a_out[g], b_out[g], th_out[g] = r, r, 0.0
            continue
        best, bi, bj = -1.0, 0, 1
        for i in range(k):
            for j in range(i + 1, k):
                dd = math.hypot(
                    px[members[k0 + j]] - px[members[k0 + i]],
                    py[members[k0 + j]] - py[members[k0 + i]],
                )
                if dd > best:
                    best, bi, bj = dd, i, j
        theta = math.atan2(
            py[members[k0 + bj]] - py[members[k0 + bi]], px[members[k0 + bj]] - px[members[k0 + bi]]
        )
        if theta > 0.5 * PI:
            theta -= PI
        elif theta <= -0.5 * PI:
            theta += PI
        nx, ny = -math.sin(theta), math.cos(theta)
        n_ang = math.atan2(ny, nx)
        pos = -1.0 if reference else 0.0
        neg = pos
        for j in range(k):
            p = (px[members[k0 + j]] - mx) * nx + (py[members[k0 + j]] - my) * ny
            if reference:
                on_pos = p != 0.0 and abs(wrap_angle(math.atan2(p * ny, p * nx) - n_ang)) < 1e-3
            else:
                on_pos = p > 0.0
            if on_pos:
                pos = max(pos, abs(p))
            else:
                neg = max(neg, abs(p))
        b = 0.5 * (pos + neg)
        if b < 1e-3:
            b = REFERENCE_OCCUPANCY if reference else occupancy_radius
        a_out[g], b_out[g], th_out[g] = 0.5 * best, b, theta


@njit(cache=True, error_model="numpy")
def group_covariances(cxx, cxy, cyx, cyy, members, start, size, reference, sxx, sxy, syy):
    """Element-wise maximum of the members' position covariances per group row."""
    for g in range(start.shape[0]):
        k0 = start[g]
        mxx, mxy, myy = -np.inf, -np.inf, -np.inf
        for j in range(size[g]):
            m = members[k0 + j]
            mxx = max(mxx, cxx[m])
            myy = max(myy, cyy[m])
            off = max(cxy[m], cyx[m]) if reference else 0.5 * (cxy[m] + cyx[m])
            mxy = max(mxy, off)
        sxx[g], sxy[g], syy[g] = mxx, mxy, myy


@njit(cache=True, error_model="numpy")
def group_terms(rob_x, rob_y, sample, cx, cy, a, b, theta, sxx, sxy, syy, fsi_out):
    """F-formation O-space intrusion (fsi) per group row."""
    for g in range(sample.shape[0]):
        n = sample[g]
        va, vb = (0.5 * a[g]) ** 2, (0.5 * b[g]) ** 2
        c, s = math.cos(theta[g]), math.sin(theta[g])
        off = c * s * (va - vb) + sxy[g]
        fsi_out[g] = gauss(
            rob_x[n] - cx[g],
            rob_y[n] - cy[g],
            c * c * va + s * s * vb + sxx[g],
            off,
            off,
            s * s * va + c * c * vb + syy[g],
        )


@njit(cache=True, error_model="numpy")
def motion_flags(
    vx, vy, omega, lin_thr, x_thr, y_thr, ang_thr, stop_tol, reference, osc_out, bwd_out, iprot_out
):
    """Per-sample predicates: oscillating, moving backward, rotating in place."""
    for n in range(vx.shape[0]):
        osc_out[n], bwd_out[n], iprot_out[n] = motion_predicates(
            vx[n], vy[n], omega[n], lin_thr, x_thr, y_thr, ang_thr, stop_tol, reference
        )


@njit(cache=True, inline="always", error_model="numpy")
def motion_predicates(vx, vy, omega, lin_thr, x_thr, y_thr, ang_thr, stop_tol, reference):
    """(oscillating, moving backward, rotating in place) of one velocity (vx, vy, omega)."""
    avx, avy, aw = abs(vx), abs(vy), abs(omega)
    lin = math.hypot(vx, vy)
    if reference:
        osc = lin < lin_thr and avx < x_thr and avx < y_thr and aw < ang_thr
        bwd = vx < -abs(x_thr)
    else:
        osc = lin < lin_thr and avx < x_thr and avy < y_thr and aw < ang_thr
        bwd = vx <= -x_thr
    iprot = avx < stop_tol and avy < stop_tol and aw >= ang_thr
    return osc, bwd, iprot


@njit(cache=True, error_model="numpy")
def _scan(values, lo, hi, threshold, stats):
    """Maximum of values[lo:hi]; folds them into stats = [min, max, count, above]."""
    peak = -np.inf
    for r in range(lo, hi):
        v = values[r]
        peak = max(peak, v)
        stats[0] = min(stats[0], v)
        stats[1] = max(stats[1], v)
        stats[2] += 1.0
        if v > threshold:
            stats[3] += 1.0
    return peak


@njit(cache=True, error_model="numpy")
def aggregate(values, sample, dt, n_samples, threshold, reference, stats):
    """The SRPB social aggregation of per-entity ``values`` (rows sorted by ``sample``).

    Each sample n <= N-2 with entities contributes weight dt[n] times the largest of its
    values. ``reference`` adds the reference tool's extra entry for entities at the last
    sample (weight dt[N-2], values of samples N-2 and N-1 together). Returns (weighted
    sum, sum of weights, number of entries); ``stats`` (4 floats, set to [inf, -inf, 0, 0]
    by the caller) receives the minimum, maximum, count and count above ``threshold`` of
    every aggregated value.
    """
    num, den, used = 0.0, 0.0, 0
    last = n_samples - 1
    prev_lo, prev_hi = 0, 0  # rows of sample N-2
    i, rows = 0, values.shape[0]
    while i < rows:
        n = sample[i]
        j = i
        while j < rows and sample[j] == n:
            j += 1
        if n < last:
            if n == last - 1:
                prev_lo, prev_hi = i, j
            peak = _scan(values, i, j, threshold, stats)
            num += dt[n] * peak
            den += dt[n]
            used += 1
        elif reference and last >= 1:
            peak = _scan(values, prev_lo, prev_hi, threshold, stats)
            peak = max(peak, _scan(values, i, j, threshold, stats))
            num += dt[last - 1] * peak
            den += dt[last - 1]
            used += 1
        i = j
    return num, den, used


@njit(cache=True, error_model="numpy")
def reference_obstacle_time(t, close):
    """The reference tool's accounting of time spent too close to obstacles [s].

    A state machine over the samples in order: a close sample sets ``start`` if unset, else
    ``end``; a clear sample closes a run that has an ``end``. So a one-sample run adds
    nothing and leaves its start behind for the next run.
    """
    total = 0.0
    start, end = 0.0, 0.0
    has_start, has_end = False, False
    for n in range(t.shape[0]):
        if close[n]:
            if not has_start:
                start, has_start = t[n], True
            else:
                end, has_end = t[n], True
        elif has_end:
            total += end - start
            has_start, has_end = False, False
    if has_start and has_end:
        total += end - start
    return total
