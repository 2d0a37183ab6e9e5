"""Angle wrapping, the one definition every module uses."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi


@njit(cache=True, inline="always", error_model="numpy")
def wrap_angle(a: Any) -> Any:
    """``a`` [rad] mapped to (-pi, pi]; a float or an array (elementwise).

    Angles already in (-pi, pi] are returned unchanged, bit for bit (within one rounding
    of -pi the result may be pi plus one ulp). Compiled with numba, so kernels inline it
    and Python code calls it directly.
    """
    return a - TWO_PI * np.ceil((a - math.pi) / TWO_PI)
