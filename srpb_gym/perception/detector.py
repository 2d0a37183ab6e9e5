"""A noisy people detector: which people the robot sees this step and where it measures them.

A person is detected when its centre lies within [range_min, range_max] of the robot centre
and within +-fov/2 of the robot heading, nothing blocks the line of sight (with
``occlusion``: walls and other bodies) and a uniform draw is at least ``miss_probability``.
A detection reports the global position with isotropic Gaussian noise whose standard
deviation grows with the range, and the yaw with Gaussian noise (wrapped to (-pi, pi]).

Every call draws the same numbers from the generator (``P`` uniforms, then ``3 P`` standard
normals, for ``P`` people), whoever is visible, so runs are reproducible.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from srpb_gym.angles import wrap_angle
from srpb_gym.config import from_spec
from srpb_gym.sim.geometry import segment_clear

__all__ = ["PRESETS", "Detections", "DetectorConfig", "PeopleDetector", "visible_people"]

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class DetectorConfig:
    """Sensing limits and noise of the people detector (defaults: preset ``camera``)."""

    fov: float = math.radians(60.0)  # rad, angular span centred on the heading
    range_min: float = 0.6  # m, nearest detectable person centre
    range_max: float = 8.0  # m, farthest detectable person centre (may be inf)
    miss_probability: float = 0.05  # chance to miss a visible person, per person per step
    noise_std: float = 0.03  # m, position noise standard deviation at zero range
    noise_per_meter: float = 0.02  # m/m, growth of the position noise std with the range
    yaw_noise_std: float = 0.2  # rad, standard deviation of the yaw noise
    occlusion: bool = True  # walls and other bodies block the line of sight

    def __post_init__(self) -> None:
        if not 0.0 < self.fov <= TWO_PI + 1e-6:
            raise ValueError(f"fov must be in (0, 2 pi] rad, got {self.fov!r}")
        if not 0.0 <= self.range_min < self.range_max:
            raise ValueError(
                "ranges must satisfy 0 <= range_min < range_max, got "
                f"range_min={self.range_min!r}, range_max={self.range_max!r}"
            )
        if not 0.0 <= self.miss_probability <= 1.0:
            raise ValueError(f"miss_probability must be in [0, 1], got {self.miss_probability!r}")
        for name in ("noise_std", "noise_per_meter", "yaw_noise_std"):
            value = getattr(self, name)
            if not (value >= 0.0 and math.isfinite(value)):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        if not isinstance(self.occlusion, (bool, np.bool_)):
            raise ValueError(f"occlusion must be true or false, got {self.occlusion!r}")

    @classmethod
    def from_spec(
        cls, spec: str | Mapping[str, Any] | DetectorConfig | None, path: str = "",
        file: str | None = None,
    ) -> DetectorConfig:  # fmt: skip
        """A config from a preset name, a mapping (optional ``preset:`` base), an instance
        or ``None`` (the ``"default"`` preset, ``camera``)."""
        return from_spec(cls, spec, PRESETS, path, file)


_CAMERA = DetectorConfig()
PRESETS: dict[str, DetectorConfig] = {
    "default": _CAMERA,
    # An RGB-D camera looking ahead.
    "camera": _CAMERA,
    # A leg/body detector on a 2-D lidar all around.
    "lidar": DetectorConfig(
        fov=TWO_PI,
        range_min=0.1,
        range_max=10.0,
        miss_probability=0.1,
        noise_std=0.05,
        noise_per_meter=0.01,
        yaw_noise_std=0.5,
    ),
    # Ground truth: everyone, exactly, through walls.
    "perfect": DetectorConfig(
        fov=TWO_PI,
        range_min=0.0,
        range_max=math.inf,
        miss_probability=0.0,
        noise_std=0.0,
        noise_per_meter=0.0,
        yaw_noise_std=0.0,
        occlusion=False,
    ),
}


class Detections(NamedTuple):
    """The people detected in one step (D of them), as fresh arrays.

    ``index`` is the ground-truth index of each detected person, for evaluation only (a
    tracker must not use it).
    """

    index: np.ndarray  # (D,) int64
    xy: np.ndarray  # (D, 2) measured global positions [m]
    yaw: np.ndarray  # (D,) measured yaw [rad], in (-pi, pi]
    std: np.ndarray  # (D,) position noise standard deviation used [m]


@njit(cache=True, error_model="numpy")
def visible_people(
    x: float, y: float, yaw: float, people_xy: np.ndarray, half_fov: float, range_min: float,
    range_max: float, occlusion: bool, segs: np.ndarray, circles: np.ndarray, skip: int,
    people_circle: np.ndarray, out: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """``out[p] = True`` when person p's centre is within [range_min, range_max] [m] of
    (x, y), within +-half_fov [rad] of ``yaw`` and, with ``occlusion``, in line of sight
    (no wall, no circle but ``skip`` and ``people_circle[p]`` in between). Returns ``out``."""
    all_around = half_fov >= math.pi
    for p in range(people_xy.shape[0]):
        px = people_xy[p, 0]
        py = people_xy[p, 1]
        dx = px - x
        dy = py - y
        d = math.hypot(dx, dy)
        seen = range_min <= d <= range_max
        if seen and not all_around:
            seen = abs(wrap_angle(math.atan2(dy, dx) - yaw)) <= half_fov
        if seen and occlusion:
            seen = segment_clear(x, y, px, py, segs, circles, skip, people_circle[p])
        out[p] = seen
    return out


@njit(cache=True, error_model="numpy")
def detect_kernel(
    x: float, y: float, yaw: float, people_xy: np.ndarray, people_yaw: np.ndarray,
    segs: np.ndarray, circles: np.ndarray, skip: int, people_circle: np.ndarray,
    limits: np.ndarray, occlusion: bool, uniform: np.ndarray, normal: np.ndarray,
    visible: np.ndarray, index: np.ndarray, xy: np.ndarray,
    yaw_out: np.ndarray, std: np.ndarray,
) -> int:  # fmt: skip
    """Fill ``visible`` (see :func:`visible_people`), then write the detections of the
    visible people not missed into the first rows of ``index``, ``xy``, ``yaw_out`` and
    ``std``; return how many there are. ``normal`` (P, 3): standard normals for x, y, yaw.
    ``limits``: half fov [rad], range_min [m],
    range_max [m], miss probability, noise std [m], noise per meter [m/m], yaw noise [rad]."""
    visible_people(x, y, yaw, people_xy, limits[0], limits[1], limits[2], occlusion, segs,
                   circles, skip, people_circle, visible)  # fmt: skip
    n = 0
    for p in range(people_xy.shape[0]):
        if not visible[p] or uniform[p] < limits[3]:
            continue
        px = people_xy[p, 0]
        py = people_xy[p, 1]
        s = limits[4] + limits[5] * math.hypot(px - x, py - y)
        index[n] = p
        xy[n, 0] = px + s * normal[p, 0]
        xy[n, 1] = py + s * normal[p, 1]
        yaw_out[n] = wrap_angle(people_yaw[p] + limits[6] * normal[p, 2])
        std[n] = s
        n += 1
    return n


class PeopleDetector:
    """Detects people around a robot (see :class:`DetectorConfig` and the module notes)."""

    def __init__(self, config: DetectorConfig | str | Mapping[str, Any] | None = None) -> None:
        self.config = DetectorConfig.from_spec(config)
        cfg = self.config
        half_fov = math.pi if cfg.fov >= TWO_PI - 1e-6 else 0.5 * cfg.fov  # 2 pi: all around
        self._limits = np.array([
            half_fov, cfg.range_min, cfg.range_max, cfg.miss_probability, cfg.noise_std,
            cfg.noise_per_meter, cfg.yaw_noise_std,
        ])  # fmt: skip
        self._resize(0)

    def _resize(self, n: int) -> None:
        self._size = n
        self.visible = np.zeros(n, dtype=np.bool_)  # line of sight of the last call
        self._uniform = np.empty(n)
        self._normal = np.empty((n, 3))
        self._index = np.empty(n, dtype=np.int64)
        self._xy = np.empty((n, 2))
        self._yaw = np.empty(n)
        self._std = np.empty(n)
        self._no_circle = np.full(n, -1, dtype=np.int64)
        #: what :func:`detect_kernel` takes after the people circles: limits, occlusion,
        #: the draws, then the outputs (visible, then the first rows of index, xy, yaw, std)
        self.arrays = (self._limits, bool(self.config.occlusion), self._uniform, self._normal,
                       self.visible, self._index, self._xy, self._yaw, self._std)  # fmt: skip

    def draw(self, rng: np.random.Generator, people: int) -> None:
        """Draw the numbers of the next detection of ``people`` people: ``people``
        uniforms, then ``3 people`` standard normals."""
        if people != self._size:
            self._resize(people)
        rng.random(out=self._uniform)
        rng.standard_normal(out=self._normal)

    def detect(
        self,
        x: float,
        y: float,
        yaw: float,
        people_xy: np.ndarray,
        people_yaw: np.ndarray,
        circles: np.ndarray,
        skip: int,
        people_circle: np.ndarray | None,
        segs: np.ndarray,
        rng: np.random.Generator,
    ) -> Detections:
        """The people detected from robot pose (x, y, yaw) this step.

        ``people_xy`` (P, 2) and ``people_yaw`` (P,) are the true people states (float64),
        ``people_circle`` (P,) int64 the index of each person's circle in ``circles``
        (``None``: no person has one), ``skip`` the robot's own circle. After the call,
        ``self.visible`` (P,) tells who was in view before the miss draw.
        """
        self.draw(rng, people_xy.shape[0])
        if people_circle is None:
            people_circle = self._no_circle
        d = detect_kernel(float(x), float(y), float(yaw), people_xy, people_yaw, segs, circles,
                          int(skip), people_circle, *self.arrays)  # fmt: skip
        return Detections(
            self._index[:d].copy(), self._xy[:d].copy(), self._yaw[:d].copy(), self._std[:d].copy()
        )
