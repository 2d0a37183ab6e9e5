"""Helpers shared by test modules (``from tests.helpers import same``)."""

from __future__ import annotations

import math

import numpy as np


def same(a, b) -> bool:
    """Equal bit for bit: same keys, types and values, NaN equal to NaN."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)
    return type(a) is type(b) and a == b
