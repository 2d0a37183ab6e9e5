"""Multi-person tracker: one constant-velocity Kalman filter per track.

Each step :meth:`KalmanTracker.step` takes the detector's measured positions, headings and
isotropic position noise stds (never identities) and

1. predicts every track by ``dt`` (constant velocity, white acceleration noise of std
   ``accel_noise_std`` held over the step): unobserved covariances grow;
2. deletes the tracks not updated for longer than ``timeout``;
3. pairs detections with tracks by a linear sum assignment (scipy's algorithm, compiled:
   :mod:`srpb_gym.perception.assignment`) on the squared Mahalanobis distance to the
   predicted position (innovation covariance: predicted position covariance + std^2 I),
   never across the chi-square ``gate`` or ``max_distance``; the most pairs first, then the
   least summed distance. The solver only sees the ambiguous part of the gating graph;
   pairs with no rival are taken directly (same result);
4. pairs leftover tracks and detections, closest first, under the looser ``reacquire_gate``
   (and ``max_distance``); otherwise a detection just outside the gate (1% for a 99% gate,
   more when people turn) starts a duplicate track that takes turns with the original;
5. updates paired tracks (covariance shrinks), coasts the others and starts a track at rest
   for each remaining detection while capacity lasts.

Ids come from a counter never reused within an episode. The state lives in preallocated
arrays of capacity ``max_tracks`` (live tracks in creation order), updated by one compiled
call per step (:mod:`srpb_gym.perception.kalman`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from srpb_gym.config import from_spec
from srpb_gym.perception.kalman import (
    F_AGE,
    F_TSU,
    F_YAW,
    I_DET,
    I_HITS,
    I_ID,
    N_LAST_REFUSED,
    N_LIVE,
    N_NEXT_ID,
    N_REFUSED,
    N_VISIBLE,
    fuse,
)

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
        self._cnt = np.zeros(5, dtype=np.int64)
        self._scratch = np.zeros((4, 4))
        self._pairs = np.zeros((2, cap), np.int64)  # solver output: rows, columns
        self._bind()
        self._reserve(cap)
        self.reset()

    # derived from the state arrays: argument tuples and read-only views
    _DERIVED = ("arrays", "_state", "_ro_x", "_ro_P", "_ro_f", "_ro_i", "_ro_matched")

    def _bind(self) -> None:
        """The argument tuples and read-only views of the state arrays (at construction and
        after a copy or unpickling, where a copied view would no longer follow its array)."""
        #: the state arrays (x, P, f, iv, cnt, cfg) for compiled readers; see
        #: :mod:`srpb_gym.perception.kalman` for their layout
        self.arrays = (self._x, self._P, self._f, self._i, self._cnt, self._cfg)
        self._state = (self._x, self._P, self._f, self._i, self._matched)
        views = [a.view() for a in (self._x, self._P, self._f, self._i, self._matched)]
        for v in views:
            v.flags.writeable = False
        self._ro_x, self._ro_P, self._ro_f, self._ro_i, self._ro_matched = views

    def __getstate__(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if k not in self._DERIVED}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind()

    def _reserve(self, detections: int) -> None:
        """Size the per-detection workspace for ``detections`` detections."""
        cap = self._x.shape[0]
        self._dcap = detections
        self._work = (self._cfg, self._cnt, np.zeros((cap, detections)), self._wt,
                      np.zeros((3, detections), dtype=np.int64), np.zeros(cap * detections),
                      self._scratch, self._pairs)  # fmt: skip

    def reset(self) -> None:
        """Forget all tracks and restart ids at 0 (a new episode)."""
        self._cnt[:] = 0

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
        return self.fuse(float(dt), xy, yaw, std, xy.shape[0])

    def fuse(self, dt: float, xy: np.ndarray, yaw: np.ndarray, std: np.ndarray, D: int) -> int:
        """:meth:`step` on the first ``D`` rows of float64 C-contiguous ``xy`` (>= D, 2),
        ``yaw`` and ``std`` (>= D,) as they are (a detector's buffers), ``dt`` a float."""
        if self._dcap < D:
            self._reserve(max(D, 2 * self._dcap))
        k = fuse(dt, *self._state, xy, yaw, std, D, *self._work)
        if k < 0:
            raise ValueError(_ERRORS[-k])
        return k

    @property
    def _sel(self) -> slice | np.ndarray:
        """The reported (confirmed) tracks among the live ones."""
        n = self._cnt[N_LIVE]
        if self._cnt[N_VISIBLE] == n:
            return slice(0, n)
        return np.flatnonzero(self._i[I_HITS, :n] >= self.config.min_hits)

    def __len__(self) -> int:
        """Number of reported tracks."""
        return int(self._cnt[N_VISIBLE])

    num_live = property(lambda self: int(self._cnt[N_LIVE]), doc="Live tracks, confirmed or not.")
    next_id = property(lambda self: int(self._cnt[N_NEXT_ID]), doc="Id of the next new track.")
    refused = property(
        lambda self: int(self._cnt[N_REFUSED]),
        doc="Detections that started no track (capacity full) this episode.",
    )
    last_refused = property(
        lambda self: int(self._cnt[N_LAST_REFUSED]),
        doc="Detections that started no track (capacity full) in the last step.",
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
        s, x, f, i = self._sel, self._ro_x, self._ro_f, self._ro_i
        return Tracks(
            i[I_ID, s], x[s, :2], x[s, 2:], f[F_YAW, s], self._ro_P[s, :2, :2], f[F_AGE, s],
            f[F_TSU, s], self._ro_matched[s], i[I_DET, s],
        )  # fmt: skip
