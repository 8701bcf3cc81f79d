"""M4's length rules without a constant (``gaitlog.host.gait.estimators.weinberg``: a weak or short step counted
as its share of a typical step), against lengths worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.host.gait.estimators.weinberg import duration_share_length_m, range_share_length_m, weinberg_length_m


def test_range_share_is_weinberg_at_and_above_the_typical_range_and_linear_below() -> None:
    r = np.array([16.0, 81.0, 4.0, 0.0, np.nan])
    got = range_share_length_m(r, 16.0, k=0.5)
    # 0.5 * 16^(1/4) = 1.0 and 0.5 * 81^(1/4) = 1.5 (Weinberg's); a quarter of the typical range: a quarter of
    # a typical step (Weinberg's 1/4 would give 0.5 * 4^(1/4) = 0.707, 71 %); no range, no length
    assert got[:4].tolist() == pytest.approx([1.0, 1.5, 0.25, 0.0])
    assert np.isnan(got[4])
    assert weinberg_length_m(r[2:3], k=0.5)[0] == pytest.approx(0.5 * np.sqrt(2.0))
    # continuous at the typical range
    assert range_share_length_m(np.array([16.0 - 1e-9]), 16.0, k=0.5)[0] == pytest.approx(1.0)


def test_duration_share_scales_a_short_step_and_caps_at_one() -> None:
    got = duration_share_length_m(np.array([16.0, 16.0, 16.0]), np.array([0.3, 0.6, 1.2]), 0.6, k=0.5)
    assert got.tolist() == pytest.approx([0.5, 1.0, 1.0])
