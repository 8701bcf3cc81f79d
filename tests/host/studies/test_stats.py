"""The one subject bootstrap (gaitlog.host.studies.stats): its seeded draws, its vectorised median, its paired
statistics and its NaN rule."""

from __future__ import annotations

import math

import numpy as np

from gaitlog.host.studies.stats import MEDIAN, percentile_interval, resampled_medians, subject_bootstrap, subject_resamples


def test_the_draws_are_pinned() -> None:
    """The studies print intervals from these draws: a change of stream changes every printed interval."""
    assert subject_resamples(4, n_resamples=3, seed=0).tolist() == [[0, 1, 2, 1], [3, 1, 0, 0], [1, 0, 1, 2]]
    groups = [np.array([1.0, 2.0, 4.0]), np.array([3.0]), np.array([0.5, 7.0])]
    value, lo, hi = subject_bootstrap(groups, MEDIAN, subject_resamples(3, n_resamples=200, seed=1))
    assert (float(value), float(lo), float(hi)) == (2.5, 2.0, 3.75)


def test_resampled_medians_are_the_medians_of_the_repeated_values() -> None:
    rng = np.random.default_rng(1)
    groups = [rng.normal(i, 1.0, rng.integers(0, 40)) for i in range(5)]
    counts = subject_resamples(5, n_resamples=300, seed=3)
    assert np.array_equal(counts.sum(axis=1), np.full(300, 5))
    got = resampled_medians(groups, counts)
    want = [np.median(np.concatenate([np.repeat(g[None], c, axis=0).ravel() for g, c in zip(groups, row)]))
            if any(c and g.size for g, c in zip(groups, row)) else np.nan for row in counts]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_the_vectorised_median_is_the_median_statistic() -> None:
    rng = np.random.default_rng(2)
    groups = [rng.normal(1.0, 0.1, rng.integers(1, 7)) for _ in range(6)]
    counts = subject_resamples(6, n_resamples=400, seed=4)
    assert subject_bootstrap(groups, MEDIAN, counts) == subject_bootstrap(groups, np.median, counts)


def test_a_paired_statistic_draws_the_same_subjects_for_both() -> None:
    rng = np.random.default_rng(3)
    a = [rng.normal(1.0, 0.1, 5) for _ in range(4)]
    b = [x + 1.0 for x in a]
    value, lo, hi = subject_bootstrap(a, lambda x, y: np.mean(y - x), subject_resamples(4, seed=5), b)
    assert math.isclose(value, 1.0) and math.isclose(lo, 1.0) and math.isclose(hi, 1.0)


def test_nan_resamples_are_left_out_and_all_nan_gives_nan() -> None:
    assert percentile_interval(np.array([np.nan, 1.0, 3.0]), 1.0) == (1.0, 3.0)
    lo, hi = percentile_interval(np.full(5, np.nan))
    assert math.isnan(lo) and math.isnan(hi)
    lo, hi = percentile_interval(np.full((5, 2), np.nan))
    assert lo.shape == (2,) and np.isnan(hi).all()
