"""Morris (1973) orientation: initial DCM from gravity, strapdown integration, Jordan orthogonalisation.

References are independent of the code under test: scipy ``Rotation``, ``scipy.linalg.expm``/``polar`` and
closed-form results (expected numbers from ``shared/notes/CALIBRATION-KINEMATICS.md``).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm, polar
from scipy.spatial.transform import Rotation

from gaitlog.host.errors import HostError
from gaitlog.host.kinematics.orientation import (
    cumulative_matmul,
    geodesic_distance_rad,
    initial_dcm_from_gravity,
    integrate_dcm,
    orthogonality_error,
    orthonormalize_jordan,
    rotation_increments,
    skew,
)

W123 = np.array([1.0, 2.0, 3.0])


def _skew_ref(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _geodesic_ref(a: np.ndarray, b: np.ndarray) -> float:
    """Angle of the rotation between the polar factors of a and b, via scipy."""
    return float((Rotation.from_matrix(a).inv() * Rotation.from_matrix(b)).magnitude())


# ---------------------------------------------------------------- initial DCM (eqs 12-16, corrected)


def test_initial_dcm_worked_example_matches_notes_and_scipy() -> None:
    lam = initial_dcm_from_gravity([0.3, 0.5, 0.812404])
    expected = [[0.938083, 0.0, -0.346410], [-0.173205, 0.866025, -0.469042], [0.3, 0.5, 0.812404]]
    np.testing.assert_allclose(lam, expected, atol=1e-6)
    g = np.array([0.3, 0.5, np.sqrt(0.66)])  # exactly unit
    lam = initial_dcm_from_gravity(g)
    ref = Rotation.from_euler("XY", [np.arcsin(g[1]), np.arctan2(-g[0], g[2])]).as_matrix()
    np.testing.assert_allclose(lam, ref, atol=1e-13, rtol=0)
    np.testing.assert_allclose(lam @ g, [0.0, 0.0, 1.0], atol=1e-15)
    assert lam[0, 1] == 0.0


def test_printed_eq15_is_not_orthogonal_but_corrected_is() -> None:
    g = np.array([0.3, 0.5, np.sqrt(0.66)])
    l22 = np.sqrt(1 - g[1] ** 2)
    l21 = -g[0] * g[1] / l22
    l13 = l21 * g[1] - l22 * g[0]
    printed_l23 = g[1] * l13  # eq (15) as printed
    lam = initial_dcm_from_gravity(g)
    assert abs(printed_l23 - lam[1, 2]) > 0.1
    assert orthogonality_error(lam) < 1e-15


@settings(max_examples=200, deadline=None)
@given(
    st.floats(-np.pi, np.pi), st.floats(-1.4, 1.4), st.floats(0.2, 5.0),
)
def test_initial_dcm_property_random_gravity(az: float, elev: float, scale: float) -> None:
    g = scale * np.array([np.cos(elev) * np.cos(az), np.sin(elev), np.cos(elev) * np.sin(az)])
    lam = initial_dcm_from_gravity(g)
    gu = g / np.linalg.norm(g)
    np.testing.assert_allclose(lam @ lam.T, np.eye(3), atol=1e-13)
    assert np.linalg.det(lam) == pytest.approx(1.0, abs=1e-13)
    np.testing.assert_allclose(lam @ gu, [0, 0, 1], atol=1e-13)
    assert lam[0, 1] == 0.0
    ref = Rotation.from_euler("XY", [np.arcsin(gu[1]), np.arctan2(-gu[0], gu[2])]).as_matrix()
    np.testing.assert_allclose(lam, ref, atol=1e-12)


def test_initial_dcm_batched_and_singular_case() -> None:
    gs = np.array([[0.0, 0.0, 1.0], [0.3, 0.5, np.sqrt(0.66)], [0.0, 1.0, 0.0]])
    with pytest.raises(HostError, match=r"body axis 2 at index \[2\]"):
        initial_dcm_from_gravity(gs)
    lam = initial_dcm_from_gravity(gs, on_singular="axis1")
    np.testing.assert_allclose(lam[0], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(lam[2] @ gs[2], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(lam[2] @ lam[2].T, np.eye(3), atol=1e-15)
    assert np.linalg.det(lam[2]) == pytest.approx(1.0)
    assert lam[2][0, 1] == 0.0  # λ12 = 0 still holds at the singular point
    lam_down = initial_dcm_from_gravity([0.0, -2.0, 0.0], on_singular="axis1")
    np.testing.assert_allclose(lam_down @ [0, -1, 0], [0, 0, 1], atol=1e-15)
    with pytest.raises(HostError, match="zero or non-finite"):
        initial_dcm_from_gravity([0.0, 0.0, 0.0])


# ---------------------------------------------------------------- strapdown integration


def test_rotation_increments_equal_scipy_rotvec() -> None:
    rng = np.random.default_rng(3)
    phi = rng.normal(size=(500, 3)) * rng.choice([1e-9, 1e-5, 1e-3, 0.3, 2.0], size=(500, 1))
    np.testing.assert_allclose(rotation_increments(phi), Rotation.from_rotvec(phi).as_matrix(), atol=2e-15)


def test_cumulative_matmul_equals_sequential_product() -> None:
    rng = np.random.default_rng(4)
    for m in (0, 1, 5, 33, 1000, 1234):
        steps = rng.normal(size=(m, 3, 3)) * 0.3 + np.eye(3)
        init = rng.normal(size=(3, 3))
        ref = [init]
        for s in steps:
            ref.append(ref[-1] @ s)
        np.testing.assert_allclose(cumulative_matmul(init, steps), np.array(ref), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize(("sampling_rate_hz", "expected_rad"), [(50, 3.5e-3), (100, 8.7e-4), (10_000, 8.7e-8)])
def test_heun_constant_rate_error_matches_notes(sampling_rate_hz: int, expected_rad: float) -> None:
    w = np.tile(W123, (sampling_rate_hz + 1, 1))
    lam = integrate_dcm(w, sampling_rate_hz, method="heun")
    truth = expm(_skew_ref(W123) * 1.0)
    err = _geodesic_ref(truth, lam[-1])
    assert err == pytest.approx(expected_rad, rel=0.02)


def test_heun_error_quarters_per_halving_of_step() -> None:
    errs = []
    for sampling_rate_hz in (50, 100, 200, 400):
        lam = integrate_dcm(np.tile(W123, (sampling_rate_hz + 1, 1)), sampling_rate_hz, method="heun")
        errs.append(_geodesic_ref(expm(_skew_ref(W123)), lam[-1]))
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    np.testing.assert_allclose(ratios, 4.0, rtol=0.01)


def test_forward_euler_error_and_orthogonality_match_notes() -> None:
    lam = integrate_dcm(np.tile(W123, (51, 1)), 50, method="euler")
    assert _geodesic_ref(expm(_skew_ref(W123)), lam[-1]) == pytest.approx(7e-3, rel=0.02)
    assert orthogonality_error(lam[-1]) == pytest.approx(0.46, rel=0.02)


@pytest.mark.parametrize("sampling_rate_hz", [7, 50, 1000])
def test_rodrigues_is_exact_for_constant_rate(sampling_rate_hz: int) -> None:
    rot0 = Rotation.from_euler("ZYX", [30, -20, 10], degrees=True).as_matrix()
    t = np.arange(3 * sampling_rate_hz + 1) / sampling_rate_hz
    lam = integrate_dcm(np.tile(W123, (t.size, 1)), sampling_rate_hz, rot0)
    truth = rot0 @ Rotation.from_rotvec(t[:, None] * W123).as_matrix()  # λ0 · expm([ωt×])
    np.testing.assert_allclose(lam, truth, atol=1e-13)
    assert orthogonality_error(lam).max() < 1e-12  # round-off only, over 3 s


def test_heun_orthogonality_over_60s_vs_jordan_each_step() -> None:
    w = np.tile(W123, (60 * 50 + 1, 1))
    plain = integrate_dcm(w, 50, method="heun")
    jordan = integrate_dcm(w, 50, method="heun", jordan_each_step=True)
    assert orthogonality_error(plain[-1]) == pytest.approx(3.4e-2, rel=0.02)
    assert orthogonality_error(jordan).max() == pytest.approx(6.5e-11, rel=0.05)


def _coning(t: np.ndarray, a: float, f: float) -> tuple[np.ndarray, np.ndarray]:
    """Classic coning: R(t) = Rz(Ωt) Rx(a) Rz(−Ωt); returns truth matrices and body rates."""
    om = 2 * np.pi * f
    rot = (
        Rotation.from_euler("z", (om * t)[:, None])
        * Rotation.from_euler("x", a)
        * Rotation.from_euler("z", (-om * t)[:, None])
    )
    # body rate of R = Rz(Ωt) Rx(a) Rz(−Ωt): ω = Ω (Rz(Ωt) Rx(−a) Rz(−Ωt) e3 − e3)  [derived from RᵀṘ]
    inner = (Rotation.from_euler("z", (om * t)[:, None]) * Rotation.from_euler("x", -a) * Rotation.from_euler("z", (-om * t)[:, None]))
    w = om * (inner.apply([0.0, 0.0, 1.0]) - [0.0, 0.0, 1.0])
    return rot.as_matrix(), w


def test_coning_motion_against_analytic_truth() -> None:
    sampling_rate_hz, a, f = 1000, np.radians(5.0), 2.0
    t = np.arange(2 * sampling_rate_hz + 1) / sampling_rate_hz
    truth, w = _coning(t, a, f)
    # the closed-form rates agree with finite differences of the truth (independent check of the truth)
    fd = (np.swapaxes(truth[1:-1], 1, 2) @ (truth[2:] - truth[:-2])) * sampling_rate_hz / 2
    np.testing.assert_allclose(fd[:, 2, 1], w[1:-1, 0], atol=1e-3)
    errs = {}
    for method, coning in (("heun", False), ("rodrigues", False), ("rodrigues", True)):
        lam = integrate_dcm(w, sampling_rate_hz, truth[0], method=method, coning_correction=coning)
        errs[(method, coning)] = geodesic_distance_rad(truth, orthonormalize_jordan(lam)).max()
    assert errs[("rodrigues", False)] < 1e-5
    assert errs[("heun", False)] < 1e-5
    # the remaining error is the secular coning drift about the cone axis; it grows linearly in time and
    # the two-sample coning term (Bortz 1970) halves it for rate samples
    t20 = np.arange(20 * 100 + 1) / 100
    truth20, w20 = _coning(t20, a, f)
    plain = geodesic_distance_rad(truth20[-1], integrate_dcm(w20, 100, truth20[0])[-1])
    corrected = geodesic_distance_rad(truth20[-1], integrate_dcm(w20, 100, truth20[0], coning_correction=True)[-1])
    assert plain == pytest.approx(10 * errs[("rodrigues", False)] * 100, rel=0.01)  # linear in T, ∝ dt²
    assert corrected < 0.55 * plain


def test_planar_flexion_matches_closed_form() -> None:
    sampling_rate_hz = 200
    t = np.arange(2 * sampling_rate_hz + 1) / sampling_rate_hz
    theta = 0.6 * np.sin(2 * np.pi * 1.0 * t)  # flexion about body axis 2, rad
    w = np.zeros((t.size, 3))
    w[:, 1] = 0.6 * 2 * np.pi * np.cos(2 * np.pi * t)
    lam = integrate_dcm(w, sampling_rate_hz)
    truth = Rotation.from_euler("y", theta[:, None]).as_matrix()
    # planar: rotations commute, the trapezoid on the rate is the only error (O(dt^2))
    err = np.abs(np.unwrap(np.arctan2(lam[:, 0, 2], lam[:, 0, 0])) - theta).max()
    assert err < 5e-4
    np.testing.assert_allclose(lam[:, 1], np.tile([0, 1, 0], (t.size, 1)), atol=1e-14)
    assert geodesic_distance_rad(truth, lam).max() < 5e-4


def test_integrate_dcm_rejects_bad_input() -> None:
    with pytest.raises(HostError, match=r"shape \(n, 3\)"):
        integrate_dcm(np.zeros((5, 2)), 50)
    with pytest.raises(HostError, match="non-finite values at row 2"):
        integrate_dcm(np.array([[0, 0, 0], [0, 0, 0], [np.nan, 0, 0]]), 50)
    with pytest.raises(HostError, match="rate_hz"):
        integrate_dcm(np.zeros((5, 3)), 0)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_integrate_dcm_property_piecewise_constant_rates(seed: int) -> None:
    """Rodrigues with a constant rate per step equals the scipy composition of the same increments."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 200))
    w = rng.normal(scale=3.0, size=(n, 3))
    sampling_rate_hz = 100.0
    lam0 = Rotation.random(random_state=int(rng.integers(1 << 31))).as_matrix()
    lam = integrate_dcm(w, sampling_rate_hz, lam0)
    incs = Rotation.from_rotvec(0.5 * (w[:-1] + w[1:]) / sampling_rate_hz)
    r = Rotation.from_matrix(lam0)
    ref = [r.as_matrix()]
    for inc in incs:
        r = r * inc
        ref.append(r.as_matrix())
    np.testing.assert_allclose(lam, np.array(ref), atol=1e-12)


# ---------------------------------------------------------------- Jordan orthogonalisation (eq 18)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_jordan_converges_to_polar_factor_in_four_iterations(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rot = Rotation.random(random_state=seed % (1 << 31)).as_matrix()
    perturbed = rot + 1e-2 * rng.uniform(-1, 1, size=(3, 3))
    out = orthonormalize_jordan(perturbed, return_info=True)
    assert out.iterations <= 4
    assert not out.fallback
    assert orthogonality_error(out.dcm) < 1e-12
    np.testing.assert_allclose(out.dcm, polar(perturbed)[0], atol=1e-12)
    np.testing.assert_allclose(out.dcm, Rotation.from_matrix(perturbed).as_matrix(), atol=1e-12)


def test_jordan_divergence_guard_falls_back_to_svd() -> None:
    rot = Rotation.from_euler("XYZ", [10, 20, 30], degrees=True).as_matrix()
    eye = np.eye(3)
    for bad in (2.0 * rot, rot @ np.diag([1.8, 1.8, 1.0])):
        naive = bad.copy()
        for _ in range(30):  # the unguarded iteration goes wrong
            naive = naive @ (eye - 0.5 * (naive.T @ naive - eye))
        assert geodesic_distance_rad(rot, orthonormalize_jordan(naive)) > 1.0 or np.linalg.det(naive) < 0
        out = orthonormalize_jordan(bad, return_info=True)
        assert bool(out.fallback)
        np.testing.assert_allclose(out.dcm, rot, atol=1e-13)
        with pytest.raises(HostError, match="convergence region"):
            orthonormalize_jordan(bad, fallback="raise")
    # a reflection-contaminated matrix (det < 0) still yields a proper rotation
    out = orthonormalize_jordan(rot @ np.diag([1.0, 1.0, -1.0]), return_info=True)
    assert bool(out.fallback) and np.linalg.det(out.dcm) == pytest.approx(1.0)


def test_jordan_batched() -> None:
    rots = Rotation.random(20, random_state=7).as_matrix()
    rng = np.random.default_rng(7)
    bad = rots + 1e-3 * rng.normal(size=rots.shape)
    bad[3] *= 2.5
    out = orthonormalize_jordan(bad.reshape(4, 5, 3, 3), return_info=True)
    assert out.dcm.shape == (4, 5, 3, 3)
    assert out.fallback.sum() == 1 and out.fallback.reshape(-1)[3]
    np.testing.assert_allclose(out.dcm.reshape(-1, 3, 3), Rotation.from_matrix(bad).as_matrix(), atol=1e-12)


def test_skew_matches_cross_product() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 10, 3))
    np.testing.assert_allclose((skew(a) @ b[..., None])[..., 0], np.cross(a, b), atol=1e-15)


def test_start_matrix_branches_of_the_quaternion_chain() -> None:
    """Every Shepperd branch for a rotation start, and a non-rotation start carried along as given."""
    t = np.arange(11) / 10.0
    w = np.tile(W123, (t.size, 1))
    inc = Rotation.from_rotvec(t[:, None] * W123).as_matrix()
    for angles in ([0, 0, 0], [179, 0, 0], [0, 179, 0], [0, 0, 179], [10, 20, 30]):
        rot0 = Rotation.from_euler("XYZ", angles, degrees=True).as_matrix()
        np.testing.assert_allclose(integrate_dcm(w, 10.0, rot0), rot0 @ inc, atol=1e-14)
    scaled = 2.0 * np.eye(3) + 1e-3
    np.testing.assert_allclose(integrate_dcm(w, 10.0, scaled), scaled @ inc, atol=1e-13)
