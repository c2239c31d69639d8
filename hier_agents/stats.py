"""Small statistics for result tables.

Across seeds (`hier_agents.compare.report`): each seed's success rate is the
share of its episodes that succeeded; the mean over seeds comes with a
percentile-bootstrap interval over the per-seed rates
(`bootstrap_interval`), and the interquartile mean (`iqm`) with a
**stratified bootstrap** interval (`stratified_interval`): the strata are
the seeds, and each of ``resamples`` resamples draws every seed's episodes
with replacement *within that seed* (as many as it has), recomputes each
seed's success rate from its drawn episodes, and takes the IQM over the
seeds; the interval is the 2.5th and 97.5th percentiles of those IQMs.
Across environments (`aggregate_interval`, rliable's aggregate, Agarwal et
al. 2021): the strata are the environments, each resample draws every
environment's runs (per-seed rates) with replacement within that
environment, and the statistic is taken over all drawn runs together.
Every resampler is seeded (the same input gives the same interval).
"""

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


def _iqm_weights(n: int):
    """The weight of each sorted value in the IQM of ``n`` values (summing to 1)."""
    import numpy as np

    low, high = 0.25 * n, 0.75 * n
    i = np.arange(n)
    return np.clip(np.minimum(i + 1, high) - np.maximum(i, low), 0.0, None) / (high - low)


def iqm(values) -> float:
    """The interquartile mean (IQM, as in rliable, Agarwal et al. 2021): the
    mean of the middle half of the sorted ``values``, trimmed by fraction (a
    value straddling the 25% or 75% position counts by the share of it
    inside: with 3 values, 1/4 + 1 + 1/4). NaN for an empty sample."""
    x = sorted(float(v) for v in values)
    if not x:
        return float("nan")
    return float(sum(w * v for w, v in zip(_iqm_weights(len(x)), x)))


def iqm_rows(matrix):
    """`iqm` of each row of a 2-D array (shape ``[rows, n]``, ``n`` >= 1):
    a 1-D array of ``rows`` values."""
    import numpy as np

    matrix = np.asarray(matrix, dtype=float)
    return np.sort(matrix, axis=1) @ _iqm_weights(matrix.shape[1])


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


#: The statistics the stratified resamplers take by name: a function of a
#: ``[resamples, n]`` array giving one value per row.
ROW_STATISTICS = {"iqm": iqm_rows, "mean": lambda m: m.mean(axis=1)}


def _strata(strata, what: str) -> list:
    """``strata`` as a list of non-empty float arrays.

    Raises:
      ValueError: no strata, or an empty one (``what`` names them).
    """
    import numpy as np

    out = [np.asarray([float(v) for v in s], dtype=float) for s in strata]
    if not out or any(s.size == 0 for s in out):
        raise ValueError(f"give at least one {what}, each non-empty")
    return out


def _percentiles(stats, level: float) -> tuple[float, float]:
    import numpy as np

    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    tail = 100 * (1.0 - level) / 2
    lo, hi = np.percentile(stats, [tail, 100 - tail])
    return float(lo), float(hi)


def stratified_replicates(
    episodes_by_seed, statistic: str = "iqm", *, resamples: int = 10_000, seed: int = 0
):
    """The stratified bootstrap's replicates (a 1-D array of ``resamples``
    values) of ``statistic`` (a `ROW_STATISTICS` name) over seeds.

    ``episodes_by_seed``: one sequence per seed (the strata) of episode
    outcomes (1 success, 0 failure; any numbers work). Each replicate draws,
    for every seed, as many episodes as it has with replacement from that
    seed's episodes only, takes each seed's mean of its drawn episodes (its
    success rate) and the statistic over the seeds' rates. The generator is
    ``numpy.random.default_rng(seed)``; the seeds are drawn in the given order.

    Raises:
      ValueError: no seeds, a seed without episodes, an unknown statistic,
        or ``resamples`` < 1.
    """
    import numpy as np

    reduce = ROW_STATISTICS[statistic]
    drawn = _draw_within(episodes_by_seed, "seed's episodes", resamples, seed)
    return reduce(np.stack([x.mean(axis=1) for x in drawn], axis=1))


def stratified_interval(
    episodes_by_seed,
    statistic: str = "iqm",
    *,
    level: float = 0.95,
    resamples: int = 10_000,
    seed: int = 0,
) -> tuple[float, float]:
    """The percentile interval (``level``, 95% by default) of
    `stratified_replicates`: episodes resampled within each seed, the
    statistic over the seeds' success rates. A seed with one outcome
    repeated, in every seed, gives a zero-width interval at the statistic.

    Raises:
      ValueError: as `stratified_replicates`, or ``level`` outside (0, 1).
    """
    reps = stratified_replicates(episodes_by_seed, statistic, resamples=resamples, seed=seed)
    return _percentiles(reps, level)


def aggregate_replicates(
    runs_by_env, statistic: str = "iqm", *, resamples: int = 10_000, seed: int = 0
):
    """rliable's stratified bootstrap over environments (1-D array of
    ``resamples`` replicates): ``runs_by_env`` is one sequence per
    environment (the strata) of run scores (one success rate per seed);
    each replicate draws every environment's runs with replacement within
    that environment (as many as it has) and takes ``statistic`` (a
    `ROW_STATISTICS` name) over all the drawn runs together.

    Raises:
      ValueError: no environments, one without runs, an unknown statistic,
        or ``resamples`` < 1.
    """
    import numpy as np

    reduce = ROW_STATISTICS[statistic]
    drawn = _draw_within(runs_by_env, "environment's runs", resamples, seed)
    return reduce(np.concatenate(drawn, axis=1))


def _draw_within(strata, what: str, resamples: int, seed: int) -> list:
    """Each stratum's values drawn with replacement within the stratum: one
    ``[resamples, n]`` array per stratum of ``n`` values, in the given
    order, from ``numpy.random.default_rng(seed)``.

    Raises:
      ValueError: ``resamples`` < 1, or as `_strata` (``what`` names a stratum).
    """
    import numpy as np

    if resamples < 1:
        raise ValueError(f"resamples must be >= 1, got {resamples!r}")
    rng = np.random.default_rng(seed)
    return [x[rng.integers(0, x.size, size=(resamples, x.size))] for x in _strata(strata, what)]


def aggregate_interval(
    runs_by_env,
    statistic: str = "iqm",
    *,
    level: float = 0.95,
    resamples: int = 10_000,
    seed: int = 0,
) -> tuple[float, float]:
    """The percentile interval (``level``) of `aggregate_replicates`.

    Raises:
      ValueError: as `aggregate_replicates`, or ``level`` outside (0, 1).
    """
    return _percentiles(
        aggregate_replicates(runs_by_env, statistic, resamples=resamples, seed=seed), level
    )
