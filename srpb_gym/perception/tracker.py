"""Multi-person tracker: one constant-velocity Kalman filter per track.

Each step :meth:`KalmanTracker.step` takes the detector's measured positions, headings and
isotropic position noise stds (never identities) and

1. predicts every track by ``dt`` (constant velocity, white acceleration noise of std
   ``accel_noise_std`` held over the step): unobserved covariances grow;
2. deletes the tracks not updated for longer than ``timeout``;
3. pairs detections with tracks by :func:`scipy.optimize.linear_sum_assignment` on the
   squared Mahalanobis distance to the predicted position (innovation covariance: predicted
   position covariance + std^2 I), never across the chi-square ``gate`` or ``max_distance``;
   the most pairs first, then the least summed distance. The solver only sees the ambiguous
   part of the gating graph; pairs with no rival are taken directly (same result);
4. pairs leftover tracks and detections, closest first, under the looser ``reacquire_gate``
   (and ``max_distance``); otherwise a detection just outside the gate (1% for a 99% gate,
   more when people turn) starts a duplicate track that takes turns with the original;
5. updates paired tracks (covariance shrinks), coasts the others and starts a track at rest
   for each remaining detection while capacity lasts.

Ids come from a counter never reused within an episode. The state lives in preallocated
arrays of capacity ``max_tracks`` (live tracks in creation order), updated by two compiled
kernels.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import njit
from scipy.optimize import linear_sum_assignment

from srpb_gym.angles import wrap_angle
from srpb_gym.config import from_spec

_MIN_VAR = 1e-6  # floor of the measurement variance [m^2], so that std 0 (exact) works
_ERRORS = (
    "", "dt must be a finite number >= 0", "detection positions must be finite",
    "detection yaws must be finite", "detection stds must be finite and >= 0",
)  # fmt: skip


@dataclass(frozen=True)
class TrackerConfig:
    """Parameters of :class:`KalmanTracker` (SI units).

    Attributes:
        accel_noise_std: std of the white acceleration of the constant-velocity model
            [m/s^2].
        init_velocity_std: std of the velocity of a new track (started at rest) [m/s].
        gate: chi-square gate on the squared Mahalanobis distance of a detection to a
            track's predicted position (9.21 keeps 99% of the true pairs, 2 dof).
        reacquire_gate: looser gate of the second-chance pairing of leftover tracks and
            detections (25: 5 sigma); a value <= ``gate`` disables it.
        max_distance: Euclidean cap on the distance of a pair [m] (may be inf).
        timeout: a track not updated for longer than this is deleted [s].
        max_tracks: capacity. When it is full, a detection paired with no track starts none
            (counted in :attr:`KalmanTracker.refused`) until tracks time out.
        yaw_smoothing: weight of a yaw measurement in (0, 1]: the yaw moves by this fraction
            of the wrapped angle to the measurement (1: take the measurement).
        min_speed_for_heading: when set, a confirmed track faster than this [m/s] takes the
            direction of its velocity as its yaw (people face where they walk); ``None``
            (default) keeps the smoothed measured yaw.
        min_hits: detections a track needs before it is reported (confirmed); 1 reports a
            track from its first detection on. Unconfirmed tracks are paired and time out
            like the others.
    """

    accel_noise_std: float = 1.0
    init_velocity_std: float = 1.0
    gate: float = 9.21
    reacquire_gate: float = 25.0
    max_distance: float = 1.5
    timeout: float = 1.0
    max_tracks: int = 64
    yaw_smoothing: float = 0.5
    min_speed_for_heading: float | None = None
    min_hits: int = 1

    def __post_init__(self) -> None:
        _check(self.accel_noise_std, "accel_noise_std", lo=0.0)
        _check(self.init_velocity_std, "init_velocity_std", lo=0.0, strict=True)
        _check(self.gate, "gate", lo=0.0, strict=True)
        _check(self.reacquire_gate, "reacquire_gate", lo=0.0)
        _check(self.max_distance, "max_distance", lo=0.0, strict=True, finite=False)
        _check(self.timeout, "timeout", lo=0.0)
        _check(self.yaw_smoothing, "yaw_smoothing", lo=0.0, strict=True)
        if self.yaw_smoothing > 1.0:
            raise ValueError(f"yaw_smoothing must be in (0, 1], got {self.yaw_smoothing!r}")
        if self.min_speed_for_heading is not None:
            _check(self.min_speed_for_heading, "min_speed_for_heading", lo=0.0)
        for name in ("max_tracks", "min_hits"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")

    @classmethod
    def from_spec(
        cls, spec: str | Mapping[str, Any] | TrackerConfig | None,
        path: str = "", file: str | None = None,
    ) -> TrackerConfig:  # fmt: skip
        """A config from a preset name, a mapping, an instance or ``None`` (default)."""
        return from_spec(cls, spec, PRESETS, path, file)


def _check(value: Any, name: str, lo: float, strict: bool = False, finite: bool = True) -> None:
    """``ValueError`` unless ``value`` is a number >= ``lo`` (> if strict), finite if finite."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    bad = math.isnan(value) or (finite and math.isinf(value))
    if bad or value < lo or (strict and value == lo):
        bound = f"> {lo}" if strict else f">= {lo}"
        kind = "a finite number" if finite else "a number"
        raise ValueError(f"{name} must be {kind} {bound}, got {value!r}")


PRESETS: dict[str, TrackerConfig] = {"default": TrackerConfig()}


class Tracks(NamedTuple):
    """The reported tracks, K rows each, in creation order."""

    ids: np.ndarray  # (K,) int64, persistent within an episode
    xy: np.ndarray  # (K, 2) position [m]
    velocity: np.ndarray  # (K, 2) global velocity [m/s]
    yaw: np.ndarray  # (K,) heading in (-pi, pi] [rad]
    covariance: np.ndarray  # (K, 2, 2) position covariance [m^2], symmetric
    age: np.ndarray  # (K,) time since creation [s]
    time_since_update: np.ndarray  # (K,) [s]
    matched: np.ndarray  # (K,) bool: updated by (or started from) a detection this step
    detection: np.ndarray  # (K,) int64 index of that detection, or -1


# Layout of the state arrays (KalmanTracker.arrays: x, P, f, iv, cnt, cfg), for compiled
# readers: rows of the per-track tables f (float) and iv (int); entries of the counters.
F_YAW, F_AGE, F_TSU = 0, 1, 2
I_ID, I_HITS, I_DET = 0, 1, 2
N_LIVE, N_NEXT_ID, N_REFUSED, N_VISIBLE = 0, 1, 2, 3
# Entries of the compiled parameter array.
C_ACC_VAR, C_VEL_VAR, C_GATE, C_REGATE, C_DIST2 = 0, 1, 2, 3, 4
C_TIMEOUT, C_YAW_W, C_HEADING, C_HITS = 5, 6, 7, 8
# Workspace rows: wt (per track) and wd (per detection).
_DEG, _ROW = 0, 1
_ASSIGN, _DEGC, _COL = 0, 1, 2


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


_NO_INDEX = np.empty(0, np.int64)


def _as_detections(det_xy: Any, det_yaw: Any, det_std: Any) -> tuple[np.ndarray, ...]:
    """Contiguous float64 (D, 2), (D,), (D,) arrays; ``ValueError`` for other shapes."""
    xy = np.ascontiguousarray(det_xy, dtype=np.float64)
    if xy.size == 0:
        xy = xy.reshape(0, 2)
    D = xy.shape[0]
    yaw = np.ascontiguousarray(det_yaw, dtype=np.float64)
    if np.ndim(det_std) == 0:
        std = np.full(D, float(det_std))
    else:
        std = np.ascontiguousarray(det_std, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2 or yaw.shape != (D,) or std.shape != (D,):
        raise ValueError(
            f"expected det_xy (D, 2), det_yaw (D,), det_std (D,); got {xy.shape}, "
            f"{yaw.shape}, {std.shape}"
        )
    return xy, yaw, std


class KalmanTracker:
    """Tracks people from noisy detections (see the module docstring for the algorithm).

    ``KalmanTracker(config)`` takes a :class:`TrackerConfig`, a preset name, a mapping or
    ``None``. Call :meth:`step` once per control step, then read the reported tracks from the
    properties or :meth:`tracks`: read-only views into the tracker's state (copies when
    ``min_hits`` > 1), valid until the next :meth:`step` or :meth:`reset`. Copy what you keep.
    """

    def __init__(self, config: TrackerConfig | str | Mapping[str, Any] | None = None) -> None:
        self.config = c = TrackerConfig.from_spec(config)
        cap = int(c.max_tracks)
        heading = math.inf if c.min_speed_for_heading is None else c.min_speed_for_heading
        self._cfg = np.array([
            c.accel_noise_std**2, c.init_velocity_std**2, c.gate, c.reacquire_gate,
            c.max_distance**2, c.timeout, c.yaw_smoothing, heading, c.min_hits,
        ], dtype=np.float64)  # fmt: skip
        self._x, self._P, self._f = np.zeros((cap, 4)), np.zeros((cap, 4, 4)), np.zeros((3, cap))
        self._i, self._wt = np.zeros((3, cap), np.int64), np.zeros((2, cap), np.int64)
        self._matched = np.zeros(cap, dtype=np.bool_)
        self._cnt = np.zeros(4, dtype=np.int64)
        self._scratch = np.zeros((4, 4))
        #: the state arrays (x, P, f, iv, cnt, cfg) for compiled readers; see the layout
        #: constants of this module
        self.arrays = (self._x, self._P, self._f, self._i, self._cnt, self._cfg)
        self._reserve(cap)
        views = [a.view() for a in (self._x, self._P, self._f, self._i, self._matched)]
        for v in views:
            v.flags.writeable = False
        self._ro_x, self._ro_P, self._ro_f, self._ro_i, self._ro_matched = views
        self.reset()

    def _reserve(self, detections: int) -> None:
        """Size the per-detection workspace for ``detections`` detections."""
        cap = self._x.shape[0]
        self._dcap = detections
        self._cost = np.zeros((cap, detections))
        self._wd = np.zeros((3, detections), dtype=np.int64)
        self._sub = np.zeros(cap * detections)

    def reset(self) -> None:
        """Forget all tracks and restart ids at 0 (a new episode)."""
        self._cnt[:] = 0
        self._sel: slice | np.ndarray = slice(0, 0)
        self.last_refused = 0

    def step(
        self, dt: float, det_xy: np.ndarray, det_yaw: np.ndarray, det_std: np.ndarray | float
    ) -> int:
        """Advance by ``dt`` [s] (finite, >= 0; 0: no prediction) and fuse the detections:
        ``det_xy`` (D, 2) global positions [m] (D may be 0), ``det_yaw`` (D,) headings
        [rad], ``det_std`` (D,) or scalar isotropic position noise std [m], >= 0 (the
        variance is floored at 1e-6 m^2). Returns K, the number of reported tracks.

        Raises ``ValueError`` for a bad shape or value, leaving the state unchanged.
        """
        xy, yaw, std = _as_detections(det_xy, det_yaw, det_std)
        D = xy.shape[0]
        if self._dcap < D:
            self._reserve(max(D, 2 * self._dcap))
        state = (self._x, self._P, self._f, self._i, self._matched)
        work = (self._cfg, self._cnt, self._cost, self._wt, self._wd)
        code, rows, cols = _predict_and_gate(float(dt), *state, xy, yaw, std, *work, self._sub)
        if code:
            raise ValueError(_ERRORS[code])
        ri = ci = _NO_INDEX
        if rows:
            ri, ci = linear_sum_assignment(self._sub[: rows * cols].reshape(rows, cols))
        self.last_refused = _update_and_spawn(*state, xy, yaw, std, *work, ri, ci, self._scratch)
        n, visible = int(self._cnt[N_LIVE]), int(self._cnt[N_VISIBLE])
        if visible == n:
            self._sel = slice(0, n)
        else:
            self._sel = np.flatnonzero(self._i[I_HITS, :n] >= self.config.min_hits)
        return visible

    def __len__(self) -> int:
        """Number of reported tracks."""
        return int(self._cnt[N_VISIBLE])

    num_live = property(lambda self: int(self._cnt[N_LIVE]), doc="Live tracks, confirmed or not.")
    next_id = property(lambda self: int(self._cnt[N_NEXT_ID]), doc="Id of the next new track.")
    refused = property(
        lambda self: int(self._cnt[N_REFUSED]),
        doc="Detections that started no track (capacity full) this episode.",
    )

    # The reported tracks, K rows each, in creation order (see :class:`Tracks`).
    ids = property(lambda self: self._ro_i[I_ID, self._sel], doc="(K,) int64 ids.")
    xy = property(lambda self: self._ro_x[self._sel, :2], doc="(K, 2) positions [m].")
    velocity = property(lambda self: self._ro_x[self._sel, 2:], doc="(K, 2) velocities [m/s].")
    yaw = property(lambda self: self._ro_f[F_YAW, self._sel], doc="(K,) headings [rad].")
    covariance = property(lambda self: self._ro_P[self._sel, :2, :2], doc="(K, 2, 2) [m^2].")
    state_covariance = property(lambda self: self._ro_P[self._sel], doc="(K, 4, 4), x y vx vy.")
    age = property(lambda self: self._ro_f[F_AGE, self._sel], doc="(K,) since creation [s].")
    time_since_update = property(lambda self: self._ro_f[F_TSU, self._sel], doc="(K,) [s].")
    matched = property(lambda self: self._ro_matched[self._sel], doc="(K,) bool, this step.")
    detection = property(lambda self: self._ro_i[I_DET, self._sel], doc="(K,) int64 or -1.")

    def tracks(self) -> Tracks:
        """All reported per-track arrays at once."""
        return Tracks(
            self.ids, self.xy, self.velocity, self.yaw, self.covariance, self.age,
            self.time_since_update, self.matched, self.detection,
        )  # fmt: skip
