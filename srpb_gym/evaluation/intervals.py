"""Confidence intervals and multiple-test correction of the evaluation's statistics.

* :func:`wilson`: the Wilson score 95 % interval of a rate (success, collision, timeout).
* :func:`bootstrap_median`: the percentile bootstrap 95 % interval of a median:
  :data:`RESAMPLES` resamples drawn by ``numpy.random.default_rng(SEED)``, afresh for every
  interval, so the same values always give the same interval.
* :func:`paired_rate_difference`: Newcombe's score interval (his method 10) of the
  difference of two rates measured on the same episodes (success of planner B minus
  planner A); a bootstrap of 0/1 differences collapses to [0, 0] when no pair differs.
* :func:`holm`: Holm's step-down correction of a family of p-values.

Every function says "not computed" (``None``) rather than give an interval its values do
not carry: no value, or (bootstrap) fewer than :data:`MIN_BOOTSTRAP` of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

Z95 = 1.959963984540054
"""The standard normal quantile of 0.975: a two-sided 95 % interval."""
RESAMPLES = 10_000
SEED = 0
MIN_BOOTSTRAP = 2
"""Fewest values a bootstrap interval is computed from (one value resamples to itself)."""
_CHUNK = 4_000_000  # resampled values drawn at a time (memory: 8 bytes each)

Interval = tuple[float, float]


def wilson(successes: int, n: int, z: float = Z95) -> Interval | None:
    """The Wilson score interval of ``successes`` out of ``n`` trials, in % (0-100);
    ``None`` when ``n`` is 0."""
    if n <= 0:
        return None
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be in [0, {n}], got {successes}")
    p = successes / n
    z2 = z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z / (1 + z2 / n) * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n))
    low, high = max(0.0, centre - half), min(1.0, centre + half)
    if successes == 0:
        low = 0.0
    if successes == n:
        high = 1.0
    return 100.0 * low, 100.0 * high


def paired_rate_difference(both: int, a_only: int, b_only: int, neither: int,
                           z: float = Z95) -> Interval | None:  # fmt: skip
    """Newcombe's hybrid score 95 % interval (1998, method 10) of ``p_B - p_A`` [points,
    -100..100] for paired outcomes: ``both`` pairs where A and B succeeded, ``a_only``
    where only A did, ``b_only`` only B, ``neither``; ``None`` without a pair.

    With the Wilson intervals (l_A, u_A), (l_B, u_B) of the two rates and phi the
    correlation of the 2x2 table (0 when a margin is empty), the bounds are
    ``D - sqrt((p_B - l_B)^2 - 2 phi (p_B - l_B)(u_A - p_A) + (u_A - p_A)^2)`` and
    ``D + sqrt((u_B - p_B)^2 - 2 phi (u_B - p_B)(p_A - l_A) + (p_A - l_A)^2)``."""
    n = both + a_only + b_only + neither
    if n <= 0:
        return None
    if a_only + b_only == 0:
        # no pair differs: method 10 collapses to [0, 0] where both rates are away from 0
        # and 100 %; the difference is then bounded by how many pairs could differ, the
        # Wilson upper bound of 0 discordant pairs in n, either way
        bound = wilson(0, n, z)[1]  # type: ignore[index]
        return -bound, bound
    pa, pb = (both + a_only) / n, (both + b_only) / n
    la, ua = (v / 100.0 for v in wilson(both + a_only, n, z))  # type: ignore[misc]
    lb, ub = (v / 100.0 for v in wilson(both + b_only, n, z))  # type: ignore[misc]
    margins = (both + a_only) * (b_only + neither) * (both + b_only) * (a_only + neither)
    phi = 0.0 if margins == 0 else (both * neither - a_only * b_only) / math.sqrt(margins)
    d = pb - pa
    low = d - math.sqrt(max(0.0, (pb - lb) ** 2 - 2 * phi * (pb - lb) * (ua - pa)
                            + (ua - pa) ** 2))  # fmt: skip
    high = d + math.sqrt(max(0.0, (ub - pb) ** 2 - 2 * phi * (ub - pb) * (pa - la)
                             + (pa - la) ** 2))  # fmt: skip
    return 100.0 * max(-1.0, low), 100.0 * min(1.0, high)


def finite(values: Sequence[float] | np.ndarray) -> np.ndarray:
    """The finite values of ``values`` as a float64 array."""
    x = np.asarray(values, dtype=np.float64).ravel()
    return x[np.isfinite(x)]


def _bootstrap(
    values: Sequence[float] | np.ndarray,
    statistic: Callable[[np.ndarray], np.ndarray],
    resamples: int,
    seed: int,
) -> Interval | None:
    x = finite(values)
    n = x.size
    if n < MIN_BOOTSTRAP:
        return None
    if np.all(x == x[0]):  # every resample is the same
        return float(x[0]), float(x[0])
    rng = np.random.default_rng(seed)
    out = np.empty(resamples)
    step = max(1, _CHUNK // n)
    for start in range(0, resamples, step):
        stop = min(resamples, start + step)
        idx = rng.integers(0, n, size=(stop - start, n))
        out[start:stop] = statistic(x[idx])
    low, high = np.percentile(out, [2.5, 97.5])
    return float(low), float(high)


def bootstrap_median(
    values: Sequence[float] | np.ndarray, resamples: int = RESAMPLES, seed: int = SEED
) -> Interval | None:
    """The percentile bootstrap 95 % interval of the median of the finite ``values``;
    ``None`` for fewer than :data:`MIN_BOOTSTRAP` of them."""
    return _bootstrap(values, lambda r: np.median(r, axis=1), resamples, seed)


def bootstrap_mean(
    values: Sequence[float] | np.ndarray, resamples: int = RESAMPLES, seed: int = SEED
) -> Interval | None:
    """The percentile bootstrap 95 % interval of the mean of the finite ``values``;
    ``None`` for fewer than :data:`MIN_BOOTSTRAP` of them."""
    return _bootstrap(values, lambda r: r.mean(axis=1), resamples, seed)


def holm(pvalues: Sequence[float | None]) -> list[float | None]:
    """Holm's step-down adjusted p-values of one family of tests, in the order given.

    With the m p-values sorted, p_(1) <= ... <= p_(m), the adjusted p_(i) is
    ``max_{j <= i} min(1, (m - j + 1) p_(j))``; a test is significant at level alpha after
    correction when its adjusted p-value is below alpha. ``None`` (a test not computed) stays
    ``None`` and does not count in m."""
    present = [(p, i) for i, p in enumerate(pvalues) if p is not None and math.isfinite(p)]
    out: list[float | None] = [None] * len(pvalues)
    m = len(present)
    running = 0.0
    for rank, (p, i) in enumerate(sorted(present)):
        running = max(running, min(1.0, (m - rank) * p))
        out[i] = running
    return out
