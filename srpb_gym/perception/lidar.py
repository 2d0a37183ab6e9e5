"""A planar lidar: one ray per beam against the walls and the body circles, with range noise.

The scan is computed by one compiled call (:func:`srpb_gym.sim.geometry.raycast`) for all
beams, then Gaussian range noise is added and the ranges are clipped to the sensor limits.
A beam that hits nothing within ``range_max`` reads exactly ``range_max`` (never ``inf`` and
never noisy), so a scan can be fed to a network as it is.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from srpb_gym.config import from_spec
from srpb_gym.sim.geometry import raycast_beams

__all__ = ["PRESETS", "Lidar", "LidarConfig", "beam_angles"]

TWO_PI = 2.0 * math.pi
# A field of view within this much of 2 pi [rad] is a full turn (e.g. 6.283185 in a file).
FULL_TURN_TOLERANCE = 1e-6


@dataclass(frozen=True)
class LidarConfig:
    """A planar lidar mounted at the robot centre, beams symmetric around the heading.

    Defaults: 180 deg in front, 181 beams (1 deg apart), 0.05-25 m, 1 cm range noise.
    """

    fov: float = math.pi  # rad, angular span of the beams (2 pi: all around)
    n_beams: int = 181  # number of beams
    range_min: float = 0.05  # m, readings are clipped up to this
    range_max: float = 25.0  # m, readings are clipped down to this; no hit reads this
    noise_std: float = 0.01  # m, standard deviation of the Gaussian range noise

    def __post_init__(self) -> None:
        if isinstance(self.n_beams, bool) or not isinstance(self.n_beams, (int, np.integer)):
            raise ValueError(f"n_beams must be an integer, got {self.n_beams!r}")
        if self.n_beams < 1:
            raise ValueError(f"n_beams must be at least 1, got {self.n_beams}")
        if not 0.0 < self.fov <= TWO_PI + FULL_TURN_TOLERANCE:
            raise ValueError(f"fov must be in (0, 2 pi] rad, got {self.fov!r}")
        if not (0.0 <= self.range_min < self.range_max and math.isfinite(self.range_max)):
            raise ValueError(
                "ranges must satisfy 0 <= range_min < range_max < inf, got "
                f"range_min={self.range_min!r}, range_max={self.range_max!r}"
            )
        if not (self.noise_std >= 0.0 and math.isfinite(self.noise_std)):
            raise ValueError(f"noise_std must be finite and >= 0, got {self.noise_std!r}")

    @property
    def full_turn(self) -> bool:
        """Whether the beams go all around (``fov`` is 2 pi)."""
        return self.fov >= TWO_PI - FULL_TURN_TOLERANCE

    @classmethod
    def from_spec(
        cls, spec: str | Mapping[str, Any] | LidarConfig | None, path: str = "",
        file: str | None = None,
    ) -> LidarConfig:  # fmt: skip
        """A config from a preset name, a mapping (optional ``preset:`` base), an instance
        or ``None`` (the ``"default"`` preset)."""
        return from_spec(cls, spec, PRESETS, path, file)


PRESETS: dict[str, LidarConfig] = {
    "default": LidarConfig(),
    # Like the robot of the SRPB paper: 180 deg in front, 0.05-25 m.
    "paper": LidarConfig(),
    "wide": LidarConfig(fov=TWO_PI, n_beams=360, range_min=0.1, range_max=10.0),
}


def beam_angles(config: LidarConfig) -> np.ndarray:
    """Beam angles [rad] relative to the heading, increasing, symmetric around 0.

    A partial field of view spans ``[-fov/2, fov/2]`` end to end. A full turn has ``n_beams``
    beams ``2 pi / n_beams`` apart with one straight ahead, so the rear beam (+-pi, for an even
    count) appears once, as -pi.
    """
    n = config.n_beams
    if n == 1:
        return np.zeros(1)
    if config.full_turn:
        return np.clip((np.arange(n) - n // 2) * (TWO_PI / n), -math.pi, math.pi)
    return np.linspace(-0.5 * config.fov, 0.5 * config.fov, n)


@njit(cache=True, error_model="numpy")
def scan_kernel(
    x: float, y: float, yaw: float, segs: np.ndarray, circles: np.ndarray, skip: int,
    angles: np.ndarray, beam_dirs: np.ndarray, params: np.ndarray, noise: np.ndarray,
    true: np.ndarray, out: np.ndarray,
) -> None:  # fmt: skip
    """Ray-cast ``true``, then ``out = clip(true + std * noise, range_min, range_max)``
    (``params``: std, range_min, range_max); beams that hit nothing stay at exactly
    ``range_max``."""
    std, range_min, range_max = params[0], params[1], params[2]
    raycast_beams(x, y, yaw, angles, beam_dirs, range_max, segs, circles, skip, true)
    for b in range(true.shape[0]):
        r = true[b]
        if r < range_max:
            r = min(max(r + std * noise[b], range_min), range_max)
        out[b] = r


class Lidar:
    """A planar lidar at the robot centre (see :class:`LidarConfig`).

    Attributes:
        config: the sensor parameters.
        angles: beam angles relative to the robot heading [rad], shape (n_beams,).
        true_ranges: the noise-free ranges of the last scan [m] (a reused buffer).
    """

    def __init__(self, config: LidarConfig | str | Mapping[str, Any] | None = None) -> None:
        self.config = LidarConfig.from_spec(config)
        self.angles = beam_angles(self.config)
        self.angles.setflags(write=False)
        self._beam_dirs = np.column_stack([np.cos(self.angles), np.sin(self.angles)])
        n = self.config.n_beams
        self.true_ranges = np.empty(n)
        self._noise = np.zeros(n)
        self._out = np.empty(n)
        cfg = self.config
        params = np.array([cfg.noise_std, cfg.range_min, cfg.range_max])
        #: what :func:`scan_kernel` takes after the pose and the obstacles: beam angles and
        #: directions, noise std and range limits, noise, true ranges, output ranges
        self.arrays = (self.angles, self._beam_dirs, params, self._noise, self.true_ranges,
                       self._out)  # fmt: skip

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)  # a copied array is writeable again
        self.angles.setflags(write=False)

    def draw(self, rng: np.random.Generator | None) -> None:
        """Draw the range noise of the next scan (``n_beams`` standard normals from ``rng``,
        none without noise)."""
        if self.config.noise_std > 0.0:
            if rng is None:
                raise ValueError("a noisy lidar needs a numpy Generator (rng)")
            rng.standard_normal(out=self._noise)

    @property
    def n_beams(self) -> int:
        return self.config.n_beams

    def scan(
        self,
        x: float,
        y: float,
        yaw: float,
        segs: np.ndarray,
        circles: np.ndarray,
        skip: int,
        rng: np.random.Generator | None,
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Ranges [m] of one scan from pose (x, y, yaw), shape (n_beams,).

        True range plus Gaussian noise of ``noise_std``, clipped to [range_min, range_max];
        a beam that hits nothing reads ``range_max``. Circle ``skip`` (the robot's own body)
        is ignored. Draws ``n_beams`` standard normals from ``rng`` when ``noise_std > 0``
        (``rng`` may be ``None`` otherwise). Without ``out`` the result is an internal
        buffer overwritten by the next scan: copy it to keep it.
        """
        self.draw(rng)
        angles, dirs, params, noise, true, own = self.arrays
        scan_kernel(float(x), float(y), float(yaw), segs, circles, int(skip), angles, dirs,
                    params, noise, true, own if out is None else out)  # fmt: skip
        return own if out is None else out

    def hit_points(
        self, x: float, y: float, yaw: float, ranges: np.ndarray, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Global end points (n_beams, 2) of the beams of a scan taken at (x, y, yaw)."""
        a = yaw + self.angles
        if out is None:
            out = np.empty((self.angles.shape[0], 2))
        np.multiply(ranges, np.cos(a), out=out[:, 0])
        np.multiply(ranges, np.sin(a), out=out[:, 1])
        out[:, 0] += x
        out[:, 1] += y
        return out
