"""Statistics over subjects: the subject bootstrap of every study (``compare``'s error budget, ``evaluate sim``'s
intervals, the IPOL evaluation's intervals and rule gains).

One scheme: subjects are drawn with replacement (:func:`subject_resamples`, seeded; the same draws for every
figure of a study), a figure is recomputed on the pooled values of the drawn subjects (a subject drawn twice
counts twice) and the interval is the central ``level`` of those figures (percentile bootstrap,
:func:`subject_bootstrap`). The median has a vectorised path (:data:`MEDIAN`, :func:`resampled_medians`) that
gives the same figures as ``np.median`` of the repeated values.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["BOOTSTRAP_LEVEL", "BOOTSTRAP_RESAMPLES", "MEDIAN", "percentile_interval", "resampled_medians",
           "subject_bootstrap", "subject_resamples"]

#: Bootstrap resamples of the subjects and the interval's level.
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_LEVEL = 0.95
#: The statistic of :func:`subject_bootstrap` that is the pooled values' median, computed by
#: :func:`resampled_medians` without repeating the values.
MEDIAN = "median"


def subject_resamples(n_subjects: int, *, n_resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0) -> np.ndarray:
    """``(n_resamples, n_subjects)`` how many times each subject is drawn (with replacement, seeded)."""
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, n_subjects, size=(n_resamples, n_subjects))
    counts = np.zeros((n_resamples, n_subjects), np.int64)
    np.add.at(counts, (np.repeat(np.arange(n_resamples), n_subjects), draws.ravel()), 1)
    return counts


def subject_bootstrap(groups: Sequence[np.ndarray], statistic: Callable[..., np.ndarray] | str, counts: np.ndarray,
                      *more: Sequence[np.ndarray], level: float = BOOTSTRAP_LEVEL) -> tuple:
    """``statistic`` of the subjects' pooled values, and its percentile-bootstrap interval over subjects:
    ``(value, low, high)``.

    ``groups`` (and each of ``more``, paired with it: ``statistic`` takes one pooled array of each) hold one
    array per subject; ``counts`` (resamples x subjects, :func:`subject_resamples`) how often each subject is
    drawn. ``statistic`` may return an array (one interval per element) or be :data:`MEDIAN`. The interval
    ignores resamples whose figure is NaN; it is NaN when every one is.
    """
    ones = np.ones((1, len(groups)), np.int64)
    value = _resampled(groups, statistic, ones, more)[0]
    lo, hi = percentile_interval(_resampled(groups, statistic, np.atleast_2d(counts), more), level)
    return value, lo, hi


def percentile_interval(boot: np.ndarray, level: float = BOOTSTRAP_LEVEL) -> tuple:
    """The central ``level`` of the resampled figures ``boot`` (resamples first), NaN resamples left out."""
    q = 50.0 * (1.0 - level), 50.0 * (1.0 + level)
    with np.errstate(all="ignore"):
        if np.isfinite(boot).any():
            return tuple(np.nanpercentile(boot, q, axis=0))
    nan = np.full(np.shape(boot)[1:], np.nan)
    return (nan, nan) if nan.ndim else (np.nan, np.nan)


def _resampled(groups: Sequence[np.ndarray], statistic: Callable[..., np.ndarray] | str, counts: np.ndarray,
               more: tuple[Sequence[np.ndarray], ...]) -> np.ndarray:
    """``statistic`` of the pooled values of each row of ``counts`` (resamples first)."""
    if statistic == MEDIAN:
        return resampled_medians(list(groups), counts)
    lists = (groups, *more)

    def pooled(weights: np.ndarray) -> np.ndarray:
        picks = np.repeat(np.arange(len(groups)), weights)
        return statistic(*(np.concatenate([np.asarray(g[i], np.float64) for i in picks]) if picks.size
                           else np.zeros(0) for g in lists))

    return np.array([pooled(c) for c in counts])


def resampled_medians(groups: list[np.ndarray], counts: np.ndarray, *, chunk: int = 250) -> np.ndarray:
    """Median of the pooled values of ``groups`` when group ``g`` is taken ``counts[r, g]`` times, per row.

    The median of the multiset (the mean of its two middle values when its size is even), as ``np.median``
    of the repeated values, without repeating them; NaN for a row with no value.

    Examples
    --------
    >>> groups = [np.array([1.0, 5.0]), np.array([2.0]), np.array([])]
    >>> resampled_medians(groups, np.array([[1, 1, 0], [0, 3, 1], [2, 0, 0], [0, 0, 2]])).tolist()
    [2.0, 2.0, 3.0, nan]
    >>> float(np.median([1.0, 5.0, 2.0]))
    2.0
    """
    counts = np.atleast_2d(np.asarray(counts, np.int64))
    v = np.concatenate([np.asarray(g, np.float64).ravel() for g in groups]) if groups else np.zeros(0)
    gid = np.repeat(np.arange(len(groups)), [np.asarray(g).size for g in groups])
    out = np.full(counts.shape[0], np.nan)
    if v.size == 0:
        return out
    order = np.argsort(v, kind="stable")
    v, gid = v[order], gid[order]
    for r0 in range(0, counts.shape[0], chunk):
        cum = np.cumsum(counts[r0:r0 + chunk][:, gid], axis=1)
        total = cum[:, -1]
        lo = np.argmax(cum > ((total - 1) // 2)[:, None], axis=1)
        hi = np.argmax(cum > (total // 2)[:, None], axis=1)
        out[r0:r0 + chunk] = np.where(total > 0, 0.5 * (v[lo] + v[hi]), np.nan)
    return out
