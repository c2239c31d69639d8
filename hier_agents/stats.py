"""Small statistics for result tables."""

from __future__ import annotations

import math


def wilson_interval(successes: int, trials: int, z: float = 1.959964) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion (95% by default).

    Returns ``(nan, nan)`` for zero trials.
    """
    if trials <= 0:
        return float("nan"), float("nan")
    if not 0 <= successes <= trials:
        raise ValueError(f"successes must be in 0..{trials}, got {successes}")
    p = successes / trials
    denom = 1 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denom
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def iqm(values) -> float:
    """The interquartile mean (IQM, as in rliable, Agarwal et al. 2021): the
    mean of the middle half of the sorted ``values``, trimmed by fraction (a
    value straddling the 25% or 75% position counts by the share of it
    inside: with 3 values, 1/4 + 1 + 1/4). NaN for an empty sample."""
    x = sorted(float(v) for v in values)
    n = len(x)
    if n == 0:
        return float("nan")
    low, high = 0.25 * n, 0.75 * n
    total = 0.0
    for i, v in enumerate(x):
        weight = max(0.0, min(i + 1, high) - max(i, low))
        total += weight * v
    return total / (high - low)


def bootstrap_interval(
    values, statistic=None, *, level: float = 0.95, resamples: int = 10_000, seed: int = 0
) -> tuple[float, float]:
    """Percentile bootstrap interval of ``statistic`` (default: the mean) over
    ``values`` (e.g. one success rate per seed), ``resamples`` draws with
    replacement from a generator seeded with ``seed`` (the same input gives
    the same interval). One value gives (v, v); none gives (nan, nan).

    Raises:
      ValueError: ``level`` outside (0, 1) or ``resamples`` < 1.
    """
    import numpy as np

    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    if resamples < 1:
        raise ValueError(f"resamples must be >= 1, got {resamples!r}")
    x = np.asarray([float(v) for v in values], dtype=float)
    if x.size == 0:
        return float("nan"), float("nan")
    if x.size == 1:
        return float(x[0]), float(x[0])
    rng = np.random.default_rng(seed)
    draws = x[rng.integers(0, x.size, size=(resamples, x.size))]
    if statistic is None:
        stats = draws.mean(axis=1)
    else:
        stats = np.apply_along_axis(statistic, 1, draws)
    tail = 100 * (1.0 - level) / 2
    lo, hi = np.percentile(stats, [tail, 100 - tail])
    return float(lo), float(hi)
