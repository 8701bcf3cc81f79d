"""The fixed-point step chain (``firmware_sim.algorithms``) against the float chain, formulas and the walk.

The float chain (``host.gait``, ``host.estimators``) is the independent reference: the same definitions in
float64. The simulated walk (``firmware_sim.world.walking`` through the emulated 10-bit logger) gives the
codes; lost samples are injected to exercise the masks.
"""

from __future__ import annotations

from fractions import Fraction
from types import SimpleNamespace

import numpy as np
import pytest

from firmware_sim.algorithms.axes import vertical_acceleration_q
from firmware_sim.algorithms.cadence import CadenceM5Q, cadence_q
from firmware_sim.algorithms.calibration import CalibrationQ, nominal_calibration_q
from firmware_sim.algorithms.chain import FixedStepChain
from firmware_sim.algorithms.formats import (
    ACC_Q,
    EXCURSION_Q,
    LENGTH_Q,
    LOWPASS_OUT_Q,
    M5_Q,
    POSITION_Q,
    ROOT4_Q,
    STEP_Q,
    ram_bytes,
    state_variables,
)
from firmware_sim.algorithms.integration import (
    M2_EXTRA_BITS,
    position_unit_m,
    step_samples_q,
    vertical_positions_q,
)
from firmware_sim.algorithms.lowpass import masked_gaussian_lowpass_q
from firmware_sim.algorithms.pendulum import excursion_q, pendulum_length_q
from firmware_sim.algorithms.weinberg import root4_q
from firmware_sim.fixedpoint import ArithmeticContext

G0 = 9.80665
FS = 50.0


@pytest.fixture(scope="module")
def walk() -> SimpleNamespace:
    """A short protocol (30 m corridor, two speeds) through the emulated 10-bit logger, with lost samples."""
    from firmware_sim.adc import Adc
    from firmware_sim.device import Logger
    from firmware_sim.world.gait_protocol import WalkingProtocol
    from firmware_sim.world.subject import Subject
    from firmware_sim.world.walking import Walking

    subject = Subject.random(np.random.default_rng(3))
    protocol = WalkingProtocol(corridor_length_m=30.0, speeds=("preferred", "fast"), rest_s=8.0,
                               rest_postures=("standing",), lap_marks_m=(0.0, 10.0, 30.0, 50.0, 60.0))
    res = Logger(adc=Adc(bits=10, rate_hz=FS), sample_rate_hz=FS, device_id=5).record(
        Walking(subject=subject, protocol=protocol, seed=3))
    codes = np.asarray(res.codes, np.int64)
    rng = np.random.default_rng(11)
    valid = np.ones(codes.shape[0], bool)
    for s in rng.choice(codes.shape[0] - 5, 40, replace=False):   # 40 short losses of 1-3 samples
        valid[s:s + rng.integers(1, 4)] = False
    return SimpleNamespace(codes=codes, valid=valid, subject=subject, truth=res.truth)


def float_chain(codes: np.ndarray, valid: np.ndarray, subject: object, calibration: object = None) -> object:
    from host.gait.pipeline import StepPipeline
    from protocol.header import Calibration

    acc = Calibration.nominal(10).apply(codes.astype(np.float64))
    acc[~valid] = np.nan
    return StepPipeline(leg_length_m=subject.leg_length_m, foot_length_m=subject.foot_length_m,
                        calibration=calibration).run(acc, sampling_rate_hz=FS, valid=valid)


# ---------------------------------------------------------------------------------------------------------
# stages


def test_calibration_matches_protocol_float_map() -> None:
    from protocol.header import Calibration

    rng = np.random.default_rng(1)
    for _ in range(5):
        m = np.diag(rng.uniform(1 / 270, 1 / 240, 3)) + rng.uniform(-2e-4, 2e-4, (3, 3))
        cal = Calibration(rng.uniform(490, 535, 3), m, True)
        calq = CalibrationQ.from_slot(*_slot_ints(cal))
        codes = rng.integers(0, 1024, (5000, 3))
        fixed = ACC_Q.to_float(calq.apply(codes))
        ref = cal.apply(codes.astype(np.float64))
        # offset rounding (1/64 count), mantissas (2^-15 relative) and the final rounding: < 2 lsb
        assert np.max(np.abs(fixed - ref)) <= 2 * ACC_Q.lsb
        assert abs(np.mean(fixed - ref)) < 0.5 * ACC_Q.lsb


def _slot_ints(cal: object) -> tuple[np.ndarray, np.ndarray]:
    raw = cal.to_bytes()
    off = np.frombuffer(raw[4:16], "<i4").astype(np.int64)
    mat = np.frombuffer(raw[16:52], "<i4").astype(np.int64)
    return off, mat


def test_nominal_calibration_is_exact_on_codes() -> None:
    codes = np.array([[0, 512, 1023], [256, 768, 511]])
    assert ACC_Q.to_float(nominal_calibration_q().apply(codes)).tolist() == ((codes - 512) / 256).tolist()
    with pytest.raises(ValueError, match="0 .. 1023"):
        nominal_calibration_q().apply(np.array([[1024, 0, 0]]))


def test_vertical_acceleration_matches_float_axes(walk: SimpleNamespace) -> None:
    from host.gait.axes import body_axes

    acc_q = nominal_calibration_q().apply(np.where(walk.valid[:, None], walk.codes, 512))
    av_q, _, ok = vertical_acceleration_q(acc_q, sampling_rate_hz=FS, valid=walk.valid)
    acc = ACC_Q.to_float(acc_q)
    acc[~walk.valid] = np.nan
    ref = body_axes(acc, sampling_rate_hz=FS, valid=walk.valid)
    np.testing.assert_array_equal(ok, ref.valid)
    d = ACC_Q.to_float(av_q[ok]) - ref.acc_v_m_s2[ok] / G0
    assert np.max(np.abs(d)) <= 3 * ACC_Q.lsb
    assert abs(np.mean(d)) < 0.05 * ACC_Q.lsb          # no bias (a bias would drift M1's integrals)


def test_lowpass_matches_float_masked_gaussian(walk: SimpleNamespace) -> None:
    from host.gait.masked_filter import masked_gaussian_lowpass

    rng = np.random.default_rng(5)
    x = rng.integers(-12000, 12000, 5000)
    valid = rng.random(5000) > 0.1
    for cutoff in (3.0, 10.0):
        y, defined = masked_gaussian_lowpass_q(x, valid, cutoff_hz=cutoff, sampling_rate_hz=FS)
        ref = masked_gaussian_lowpass(ACC_Q.to_float(x), valid, cutoff_hz=cutoff, sampling_rate_hz=FS)
        same = defined == np.isfinite(ref)
        assert same.mean() > 0.999                          # only at the min-weight threshold
        both = defined & np.isfinite(ref)
        # weights rounded to 2^-14: a relative 2^-13 of the signal, plus the output rounding
        err = np.abs(LOWPASS_OUT_Q.to_float(y[both]) - ref[both])
        assert np.max(err) <= 2e-4 * 1.5 + LOWPASS_OUT_Q.lsb


def test_integration_matches_float_positions() -> None:
    from host.gait.integration import step_samples, vertical_positions

    rng = np.random.default_rng(7)
    n = 2000
    t = np.arange(n) / FS
    a_g = 0.25 * np.cos(2 * np.pi * 1.9 * t) + 0.03 * rng.standard_normal(n) + 0.01
    a_q = ACC_Q.from_float(a_g)
    valid = rng.random(n) > 0.03
    starts = np.arange(10, n - 40, 26)
    starts = starts[valid[starts]]
    ends = starts[1:]
    starts = starts[:-1]
    ss = step_samples_q(starts, ends, valid)
    pos = vertical_positions_q(a_q, ss)
    ssf = step_samples(starts, ends, valid, FS)
    p1, p2 = vertical_positions(ACC_Q.to_float(a_q) * G0, ssf)
    np.testing.assert_array_equal(ss.index, ssf.index)
    # M1 integrates exactly (no rounding at all): equal to float rounding
    np.testing.assert_allclose(pos.p1 * position_unit_m(FS, m2=False), p1, atol=1e-12)
    # M2: the c1/c2 roundings only (c1 to half a 2^-17 g lsb: ~T^2/8 * 2^-18 g, a few um)
    assert np.max(np.abs(pos.p2 * position_unit_m(FS, m2=True) - p2)) < 5e-6


def test_saturating_accumulator_matches_clipping_loop() -> None:
    big = ACC_Q.max_raw
    a = np.r_[np.full(38, big), np.full(37, -big)]          # +4 g then -4 g over a 75-sample step
    ss = step_samples_q(np.array([0]), np.array([74]), np.ones(75, bool))
    ctx = ArithmeticContext()
    pos = vertical_positions_q(a, ss, ctx=ctx)
    assert ctx.saturated["integration.p2"] > 0
    # reference: the firmware's loop in Python ints, clipping the 32-bit position accumulator
    lo, hi = POSITION_Q.min_raw, POSITION_Q.max_raw
    v_end = sum((int(a[k]) + int(a[k - 1])) for k in range(1, 75))
    scale = 1 << (M2_EXTRA_BITS - 1)
    num, den = -v_end * scale, 74
    c1 = (abs(num) + den // 2) // den * (1 if num >= 0 else -1)
    a2 = [(int(x) << M2_EXTRA_BITS) + c1 for x in a]
    v, p, ps = 0, 0, [0]
    vs = [0]
    for k in range(1, 75):
        v = min(max(v + a2[k] + a2[k - 1], lo), hi)
        vs.append(v)
        p = min(max(p + vs[k] + vs[k - 1], lo), hi)
        ps.append(p)
    c2 = (abs(ps[-1]) + 37) // 74 * (1 if ps[-1] >= 0 else -1)
    ref = [min(max(x - c2 * k, lo), hi) for k, x in enumerate(ps)]
    assert pos.p2.tolist() == ref


@pytest.mark.parametrize("leg", [0.6, 0.9, 1.2])
def test_pendulum_length_against_formula(leg: float) -> None:
    rng = np.random.default_rng(int(leg * 10))
    h = EXCURSION_Q.from_float(rng.uniform(0, 0.3, 5000))
    lq = int(LENGTH_Q.from_float(leg))
    s, bad = pendulum_length_q(h, lq)
    hf, lf = EXCURSION_Q.to_float(h), LENGTH_Q.to_float(lq)
    ref = 2 * np.sqrt(2 * lf * hf - hf ** 2)
    assert not bad.any()
    err = STEP_Q.to_float(s) - ref
    assert np.max(np.abs(err)) <= 1.01 * STEP_Q.lsb      # floor of the square root, h^2 rounded
    s2, bad2 = pendulum_length_q(EXCURSION_Q.from_float(np.array([0.9])), int(LENGTH_Q.from_float(0.4)))
    assert bad2.tolist() == [True]                                    # h > 2 l: impossible, flagged


def test_excursion_conversion_and_root4() -> None:
    unit = position_unit_m(FS, m2=True)
    units = np.array([0, 1000, 123456, int(0.25 / unit), int(0.999 / unit), int(5.0 / unit)])
    ctx = ArithmeticContext()
    h = EXCURSION_Q.to_float(excursion_q(units, unit, ctx=ctx))
    ref = np.minimum(units * unit, EXCURSION_Q.max_value)
    assert np.max(np.abs(h - ref)) <= 2 * EXCURSION_Q.lsb       # two roundings (shift, scale)
    assert ctx.saturated["pendulum.excursion"] >= 1                 # the 5 m one (shift and scale)
    assert h[-1] == EXCURSION_Q.max_value and np.all(h[:-1] < EXCURSION_Q.max_value)
    r = np.arange(0, 65536, 37)
    root = ROOT4_Q.to_float(root4_q(r))
    ref4 = (r / 2 ** 13) ** 0.25
    assert np.all(root <= ref4 + 1e-12) and np.all(ref4 - root < 2 * ROOT4_Q.lsb)


def test_m5_cadence_rounding_is_exact() -> None:
    t = np.arange(10, 160)
    got = cadence_q(t, FS)
    for ti, g in zip(t.tolist(), got.tolist()):
        exact = Fraction(int(M5_Q.from_float(FS)), ti)
        assert g == int(exact + Fraction(1, 2))
    m5 = CadenceM5Q(k1_m_s=0.32, k2_m=0.05).estimate(step_samples=t, sampling_rate_hz=FS)
    assert np.max(np.abs(m5.step_length_m_ - (0.32 * FS / t + 0.05))) <= STEP_Q.lsb


def test_ram_budget_fits_the_pic() -> None:
    total = ram_bytes()
    assert total == sum(v.fmt.ram_bytes * v.count for v in state_variables())
    assert total <= 368
    assert ram_bytes(state_variables(sampling_rate_hz=100.0, lowpass_radius=18, detail_radius=6,
                                     hs_search=20, hs_after=6)) <= 368


# ---------------------------------------------------------------------------------------------------------
# the whole chain, fixed vs float on the same codes


def _same_event_steps(fx: object, fl: object) -> tuple[np.ndarray, np.ndarray, int]:
    """Rows of both tables whose step has the same window and events (matched by foot-flat sample)."""
    a, b = fx.steps_, fl.steps_
    _, ia, ib = np.intersect1d(a.foot_flat, b.foot_flat, return_indices=True)
    same = ((a.start[ia] == b.start[ib]) & (a.heel_strike[ia] == b.heel_strike[ib])
            & (a.toe_off[ia] == b.toe_off[ib]))
    n_diff = max(a.n_steps, b.n_steps) - int(np.count_nonzero(same))
    return ia[same], ib[same], n_diff


def test_chain_fixed_vs_float_same_codes(walk: SimpleNamespace) -> None:
    cal = SimpleNamespace(k_m1=0.98, k_m2=1.05, k_m4=0.45, k1_m5_m_s=0.33, k2_m5_m=0.12)
    fx = FixedStepChain(leg_length_m=walk.subject.leg_length_m, foot_length_m=walk.subject.foot_length_m,
                        calibration=cal).run(walk.codes, sampling_rate_hz=FS, valid=walk.valid)
    fl = float_chain(walk.codes, walk.valid, walk.subject, calibration=_k_calibration(cal, walk.subject))
    assert fx.ctx_.report() == ""                                   # no saturation on walking
    ia, ib, n_diff = _same_event_steps(fx, fl)
    assert fl.steps_.n_steps > 100
    assert n_diff <= 0.02 * fl.steps_.n_steps
    for name in ("M1", "M2", "M3", "M4", "M5"):
        x, y = fx.steps_.length_m[name][ia], fl.steps_.length_m[name][ib]
        both = np.isfinite(x) & np.isfinite(y)
        assert np.count_nonzero(np.isfinite(x) != np.isfinite(y)) == 0, name
        d = np.abs(x[both] - y[both])
        assert np.median(d) <= 1e-3, name
        assert np.max(d / y[both]) <= 0.01, name
    assert 0 < fx.cycles_per_sample_ < 100_000


def _k_calibration(cal: SimpleNamespace, subject: object) -> object:
    from host.estimators.calibration import KCalibration

    return KCalibration(k_m1=cal.k_m1, k_m2=cal.k_m2, k_m4=cal.k_m4, k1_m5_m_s=cal.k1_m5_m_s, k2_m5_m=cal.k2_m5_m,
                        mode="single-speed", m5_fallback=False, leg_length_m=subject.leg_length_m,
                        foot_length_m=subject.foot_length_m, n_sections=1, n_steps=10, distance_m=40.0)


def test_chain_detects_the_walks_steps(walk: SimpleNamespace) -> None:
    fx = FixedStepChain(leg_length_m=walk.subject.leg_length_m,
                        foot_length_m=walk.subject.foot_length_m).run(walk.codes, sampling_rate_hz=FS)
    truth_ff = np.asarray(walk.truth["steps"]["next_foot_flat_s"], np.float64)
    t = fx.steps_.foot_flat / FS
    tol = 0.1
    matched = np.abs(t[:, None] - truth_ff[None, :]).min(axis=0) <= tol
    assert matched.mean() >= 0.9


def test_chain_reports_saturation_on_violent_input() -> None:
    n = 1500
    codes = np.full((n, 3), 512)
    codes[:, 2] = np.where((np.arange(n) // 25) % 2 == 0, 1023, 300)   # +2 g / -0.8 g square wave
    ch = FixedStepChain(leg_length_m=0.9, foot_length_m=0.26).run(codes, sampling_rate_hz=FS)
    assert ch.steps_.n_steps > 0
    assert ch.ctx_.total_saturated > 0
    assert "saturated" in ch.ctx_.report()


def test_chain_rejects_bad_input() -> None:
    ch = FixedStepChain(leg_length_m=0.9, foot_length_m=0.26)
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        ch.run(np.zeros((10, 2), int), sampling_rate_hz=FS)
    with pytest.raises(ValueError, match="positive"):
        ch.run(np.zeros((10, 3), int), sampling_rate_hz=0.0)
    with pytest.raises(ValueError, match="valid must have shape"):
        ch.run(np.zeros((10, 3), int), sampling_rate_hz=FS, valid=np.ones(3, bool))


def test_window_reductions_respect_window_ends() -> None:
    valid = np.ones(12, bool)
    valid[5:8] = False                                   # the middle window has no measured sample
    ss = step_samples_q(np.array([0, 5, 8]), np.array([4, 7, 11]), valid)
    x = np.arange(12) * 10 - 100
    assert ss.n_measured.tolist() == [5, 0, 4]
    assert ss.reduce_max(x[ss.index]).tolist() == [-60, 0, 10]
    assert ss.reduce_min(x[ss.index]).tolist() == [-100, 0, -20]
    assert ss.defined.tolist() == [True, False, True]


def _synthetic_codes(n: int, fs: float, bits: int) -> np.ndarray:
    """Codes of a tilted sensor on a CoM moving at ~1.8 steps/s (2.5 cm), with impacts, AP sway and noise."""
    rng = np.random.default_rng(int(fs) + bits)
    t = np.arange(n) / fs
    f = 1.8 * (1 + 0.05 * np.sin(2 * np.pi * t / 30.0))
    phase = 2 * np.pi * np.cumsum(f) / fs
    a_v = 0.0125 * (2 * np.pi * f) ** 2 * np.cos(phase) / G0
    # heel-strike impact (0.3 g, sigma 15 ms) at the CoM's lowest point: without it the heel-strike band
    # holds only noise and its peak is a near-tie between the two arithmetics
    lag_s = (np.angle(np.exp(1j * phase))) / (2 * np.pi * f)
    a_v = a_v + 0.3 * np.exp(-0.5 * (lag_s / 0.015) ** 2)
    up = np.array([0.2, 0.1, 0.9747])
    fwd = np.cross([0.0, 1.0, 0.0], up)
    fwd /= np.linalg.norm(fwd)
    acc = (1 + a_v)[:, None] * up + 0.15 * np.sin(phase + 0.5)[:, None] * fwd + rng.normal(0, 0.004, (n, 3))
    span = 1 << bits
    return np.clip(np.floor(acc * span / 4 + span / 2), 0, span - 1).astype(np.int64)


@pytest.mark.parametrize("bits,fs", [(8, 50.0), (12, 50.0), (10, 25.0), (10, 100.0)])
def test_chain_sweep_configurations_agree_with_float(bits: int, fs: float) -> None:
    from host.gait.pipeline import StepPipeline
    from protocol.header import Calibration

    codes = _synthetic_codes(int(60 * fs), fs, bits)
    fx = FixedStepChain(leg_length_m=0.9, foot_length_m=0.26).run(
        codes, sampling_rate_hz=fs, adc_calibration=nominal_calibration_q(adc_bits=bits))
    span = float(1 << bits)
    acc = (codes - span / 2) * (4.0 / span)
    if bits <= 10:
        np.testing.assert_allclose(acc, Calibration.nominal(bits).apply(codes.astype(np.float64)))
    fl = StepPipeline(leg_length_m=0.9, foot_length_m=0.26).run(acc, sampling_rate_hz=fs)
    assert fx.ctx_.report() == ""
    ia, ib, n_diff = _same_event_steps(fx, fl)
    assert fl.steps_.n_steps > 90 and n_diff <= 0.03 * fl.steps_.n_steps
    for name in ("M1", "M2", "M3", "M4"):
        x, y = fx.steps_.raw_m[name][ia], fl.steps_.raw_m[name][ib]
        g = np.isfinite(x) & np.isfinite(y)
        d = np.abs(x[g] - y[g])
        assert np.median(d) <= 1e-3 and np.max(d / y[g]) <= 0.01, name


def _round_div(n: int, d: int) -> int:
    """Ties away from zero, Python ints."""
    q = (abs(n) + d // 2) // d
    return q if n >= 0 else -q


def test_vectorised_axes_equal_the_per_sample_firmware_loop() -> None:
    import math

    rng = np.random.default_rng(21)
    n, w = 400, 50
    acc = ACC_Q.from_float(np.array([0.1, 0.2, 0.97]) + rng.normal(0, 0.3, (n, 3)))
    valid = rng.random(n) > 0.1
    av, g, ok = vertical_acceleration_q(acc, sampling_rate_hz=FS, valid=valid, gravity_window_s=w / FS)
    # firmware: running sums updated by the entering and leaving samples, then per-sample integer maths
    sums, count = [0, 0, 0], 0
    lo_off, hi_off = w // 2, w - 1 - w // 2
    ref_av = []
    for i in range(n):                                    # window of sample i: [i - w//2, i + hi_off]
        lo, hi = max(0, i - lo_off), min(n - 1, i + hi_off)
        if i == 0:
            for k in range(lo, hi + 1):
                if valid[k]:
                    sums = [s + int(acc[k, j]) for j, s in enumerate(sums)]
                    count += 1
        else:
            enter, leave = i + hi_off, i - lo_off - 1
            if enter < n and valid[enter]:
                sums = [s + int(acc[enter, j]) for j, s in enumerate(sums)]
                count += 1
            if leave >= 0 and valid[leave]:
                sums = [s - int(acc[leave, j]) for j, s in enumerate(sums)]
                count -= 1
        gi = [_round_div(s, count) for s in sums]
        norm2 = sum(x * x for x in gi)
        r = math.isqrt(norm2)
        gn = r + 1 if norm2 - r * r > r else r
        if not (valid[i] and gn > int(ACC_Q.from_float(0.2))):
            ref_av.append(None)
            continue
        dot = sum(int(acc[i, j]) * gi[j] for j in range(3))
        ref_av.append(_round_div(dot - norm2, gn))
    assert ok.tolist() == [x is not None for x in ref_av]
    assert [int(v) for v, k in zip(av, ok) if k] == [x for x in ref_av if x is not None]


def test_vectorised_lowpass_equals_the_mac_loop() -> None:
    from firmware_sim.algorithms.lowpass import gaussian_kernel_q

    rng = np.random.default_rng(22)
    n = 300
    x = rng.integers(-9000, 9000, n)
    valid = rng.random(n) > 0.15
    y, defined = masked_gaussian_lowpass_q(x, valid, cutoff_hz=3.0, sampling_rate_hz=FS, min_weight=0.25)
    wq = gaussian_kernel_q(3.0, FS).tolist()
    r = (len(wq) - 1) // 2
    thr = int(np.ceil(0.25 * sum(wq)))
    for i in range(n):
        num = den = 0
        for k, wk in enumerate(wq):                       # one MAC per tap
            j = i + k - r
            if 0 <= j < n and valid[j]:
                num += wk * int(x[j])
                den += wk
        assert bool(defined[i]) == (den >= thr)
        if den >= thr:
            assert int(y[i]) == _round_div(num * 8, den)   # Q2.13 -> Q2.16: three more bits
