"""Quintic Hermite channels of the walking world: knot conditions, C2 continuity, polynomial exactness."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitlog.firmware_sim.world.hermite import constant_ppoly, quintic_hermite

knots = st.lists(st.floats(0.01, 2.0), min_size=1, max_size=12).map(lambda d: np.concatenate(([0.0], np.cumsum(d))))


@settings(max_examples=80, deadline=None)
@given(knots, st.integers(0, 2**31))
def test_knot_conditions_and_c2_continuity(t, seed) -> None:
    rng = np.random.default_rng(seed)
    y, dy, ddy = (rng.normal(0, s, t.size) for s in (1.0, 2.0, 5.0))
    pp = quintic_hermite(t, y, dy, ddy)
    for nu, want in ((0, y), (1, dy), (2, ddy)):
        np.testing.assert_allclose(pp(t, nu), want, rtol=1e-7, atol=1e-7)
    # C2: limits from both sides of every interior knot agree
    # C2: limits from both sides of every interior knot agree (to the jerk times the offset)
    eps = 1e-9
    tk = t[1:-1]
    for nu in (0, 1, 2):
        slack = 2 * eps * (np.abs(pp(tk - eps, nu + 1)) + np.abs(pp(tk + eps, nu + 1))) + 1e-7
        assert np.all(np.abs(pp(tk - eps, nu) - pp(tk + eps, nu)) <= slack)


@settings(max_examples=40, deadline=None)
@given(knots, st.lists(st.floats(-3, 3), min_size=6, max_size=6))
def test_reproduces_any_quintic_exactly(t, coef) -> None:
    poly = np.poly1d(coef)
    pp = quintic_hermite(t, poly(t), poly.deriv(1)(t), poly.deriv(2)(t))
    x = np.linspace(t[0], t[-1], 57)
    scale = 1.0 + np.abs(poly(x)).max()
    np.testing.assert_allclose(pp(x), poly(x), atol=1e-8 * scale * (1 + t[-1]) ** 5)


def test_bad_knots_are_refused() -> None:
    with pytest.raises(ValueError, match="strictly increasing"):
        quintic_hermite(np.array([0.0, 1.0, 1.0]), np.zeros(3), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="at least two"):
        quintic_hermite(np.array([0.0]), np.zeros(1), np.zeros(1), np.zeros(1))
    assert float(constant_ppoly(0.0, 2.0, 5.0)(1.3, 2)) == 0.0
