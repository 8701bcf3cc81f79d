"""What quantisation should cost each estimator, predicted analytically: the theory ``gaitlog sweep`` prints
beside the measured error, so that a reader can tell a model effect from a bug.

**The model.** A rounding or truncation to a step ``q`` adds an error uniform in one step: variance ``q^2 / 12``,
independent from sample to sample and of the signal (Widrow's conditions: the signal moves over many steps
between samples, or noise dithers it). Each error is then carried through the estimator's linear part (or its
linearisation at the step's own values), and the per-step standard deviations ``sigma_i`` give the predicted
median ``|error|`` of a set of steps (:func:`median_abs_of_mixture`: the median of a mixture of zero-mean
normals, what the sweep measures as the median per-step ``|offline - ideal|``).

* **ADC** (share ``offline - ideal``). The ideal chain reads the analog input (minus the floor's half code),
  the offline chain the codes: one code's uniform error per axis and sample. The calibration ``a = M (c - o)``
  and the projection on gravity ``a_v = f . g_hat`` give ``var(a_v) = |M^T g_hat|^2 / 12`` g^2
  (:func:`adc_vertical_variance_m2_s4`).
* **M4** ``K r^p`` (``r`` the range of the 3 Hz Gaussian low-pass of ``a_v``): the filter passes ``sum w_k^2``
  of a white variance (:func:`fir_noise_gain`); the range is the difference of two filtered values far apart
  (twice that variance); ``dL = p L dr / r``.
* **M1, M2** ``2 K sqrt(2 l h - h^2)``: ``h`` is the range of the double integral of ``a_v`` over the step
  (trapezoids, as the offline chain): :func:`position_error_variance` computes the exact variance of the
  integrated error at two instants, by the chain's own linear operator. M2's drift correction pins its
  position error to zero at both foot-flats, M1's only at the first. The extremes of both are taken a half
  step apart (``n/4`` and ``3n/4``: a CoM that oscillates once per step; with M1's extremes at the window's
  ends instead, the prediction is twice the measured error). ``dL/dh = 2 K (l - h) / sqrt(2 l h - h^2)``.
* **M3**: M2's position over the single support, the same variance (a half step apart), M3's derivative.
* **M5** ``K1 / T + K2``: no amplitude enters; on steps whose events agree the error is zero.
* **Arithmetic** (share ``online-fixed - online-float``, :func:`arithmetic_sigma_m`): the fixed-point chain's
  requantisations that can be modelled: the calibrated specific force and a_v rounded to the a_v format
  (two roundings of ``2^-f_acc`` g), the 3 Hz output to the low-pass format (M4), the excursion to its format
  (M1-M3), the pendulum's square root (a floor: a bias of one root step), K rounded to its format, and the
  length rounded to the step format (twice for M1, M2: the pendulum's output and the product with K). Not
  modelled: the FIR weights' rounding (a systematic change of the filter's shape: M4's arithmetic share is
  measured up to ~4x the prediction at 100 Hz), the calibration's mantissas and offsets, c1 and c2.

**Where it breaks down.** Few bits with little noise (the error follows the signal: 8 bits on slow walking);
saturation (an error no longer bounded by ``q``); steps whose events differ between the chains (left out of
the measurement, not of a bias); M1's extremes, which are not always at the window's ends; the floor of a
square root (a bias of half a step, not a zero-mean error); constants rounded once per configuration (K, the
calibration's mantissas): a systematic error, counted here as if it were random across subjects.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from scipy.special import erf

from gaitlog.firmware_sim.algorithms import formats
from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT, SIGMA_S_AT_1HZ
from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS, StepTable
from gaitlog.units import STANDARD_GRAVITY_M_S2

__all__ = ["FF_CUTOFF_HZ", "adc_vertical_variance_m2_s4", "adc_sigma_m", "arithmetic_sigma_m", "fir_noise_gain",
           "median_abs_of_mixture", "position_error_variance", "uniform_variance"]

#: The 3 Hz low-pass of M4's range (the chains' ``ff_cutoff_hz``).
FF_CUTOFF_HZ = 3.0
#: Gaussian kernel half-width in sigmas (the chains').
_TRUNCATE_SIGMAS = 4.0


def uniform_variance(step: float) -> float:
    """Variance of a rounding error uniform over one step ``q``: ``q^2 / 12``.

    >>> uniform_variance(1.0) * 12
    1.0
    """
    return step * step / 12.0


@functools.lru_cache(maxsize=64)
def fir_noise_gain(cutoff_hz: float, sampling_rate_hz: float) -> float:
    """``sum w_k^2`` of the normalised Gaussian low-pass (-3 dB at ``cutoff_hz``, truncated at 4 sigma): the
    factor by which it scales a white variance (about ``1 / (2 sqrt(pi) sigma)``, sigma in samples).

    >>> round(fir_noise_gain(3.0, 50.0), 4), round(1 / (2 * math.sqrt(math.pi) * SIGMA_S_AT_1HZ / 3 * 50), 4)
    (0.1277, 0.1277)
    """
    sigma = SIGMA_S_AT_1HZ / cutoff_hz * sampling_rate_hz
    r = int(_TRUNCATE_SIGMAS * sigma + 0.5)
    w = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    w /= w.sum()
    return float(np.sum(w * w))


@functools.lru_cache(maxsize=512)
def _position_operator(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The linear maps from ``n + 1`` accelerations (one step window, sample period 1) to the M1 and M2
    positions (the offline chain's trapezoids and eqs 2-3), as ``(n + 1, n + 1)`` matrices."""
    a = np.eye(n + 1)
    v = np.zeros_like(a)
    v[1:] = np.cumsum(0.5 * (a[1:] + a[:-1]), axis=0)
    p1 = np.zeros_like(a)
    p1[1:] = np.cumsum(0.5 * (v[1:] + v[:-1]), axis=0)
    tau = np.arange(n + 1, dtype=np.float64)[:, None]
    c1 = -v[n] / n
    p_c1 = p1 + 0.5 * c1 * tau ** 2
    p2 = p_c1 - p_c1[n] / n * tau
    return p1, p2


def position_error_variance(n: int, sampling_rate_hz: float, *, corrected: bool, ends: bool = False) -> float:
    """Variance (m^2 per (m/s^2)^2 of white acceleration error) of the excursion's error over an ``n``-sample step:
    the double-integrated error's difference between the extremes, ``n/4`` and ``3n/4`` (module notes), with the
    drift correction (M2, M3: ``corrected``) or without (M1); ``ends`` takes M1's at ``0`` and ``n`` instead.

    The continuous limit at the ends: ``n^3 / 3`` sample periods^4 (a random walk, integrated).

    >>> n = 400; round(position_error_variance(n, 1.0, corrected=False, ends=True) / (n ** 3 / 3), 2)
    1.0
    """
    return _samples_variance(int(n), bool(corrected), bool(ends)) / sampling_rate_hz ** 4


@functools.lru_cache(maxsize=4096)
def _samples_variance(n: int, corrected: bool, ends: bool) -> float:
    """:func:`position_error_variance` in sample periods (cached: a walk's steps take few distinct lengths)."""
    if n < 2:
        return 0.0
    p1, p2 = _position_operator(n)
    p = p2 if corrected else p1
    row = p[n] - p[0] if ends else p[n // 4] - p[(3 * n) // 4]
    return float(np.sum(row * row))


def _excursion_variances(table: StepTable, corrected: bool) -> np.ndarray:
    """Each step's :func:`position_error_variance` (NaN without a window)."""
    rate = table.sampling_rate_hz
    n = np.rint(table.duration_s * rate)
    return np.array([position_error_variance(int(k), rate, corrected=corrected) if np.isfinite(k) else np.nan
                     for k in n])


def adc_vertical_variance_m2_s4(calibration: Any, gravity_g: np.ndarray) -> float:
    """Variance of a_v's ADC error, (m/s^2)^2: one code's uniform error per axis (``1/12`` code^2) through the
    calibration matrix (g per code) and the projection on the gravity direction."""
    g = np.asarray(gravity_g, np.float64)
    g_hat = g / np.linalg.norm(g)
    m = np.asarray(calibration.matrix_g_per_count, np.float64)
    return float(np.sum((m.T @ g_hat) ** 2)) * uniform_variance(1.0) * STANDARD_GRAVITY_M_S2 ** 2


def _pendulum_slope(h: np.ndarray, leg_length_m: float) -> np.ndarray:
    """``d(2 sqrt(2 l h - h^2)) / dh`` (NaN where the excursion is impossible)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return 2.0 * (leg_length_m - h) / np.sqrt(2 * leg_length_m * h - h * h)


def _k(table: StepTable, est: str) -> np.ndarray:
    """Each step's K: its calibrated length over its raw one (M3's raw includes the foot: K 1)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return table.length_m[est] / table.raw_m[est]


def adc_sigma_m(table: StepTable, var_av_m2_s4: float, *, leg_length_m: float,
                exponent: float = M4_EXPONENT) -> dict[str, np.ndarray]:
    """Per estimator, each step's predicted standard deviation (m) of the calibrated length's error for a white
    a_v error of variance ``var_av_m2_s4`` (module notes); NaN where the step has no length."""
    rate = table.sampling_rate_hz
    out: dict[str, np.ndarray] = {}
    h = table.vertical_excursion_m
    for est, corrected in (("M1", False), ("M2", True), ("M3", True)):
        var_h = _excursion_variances(table, corrected) * var_av_m2_s4
        slope = _pendulum_slope(h[est], leg_length_m) * (_k(table, est) if est != "M3" else 1.0)
        out[est] = np.abs(slope) * np.sqrt(var_h)
    var_r = 2.0 * fir_noise_gain(FF_CUTOFF_HZ, rate) * var_av_m2_s4
    with np.errstate(invalid="ignore", divide="ignore"):
        out["M4"] = exponent * table.length_m["M4"] / table.acc_range_m_s2 * math.sqrt(var_r)
    out["M5"] = np.where(np.isfinite(table.length_m["M5"]), 0.0, np.nan)
    return {e: out[e] for e in ESTIMATORS}


def arithmetic_sigma_m(table: StepTable, *, leg_length_m: float, acc_frac_bits: int = formats.F_ACC,
                       lowpass_frac_bits: int = formats.F_LP, exponent: float = M4_EXPONENT,
                       excursion_frac_bits: tuple[int, int] = (formats.F_EXC, formats.F_EXC2),
                       step_frac_bits: int = formats.F_STEP, k_frac_bits: int = formats.F_K,
                       k4_frac_bits: int = formats.F_K4,
                       two_length_frac_bits: int = formats.F_TWO_LEN) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Per estimator, each step's predicted standard deviation and bias (m) of the fixed-point chain's error
    against the float chain's (module notes: the requantisations modelled), for the formats' fraction bits given.

    The pendulum's square root is a floor (``(2 l h - h^2)`` in ``f_2l + f_h`` fraction bits, its root in half as
    many, doubled): a bias of minus one root step and a uniform error of two, before K."""
    g = STANDARD_GRAVITY_M_S2
    var_av = 2.0 * uniform_variance(g * 2.0 ** -acc_frac_bits)         # f rounded, then a_v rounded
    var_step = uniform_variance(2.0 ** -step_frac_bits)
    var_k = uniform_variance(2.0 ** -k_frac_bits)                      # K rounded (the lengths' K = 1 one)
    rate = table.sampling_rate_hz
    h = table.vertical_excursion_m
    out: dict[str, np.ndarray] = {}
    bias: dict[str, np.ndarray] = {}
    for est, corrected, f_h, roundings in (("M1", False, excursion_frac_bits[0], 2),
                                           ("M2", True, excursion_frac_bits[1], 2),
                                           ("M3", True, excursion_frac_bits[1], 1)):
        var_h = _excursion_variances(table, corrected) * var_av + uniform_variance(2.0 ** -f_h)
        k = _k(table, est) if est != "M3" else 1.0
        slope = _pendulum_slope(h[est], leg_length_m) * k
        root_step = 2.0 * 2.0 ** -((two_length_frac_bits + f_h) // 2)
        var = slope ** 2 * var_h + roundings * var_step + uniform_variance(root_step * k)
        if est != "M3":
            var = var + (table.length_m[est] / k) ** 2 * var_k
        out[est] = np.sqrt(var)
        bias[est] = np.where(np.isfinite(out[est]), -0.5 * root_step * k, np.nan)
    var_r = 2.0 * (fir_noise_gain(FF_CUTOFF_HZ, rate) * var_av + uniform_variance(g * 2.0 ** -lowpass_frac_bits))
    with np.errstate(invalid="ignore", divide="ignore"):
        k4 = table.length_m["M4"] / (table.acc_range_m_s2 / g) ** exponent        # K g0^p, the device's constant
        rel = exponent ** 2 * var_r / table.acc_range_m_s2 ** 2 + uniform_variance(2.0 ** -k4_frac_bits) / k4 ** 2
        out["M4"] = np.sqrt(table.length_m["M4"] ** 2 * rel + var_step)
    out["M5"] = np.where(np.isfinite(table.length_m["M5"]), math.sqrt(var_step), np.nan)
    for est in ("M4", "M5"):
        bias[est] = np.where(np.isfinite(out[est]), 0.0, np.nan)
    return {e: out[e] for e in ESTIMATORS}, {e: bias[e] for e in ESTIMATORS}


def median_abs_of_mixture(sigmas: np.ndarray, biases: np.ndarray | float = 0.0) -> float:
    """The median of ``|e|`` when each ``e_i`` is normal with mean ``biases[i]`` and standard deviation
    ``sigmas[i]`` (equal weights; NaN ones left out): the ``x`` where ``mean(P(|e_i| <= x)) = 1/2``. NaN when
    none.

    >>> round(median_abs_of_mixture(np.array([1.0, 1.0])), 4)      # 0.6745 sigma for one normal
    0.6745
    >>> median_abs_of_mixture(np.array([0.0, 0.0, 1.0]))
    0.0
    """
    s = np.asarray(sigmas, np.float64)
    b = np.broadcast_to(np.asarray(biases, np.float64), s.shape)
    keep = np.isfinite(s) & np.isfinite(b)
    s, b = s[keep], np.abs(b[keep])
    if s.size == 0:
        return math.nan
    def below(x: float) -> float:
        """The share of the steps with ``|e| <= x``."""
        exact = s == 0
        inside = np.where(exact, (b <= x).astype(float), 0.0)
        z = np.where(exact, 1.0, s) * math.sqrt(2.0)
        normal = 0.5 * (erf((x - b) / z) - erf((-x - b) / z))
        return float(np.mean(np.where(exact, inside, normal)))

    lo, hi = 0.0, float(np.max(b + 10.0 * s)) or 0.0
    if below(lo) >= 0.5:
        return 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if below(mid) < 0.5 else (lo, mid)
    return 0.5 * (lo + hi)
