"""The numpy peak finder against ``scipy.signal.find_peaks`` as the oracle (distance and prominence rules)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.signal import find_peaks as scipy_find_peaks

from gaitlog.host.gait.peaks import find_peaks

#: Small integers: plateaus, equal peaks (argsort ties) and equal bases are common.
LEVELS = arrays(np.float64, st.integers(0, 300), elements=st.integers(-4, 4).map(float))
#: Any finite values, NaN-free.
FLOATS = arrays(np.float64, st.integers(0, 300),
                elements=st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False))
DISTANCE = st.one_of(st.none(), st.integers(1, 40), st.floats(1.0, 40.0))
PROMINENCE = st.one_of(st.none(), st.sampled_from([0.0, 0.5, 1.0, 2.0, 3.0]), st.floats(0.0, 1e6))


def assert_same_as_scipy(x: np.ndarray, distance, prominence) -> None:
    expected, _ = scipy_find_peaks(x, distance=distance, prominence=prominence)
    got = find_peaks(x, distance=distance, prominence=prominence)
    assert got.dtype == expected.dtype
    np.testing.assert_array_equal(got, expected)


@settings(max_examples=400, deadline=None)
@given(x=LEVELS, distance=DISTANCE, prominence=PROMINENCE)
def test_plateaus_and_ties_match_scipy(x, distance, prominence) -> None:
    assert_same_as_scipy(x, distance, prominence)


@settings(max_examples=300, deadline=None)
@given(x=FLOATS, distance=DISTANCE, prominence=PROMINENCE)
def test_random_values_match_scipy(x, distance, prominence) -> None:
    assert_same_as_scipy(x, distance, prominence)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), distance=st.integers(1, 60), prominence=st.floats(0.0, 3.0),
       quantum=st.sampled_from([0.0, 0.05, 0.5]))
def test_long_smooth_signals_match_scipy(seed, distance, prominence, quantum) -> None:
    """Long curves like the foot-flat search's (a few thousand samples, a cadence, noise, a trend), optionally
    rounded to a grid so that plateaus and equal heights occur."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(500, 5000))
    t = np.arange(n) / 50.0
    x = (np.cos(2 * np.pi * rng.uniform(0.5, 2.5) * t) * rng.uniform(0.1, 3.0)
         + np.cumsum(rng.normal(0, 0.05, n)) + rng.normal(0, rng.uniform(0, 0.5), n))
    if quantum:
        x = np.round(x / quantum) * quantum
    assert_same_as_scipy(x, distance, prominence)


def test_known_peaks() -> None:
    """Hand-worked: the plateau's left-middle sample; the ends never; prominence against the higher base."""
    x = np.array([3.0, 1.0, 2.0, 2.0, 2.0, 2.0, 0.0, 5.0, 4.0, 4.5, 1.0, 6.0])
    np.testing.assert_array_equal(find_peaks(x), [3, 7, 9])
    # prominences: 3 -> 2 - 1 = 1 (left base 1, right base 0 -> higher is 1); 7 -> 5 - 0 = 5; 9 -> 4.5 - 4 = 0.5
    np.testing.assert_array_equal(find_peaks(x, prominence=1.0), [3, 7])
    np.testing.assert_array_equal(find_peaks(x, prominence=1.01), [7])
    np.testing.assert_array_equal(find_peaks(x, distance=3), [3, 7])  # 9 is 2 from the higher 7


@pytest.mark.parametrize(("x", "kwargs", "match"), [
    (np.zeros((2, 5)), {}, "one-dimensional"),
    (np.array([0.0, 1.0, np.nan, 0.0]), {}, "NaN"),
    (np.array([0.0, 1.0, 0.0]), {"distance": 0}, "distance"),
])
def test_bad_input_is_refused(x, kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        find_peaks(x, **kwargs)
