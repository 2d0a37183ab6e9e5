"""Compiled kernels of :class:`~srpb_gym.perception.tracker.KalmanTracker` (the algorithm is
described there): one call of :func:`fuse` is one tracker step on preallocated arrays.

State arrays (``KalmanTracker.arrays``): ``x`` (capacity, 4) means x, y, vx, vy; ``P``
(capacity, 4, 4) covariances; ``f`` (3, capacity) float rows ``F_*``; ``iv`` (3, capacity)
int rows ``I_*``; ``cnt`` counters ``N_*``; ``cfg`` parameters ``C_*``. Live tracks are the
first ``cnt[N_LIVE]`` entries, in creation order.
"""

from __future__ import annotations

import math

from numba import njit

from srpb_gym.angles import wrap_angle
from srpb_gym.perception.assignment import linear_sum_assignment

_MIN_VAR = 1e-6  # floor of the measurement variance [m^2], so that std 0 (exact) works

# Rows of the per-track tables f (float) and iv (int); entries of the counters.
F_YAW, F_AGE, F_TSU = 0, 1, 2
I_ID, I_HITS, I_DET = 0, 1, 2
N_LIVE, N_NEXT_ID, N_REFUSED, N_VISIBLE, N_LAST_REFUSED = 0, 1, 2, 3, 4
# Entries of the compiled parameter array.
C_ACC_VAR, C_VEL_VAR, C_GATE, C_REGATE, C_DIST2 = 0, 1, 2, 3, 4
C_TIMEOUT, C_YAW_W, C_HEADING, C_HITS = 5, 6, 7, 8
# Workspace rows: wt (per track) and wd (per detection).
_DEG, _ROW = 0, 1
_ASSIGN, _DEGC, _COL = 0, 1, 2


@njit(cache=True, error_model="numpy")
def fuse(dt, x, P, f, iv, matched, det_xy, det_yaw, det_std, D, cfg, cnt, cost, wt, wd, sub,
          scratch, pairs):  # fmt: skip
    """One tracker step on the first ``D`` detections: predict and gate
    (:func:`_predict_and_gate`), solve the ambiguous part
    (:func:`~srpb_gym.perception.assignment.linear_sum_assignment`), update and spawn
    (:func:`_update_and_spawn`). Returns the number of reported tracks, or minus an error
    code of ``_ERRORS`` (nothing changed then)."""
    xy, yaw, std = det_xy[:D], det_yaw[:D], det_std[:D]
    code, rows, cols = _predict_and_gate(dt, x, P, f, iv, matched, xy, yaw, std, cfg, cnt, cost,
                                         wt, wd, sub)  # fmt: skip
    if code != 0:
        return -code
    k = 0
    if rows:  # finite costs: always a complete assignment
        k = linear_sum_assignment(sub, rows, cols, pairs[0], pairs[1])
    ri, ci = pairs[0, :k], pairs[1, :k]
    cnt[N_LAST_REFUSED] = _update_and_spawn(x, P, f, iv, matched, xy, yaw, std, cfg, cnt, cost,
                                            wt, wd, ri, ci, scratch)  # fmt: skip
    return cnt[N_VISIBLE]


@njit(cache=True, error_model="numpy")
def _predict_and_gate(dt, x, P, f, iv, matched, det_xy, det_yaw, det_std, cfg, cnt, cost, wt, wd,
                      sub):  # fmt: skip
    """Validate the inputs, predict every track by ``dt``, delete expired tracks (keeping
    creation order), gate all pairs into ``cost`` (inf: inadmissible) and split them with
    :func:`_split`. Returns (error code, rows, cols)."""
    D = det_xy.shape[0]
    code = 0 if 0.0 <= dt < math.inf else 1
    for d in range(D):
        if not (math.isfinite(det_xy[d, 0]) and math.isfinite(det_xy[d, 1])):
            code = 2
        elif not math.isfinite(det_yaw[d]):
            code = 3
        elif not 0.0 <= det_std[d] < math.inf:
            code = 4
    if code != 0:
        return code, 0, 0
    q = cfg[C_ACC_VAR]
    q_pp, q_pv, q_vv = q * dt**4 / 4.0, q * dt**3 / 2.0, q * dt * dt
    n = 0
    for r in range(cnt[N_LIVE]):
        f[F_AGE, r] += dt
        f[F_TSU, r] += dt
        if f[F_TSU, r] > cfg[C_TIMEOUT]:
            continue
        if n != r:
            x[n], P[n], f[:, n], iv[:, n] = x[r], P[r], f[:, r], iv[:, r]
        if dt > 0.0:
            _predict(x[n], P[n], dt, q_pp, q_pv, q_vv)
        matched[n] = False
        iv[I_DET, n] = -1
        wt[_DEG, n] = 0
        n += 1
    cnt[N_LIVE] = n
    wd[_ASSIGN, :D] = -1
    wd[_DEGC, :D] = 0
    for r in range(n):
        for d in range(D):
            c = _gated_cost(x[r], P[r], det_xy[d, 0], det_xy[d, 1], det_std[d], cfg[C_GATE], cfg)
            cost[r, d] = c
            if c < math.inf:
                wt[_DEG, r] += 1
                wd[_DEGC, d] += 1
    rows, cols = _split(n, D, cost, wt, wd, sub, cfg[C_GATE])
    return 0, rows, cols


@njit(cache=True, inline="always", error_model="numpy")
def _predict(x, P, dt, q_pp, q_pv, q_vv):
    """x <- F x, P <- F P F^T + Q for the constant-velocity model (state x, y, vx, vy)."""
    for a in range(2):
        x[a] += dt * x[a + 2]
        for j in range(4):  # F P
            P[a, j] += dt * P[a + 2, j]
        for i in range(4):  # (F P) F^T
            P[i, a] += dt * P[i, a + 2]
    for a in range(2):
        P[a, a] += q_pp
        P[a, a + 2] += q_pv
        P[a + 2, a] += q_pv
        P[a + 2, a + 2] += q_vv


@njit(cache=True, inline="always", error_model="numpy")
def _gated_cost(x, P, zx, zy, std, gate, cfg):
    """Squared Mahalanobis distance of a detection to a track, inf outside the gates."""
    ex, ey = zx - x[0], zy - x[1]
    if ex * ex + ey * ey > cfg[C_DIST2]:
        return math.inf
    r2 = max(std * std, _MIN_VAR)
    sxx, syy, sxy = P[0, 0] + r2, P[1, 1] + r2, P[0, 1]
    d2 = (syy * ex * ex - 2.0 * sxy * ex * ey + sxx * ey * ey) / (sxx * syy - sxy * sxy)
    return d2 if d2 <= gate else math.inf


@njit(cache=True, error_model="numpy")
def _split(n, D, cost, wt, wd, sub, gate):
    """Assign the admissible pairs with no rival (``wd[_ASSIGN]``); write the rest into
    ``sub`` as a dense problem of tracks ``wt[_ROW, :rows]`` x detections ``wd[_COL, :cols]``
    (inadmissible entries: a cost above any sum of admissible ones). Returns (rows, cols)."""
    rows = 0
    for r in range(n):
        keep = False
        for d in range(D):
            if cost[r, d] < math.inf:
                if wt[_DEG, r] == 1 and wd[_DEGC, d] == 1:
                    wd[_ASSIGN, d] = r
                else:
                    keep = True
        if keep:
            wt[_ROW, rows] = r
            rows += 1
    if rows == 0:
        return 0, 0
    cols = 0
    for d in range(D):
        if wd[_DEGC, d] > 1 or (wd[_DEGC, d] == 1 and wd[_ASSIGN, d] < 0):
            wd[_COL, cols] = d
            cols += 1
    big = gate * (min(rows, cols) + 1) + 1.0
    for i in range(rows):
        for j in range(cols):
            c = cost[wt[_ROW, i], wd[_COL, j]]
            sub[i * cols + j] = c if c < math.inf else big
    return rows, cols


@njit(cache=True, error_model="numpy")
def _update_and_spawn(x, P, f, iv, matched, det_xy, det_yaw, det_std, cfg, cnt, cost, wt, wd,
                      ri, ci, scratch):  # fmt: skip
    """Take the solver's admissible pairs, give leftovers a second chance, update paired
    tracks, start tracks for the other detections (while capacity lasts), set headings and
    count the confirmed tracks. Returns the number of detections refused for capacity."""
    for k in range(ri.size):
        r, d = wt[_ROW, ri[k]], wd[_COL, ci[k]]
        if cost[r, d] < math.inf:
            wd[_ASSIGN, d] = r
    n = cnt[N_LIVE]
    if cfg[C_REGATE] > cfg[C_GATE]:
        _reacquire(x, P, det_xy, det_std, cfg, n, wt, wd)
    refused = 0
    for d in range(det_xy.shape[0]):
        t = wd[_ASSIGN, d]
        if t >= 0:
            _update(x[t], P[t], det_xy[d, 0], det_xy[d, 1], det_std[d], scratch)
            turn = wrap_angle(det_yaw[d] - f[F_YAW, t])
            f[F_YAW, t] = wrap_angle(f[F_YAW, t] + cfg[C_YAW_W] * turn)
        elif n == x.shape[0]:
            refused += 1
            continue
        else:
            t = n
            n += 1
            _start(t, x[t], P[t], f, iv, det_xy[d], det_yaw[d], det_std[d], cfg, cnt)
        f[F_TSU, t] = 0.0
        iv[I_HITS, t] += 1
        iv[I_DET, t] = d
        matched[t] = True
    cnt[N_LIVE] = n
    cnt[N_REFUSED] += refused
    _confirm(x, f, iv, cfg, cnt)
    return refused


@njit(cache=True, error_model="numpy")
def _reacquire(x, P, det_xy, det_std, cfg, n, wt, wd):
    """Pair the tracks and detections left unpaired, smallest distance first, under the
    looser gate (still capped by ``max_distance``)."""
    D = det_xy.shape[0]
    used = wt[_DEG]  # reused as a flag row
    used[:n] = 0
    free = 0
    for d in range(D):
        if wd[_ASSIGN, d] >= 0:
            used[wd[_ASSIGN, d]] = 1
        else:
            free += 1
    while free > 0:
        best, bt, bd = math.inf, -1, -1
        for r in range(n):
            if used[r] == 0:
                for d in range(D):
                    if wd[_ASSIGN, d] < 0:
                        c = _gated_cost(x[r], P[r], det_xy[d, 0], det_xy[d, 1], det_std[d],
                                        cfg[C_REGATE], cfg)  # fmt: skip
                        if c < best:
                            best, bt, bd = c, r, d
        if bt < 0:
            return
        wd[_ASSIGN, bd] = bt
        used[bt] = 1
        free -= 1


@njit(cache=True, inline="always", error_model="numpy")
def _start(t, x, P, f, iv, z, yaw, std, cfg, cnt):
    """New track ``t`` at rest at detection ``z``, P = diag(std^2, std^2, v^2, v^2)."""
    x[0], x[1], x[2], x[3] = z[0], z[1], 0.0, 0.0
    P[:, :] = 0.0
    P[0, 0] = P[1, 1] = max(std * std, _MIN_VAR)
    P[2, 2] = P[3, 3] = cfg[C_VEL_VAR]
    f[F_YAW, t] = wrap_angle(yaw)
    f[F_AGE, t] = 0.0
    iv[I_ID, t] = cnt[N_NEXT_ID]
    iv[I_HITS, t] = 0
    cnt[N_NEXT_ID] += 1


@njit(cache=True, inline="always", error_model="numpy")
def _update(x, P, zx, zy, std, scratch):
    """Kalman update with a position measurement of isotropic std; P stays symmetric."""
    r2 = max(std * std, _MIN_VAR)
    sxx, syy, sxy = P[0, 0] + r2, P[1, 1] + r2, P[0, 1]
    det = sxx * syy - sxy * sxy
    ixx, ixy, iyy = syy / det, -sxy / det, sxx / det  # S^-1
    ex, ey = zx - x[0], zy - x[1]
    kx, ky = scratch[0], scratch[1]  # gain K = P H^T S^-1, two columns
    ph0, ph1 = scratch[2], scratch[3]  # H P, two rows, read before P changes
    for i in range(4):
        kx[i] = P[i, 0] * ixx + P[i, 1] * ixy
        ky[i] = P[i, 0] * ixy + P[i, 1] * iyy
        ph0[i], ph1[i] = P[0, i], P[1, i]
    for i in range(4):
        x[i] += kx[i] * ex + ky[i] * ey
        for j in range(4):
            P[i, j] -= kx[i] * ph0[j] + ky[i] * ph1[j]
    for i in range(4):
        for j in range(i + 1, 4):
            P[i, j] = P[j, i] = 0.5 * (P[i, j] + P[j, i])


@njit(cache=True, inline="always", error_model="numpy")
def _confirm(x, f, iv, cfg, cnt):
    """Count the confirmed tracks; turn the fast confirmed ones to face their velocity."""
    visible = 0
    v2 = cfg[C_HEADING] * cfg[C_HEADING]
    for t in range(cnt[N_LIVE]):
        if iv[I_HITS, t] >= cfg[C_HITS]:
            visible += 1
            if x[t, 2] * x[t, 2] + x[t, 3] * x[t, 3] > v2:
                f[F_YAW, t] = math.atan2(x[t, 3], x[t, 2])
    cnt[N_VISIBLE] = visible
