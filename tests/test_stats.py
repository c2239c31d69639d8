"""`hier_agents.stats`: the IQM, the stratified bootstrap over seeds and the
aggregate over environments, against cases small enough to enumerate."""

from __future__ import annotations

import itertools
from collections import Counter
from fractions import Fraction

import numpy as np
import pytest

from hier_agents.stats import (
    aggregate_interval,
    aggregate_replicates,
    iqm,
    iqm_rows,
    stratified_interval,
    stratified_replicates,
)


def test_iqm_by_hand():
    # n = 4: the middle two; n = 3: 1/4 of the outer ones and all of the middle one, over 1.5.
    assert iqm([9, 1, 2, 0]) == pytest.approx(1.5)
    assert iqm([0, 0.5, 1]) == pytest.approx((0 + 0.5 + 0.25) / 1.5)
    assert iqm([0, 1]) == pytest.approx(0.5)  # n = 2: half of each
    assert iqm([7]) == 7.0 and np.isnan(iqm([]))
    rows = iqm_rows([[1, 0, 0.5], [0, 4, 0]])
    assert rows == pytest.approx([0.5, 4 / 6])


def _exact_iqm_distribution(strata) -> dict:
    """Every equally likely resample of ``strata`` (each seed's episodes
    drawn with replacement within the seed), enumerated: IQM -> probability."""
    per_seed = [list(itertools.product(s, repeat=len(s))) for s in strata]
    counts: Counter = Counter()
    for draw in itertools.product(*per_seed):
        rates = [sum(map(Fraction, d)) / len(d) for d in draw]
        counts[round(iqm([float(r) for r in rates]), 9)] += 1
    total = sum(counts.values())
    return {value: n / total for value, n in sorted(counts.items())}


def test_the_stratified_bootstrap_matches_the_enumerated_resamples():
    """Seeds [1, 0], [1, 1], [0, 0]: seed 0's resampled rate is 0, 1/2 or 1
    (probabilities 1/4, 1/2, 1/4), the others stay 1 and 0, so the IQM over
    the three seeds, (0/4 + a + 1/4) / 1.5, is 1/6, 1/2 or 5/6 with those
    probabilities; the 95% interval is [1/6, 5/6]."""
    strata = [[1, 0], [1, 1], [0, 0]]
    exact = _exact_iqm_distribution(strata)
    assert exact == pytest.approx({round(1 / 6, 9): 0.25, 0.5: 0.5, round(5 / 6, 9): 0.25})
    reps = stratified_replicates(strata, resamples=20_000, seed=3)
    for value, probability in exact.items():
        assert np.mean(np.isclose(reps, value)) == pytest.approx(probability, abs=0.015)
    assert np.isclose(reps[:, None], list(exact)).any(axis=1).all()  # nothing else occurs
    assert stratified_interval(strata, seed=3) == pytest.approx((1 / 6, 5 / 6))
    assert stratified_interval(strata, "mean", seed=3) == pytest.approx((1 / 3, 2 / 3))
    # Seeded: the same input gives the same replicates.
    assert (
        stratified_replicates(strata, resamples=500, seed=3)
        == stratified_replicates(strata, resamples=500, seed=3)
    ).all()


def test_the_stratified_bootstrap_takes_game_scores_not_only_successes():
    """Board games score 1 / 1/2 / 0 per game. Seeds [win, draw], [draw,
    draw], [loss, loss]: seed 0's resampled mean is 1/2, 3/4 or 1
    (probabilities 1/4, 1/2, 1/4), the others stay 1/2 and 0, so the IQM,
    (0/4 + 1/2 + a/4) / 1.5, is 5/12, 11/24 or 1/2; a counter of wins only
    (or of scores rounded to 0/1) would give other values."""
    strata = [[1.0, 0.5], [0.5, 0.5], [0.0, 0.0]]
    exact = _exact_iqm_distribution(strata)
    assert exact == pytest.approx(
        {round(5 / 12, 9): 0.25, round(11 / 24, 9): 0.5, round(1 / 2, 9): 0.25}
    )
    reps = stratified_replicates(strata, resamples=20_000, seed=3)
    for value, probability in exact.items():
        assert np.mean(np.isclose(reps, value)) == pytest.approx(probability, abs=0.015)
    assert np.isclose(reps[:, None], list(exact)).any(axis=1).all()
    assert stratified_interval(strata, seed=3) == pytest.approx((5 / 12, 1 / 2))
    # Every game drawn, against an opponent nobody beats: 1/2 exactly, no spread.
    assert stratified_interval([[0.5] * 50] * 3) == pytest.approx((0.5, 0.5))


def test_the_stratified_bootstrap_never_mixes_episodes_of_different_seeds():
    """A seed that always succeeds and one that always fails: resampled
    within each seed the rates stay 1 and 0 and the IQM over the two is
    always 1/2. Pooling the episodes (mixing the strata) would move it."""
    assert stratified_interval([[1, 1, 1], [0, 0, 0]]) == (0.5, 0.5)
    assert stratified_interval([[1, 1, 1], [0, 0, 0]], "mean") == (0.5, 0.5)
    pooled = stratified_interval([[1, 1, 1, 0, 0, 0]])  # one stratum: the rate moves
    assert pooled[0] < 0.5 < pooled[1]
    with pytest.raises(ValueError, match="non-empty"):
        stratified_interval([[1, 0], []])
    with pytest.raises(ValueError, match="resamples"):
        stratified_interval([[1]], resamples=0)


def test_the_aggregate_resamples_runs_within_each_environment():
    """Environment A's runs [0, 1], B's [1, 1]: each replicate draws A's two
    runs from {0, 1} (0, 1 or 2 ones: 1/4, 1/2, 1/4) and B's stay ones; the
    IQM over the four runs is then 0.5, 1 or 1 (the middle two of
    [0, 0, 1, 1], [0, 1, 1, 1], [1, 1, 1, 1])."""
    reps = aggregate_replicates([[0, 1], [1, 1]], resamples=20_000, seed=1)
    assert np.mean(reps == 0.5) == pytest.approx(0.25, abs=0.015)
    assert np.mean(reps == 1.0) == pytest.approx(0.75, abs=0.015)
    assert aggregate_interval([[0, 1], [1, 1]], seed=1) == (0.5, 1.0)
    # Strata kept apart: an environment of zeros and one of ones give IQM 1/2 always.
    assert aggregate_interval([[0, 0, 0], [1, 1, 1]]) == (0.5, 0.5)
