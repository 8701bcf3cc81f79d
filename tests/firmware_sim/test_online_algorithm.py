"""The on-line step algorithm (``gaitlog.firmware_sim.algorithms``): analytic results, both arithmetics, streaming,
the compiled kernel against its own Python text, flags, bounded memory."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm, OnlineSteps
from gaitlog.firmware_sim.algorithms.parameters import (
    M4_EXPONENT,
    EventParameters,
    OnlineParameters,
)
from gaitlog.firmware_sim.algorithms.steps import StepTable
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.header import CalibrationSlot
from gaitlog.protocol.steps import StepConfig, StepFlag
from gaitlog.units import STANDARD_GRAVITY_M_S2

SAMPLING_RATE_HZ = 50.0
ROOT = Path(__file__).resolve().parents[2]


def sinusoid_codes(*, seconds: float = 30.0, step_hz: float = 2.0, amplitude_m: float = 0.02, sampling_rate_hz: float = SAMPLING_RATE_HZ,
                   tilt: tuple[float, float, float] = (0.0, 0.0, 1.0), noise_g: float = 0.0, seed: int = 0
                   ) -> np.ndarray:
    """10-bit codes of a centre of mass moving as ``z = -A cos(2 pi f t)`` (lowest at t = 0), tilted device."""
    t = np.arange(int(seconds * sampling_rate_hz)) / sampling_rate_hz
    a_v = amplitude_m * (2 * np.pi * step_hz) ** 2 * np.cos(2 * np.pi * step_hz * t) / STANDARD_GRAVITY_M_S2
    up = np.asarray(tilt, float) / np.linalg.norm(tilt)
    acc = (1.0 + a_v)[:, None] * up[None, :]
    acc += np.random.default_rng(seed).normal(0.0, noise_g, acc.shape)
    return np.clip(np.floor(acc * 256 + 512), 0, 1023).astype(np.int64)


def config(leg: float = 0.9, foot: float = 0.2, **k) -> StepConfig:
    return StepConfig(step_format=1, leg_length_m=leg, foot_length_m=foot, **k)


@pytest.mark.parametrize("arithmetic", ["fixed", "float"])
def test_sinusoid_excursion_and_pendulum_length(arithmetic: str) -> None:
    # h = 2 A = 4 cm for M2 (drift corrected); the pendulum length 2 sqrt(2 l h - h^2) with l = 0.9 m
    steps = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(), arithmetic=arithmetic).run(
        sinusoid_codes(tilt=(0.3, -0.2, 0.93)))
    inner = slice(3, -3)
    h2 = steps.excursion_m()[inner, 1]
    assert np.all(np.abs(h2 - 0.04) < 4e-4)
    expected = 2 * np.sqrt(2 * 0.9 * 0.04 - 0.04 ** 2)
    assert np.all(np.abs(steps.length_m()[inner, 1] - expected) < 0.003)
    # steps are 0.5 s apart, the first has no window
    assert np.all(steps.duration[1:] == 25) and steps.duration[0] == 0
    assert steps.has_flag(StepFlag.NO_WINDOW)[0] and not steps.has_flag(StepFlag.NO_WINDOW)[1:].any()
    # uncalibrated: M5 is the cadence, M4 the raw (g0 range)^p
    np.testing.assert_allclose(steps.length_m()[inner, 4], 2.0, atol=1e-3)
    np.testing.assert_allclose(steps.length_m()[inner, 3],
                               (steps.range_g()[inner] * STANDARD_GRAVITY_M_S2) ** M4_EXPONENT,
                               rtol=1e-3)
    assert steps.has_flag(StepFlag.UNCALIBRATED).all()


def test_k_is_applied_and_m5_line() -> None:
    codes = sinusoid_codes()
    raw = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config()).run(codes)
    cal = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(calibrated=True, k_m1=0.8, k_m2=1.25,
                                                                      k_m4=0.5, k1_m5_m_s=0.3, k2_m5_m=0.1)).run(codes)
    r, c = raw.length_m()[1:], cal.length_m()[1:]
    np.testing.assert_allclose(c[:, 0], 0.8 * r[:, 0], atol=2e-4)
    np.testing.assert_allclose(c[:, 1], 1.25 * r[:, 1], atol=2e-4)
    np.testing.assert_allclose(c[:, 2], r[:, 2], atol=0)                 # M3 has no K
    np.testing.assert_allclose(c[:, 3], 0.5 * r[:, 3], atol=2e-4)
    np.testing.assert_allclose(c[:, 4], 0.3 / 0.5 + 0.1, atol=2e-4)       # K1 / T + K2, T = 0.5 s
    assert not cal.has_flag(StepFlag.UNCALIBRATED).any()


@pytest.mark.parametrize("arithmetic", ["fixed", "float"])
def test_feeding_in_blocks_gives_the_same_records(arithmetic: str, simulated_walk: tuple) -> None:
    codes, _ = simulated_walk
    whole = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(), arithmetic=arithmetic)
    a = whole.run(codes)
    alg = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(), arithmetic=arithmetic)
    rng = np.random.default_rng(5)
    parts, pos = [], 0
    while pos < codes.shape[0]:
        n = int(rng.integers(1, 400))
        parts.append(alg.feed(codes[pos:pos + n]))
        pos += n
    parts.append(alg.flush())
    b = OnlineSteps.concatenate(parts)
    for name in ("end", "duration", "toe_off", "heel_strike", "flags", "lengths", "extras"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.n_steps > 500
    assert whole.cycles.total == alg.cycles.total


def test_fixed_and_float_agree_on_a_walk(simulated_walk: tuple) -> None:
    codes, _ = simulated_walk
    fx = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(), arithmetic="fixed").run(codes)
    fl = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(), arithmetic="float").run(codes)
    common, ia, ib = np.intersect1d(fx.end, fl.end, return_indices=True)
    assert common.size >= 0.995 * max(fx.n_steps, fl.n_steps)
    same = ((fx.duration[ia] == fl.duration[ib]) & (fx.toe_off[ia] == fl.toe_off[ib])
            & (fx.heel_strike[ia] == fl.heel_strike[ib]))
    assert np.count_nonzero(same) >= 0.99 * common.size
    a, b = fx.length_m()[ia[same]], fl.length_m()[ib[same]]
    defined = (a > 0) & (b > 0)
    assert np.array_equal(a > 0, b > 0)
    d = np.abs(a - b)[defined]
    assert np.median(d) <= 1e-4                                          # 0.1 mm
    assert np.max(d / b[defined]) <= 0.01
    ctx = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config())
    ctx.run(codes)
    assert ctx.arithmetic_context().report() == ""                      # nothing saturated on walking


def test_compiled_kernel_equals_its_python_text_bit_for_bit(tmp_path: Path) -> None:
    # the same source run by CPython (NUMBA_DISABLE_JIT) and compiled by numba give identical records
    codes = sinusoid_codes(seconds=12.0, tilt=(0.2, 0.1, 0.97), noise_g=0.01, seed=2)
    np.save(tmp_path / "codes.npy", codes)
    script = (
        "import json, sys, numpy as np\n"
        "from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm\n"
        "from gaitlog.protocol.steps import StepConfig\n"
        f"codes = np.load({str(tmp_path / 'codes.npy')!r})\n"
        "out = {}\n"
        "for ar in ('fixed', 'float'):\n"
        "    alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=StepConfig(step_format=1, "
        "leg_length_m=0.9, foot_length_m=0.2), arithmetic=ar)\n"
        "    s = alg.run(codes)\n"
        "    out[ar] = dict(end=s.end.tolist(), hs=s.heel_strike.tolist(), to=s.toe_off.tolist(), "
        "flags=s.flags.tolist(), lengths=np.asarray(s.lengths).tolist(), cycles=alg.cycles.total)\n"
        "json.dump(out, sys.stdout)\n")
    env = dict(os.environ, NUMBA_DISABLE_JIT="1", PYTHONPATH=str(ROOT))
    py = json.loads(subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True,
                                   check=True, timeout=600).stdout)
    for ar in ("fixed", "float"):
        alg = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(), arithmetic=ar)
        s = alg.run(codes)
        assert s.end.tolist() == py[ar]["end"] and s.heel_strike.tolist() == py[ar]["hs"]
        assert s.toe_off.tolist() == py[ar]["to"] and s.flags.tolist() == py[ar]["flags"]
        if ar == "fixed":
            assert np.asarray(s.lengths).tolist() == py[ar]["lengths"]
            assert alg.cycles.total == py[ar]["cycles"]
        else:
            np.testing.assert_allclose(s.lengths, py[ar]["lengths"], rtol=1e-12, atol=1e-12)


def test_scratch_ring_is_long_enough_for_the_slowest_steps() -> None:
    # 1.4 s steps (near max_step): a much longer scratch ring changes nothing
    codes = sinusoid_codes(seconds=60.0, step_hz=1 / 1.4, amplitude_m=0.03)
    alg = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config())
    a = alg.run(codes)
    big = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config())
    size = int(big.config.cfg_i[kernel.CI_SCRATCH])
    big.config.cfg_i[kernel.CI_SCRATCH] = 8 * size
    big._scr = np.zeros((8 * size, 4), np.int64)
    b = big.run(codes)
    assert a.n_steps > 30 and np.all(a.duration[1:] == 70)
    np.testing.assert_array_equal(a.lengths, b.lengths)
    np.testing.assert_array_equal(a.heel_strike, b.heel_strike)


def test_impossible_excursion_is_flagged_not_hidden() -> None:
    # a 12 cm excursion with a 5 cm "leg": h > 2 l, the pendulum has no solution
    steps = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(leg=0.05, foot=0.1)).run(
        sinusoid_codes(amplitude_m=0.06, step_hz=1.2))
    inner = slice(2, -2)
    assert steps.has_flag(StepFlag.IMPOSSIBLE)[inner].all()
    assert np.all(steps.length_m()[inner, 1] == 0)
    table = StepTable.from_online(steps)
    assert np.isnan(table.length_m["M2"][inner]).all()


def test_saturation_is_counted_and_flagged() -> None:
    # +-2 g square waves: the FIR's pair sums and the integrals leave their words
    t = np.arange(1500)
    z = np.where((t // 12) % 2 == 0, 1023, 0)
    codes = np.column_stack([np.full(t.size, 512), np.full(t.size, 512), z]).astype(np.int64)
    alg = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config())
    steps = alg.run(codes)
    assert alg.saturations > 0
    assert "saturated" in alg.arithmetic_context().report()
    assert steps.has_flag(StepFlag.SATURATED).any()


def test_calibration_matrix_is_used() -> None:
    # a device whose z axis reads 2 % high: with its calibration the excursion comes back right
    codes = sinusoid_codes(tilt=(0.0, 0.0, 1.0))
    hot = np.clip(np.floor((codes - 512) * 1.02 + 512), 0, 1023).astype(np.int64)
    cal = CalibrationSlot(np.full(3, 512.0), np.diag([1 / 256, 1 / 256, 1 / (256 * 1.02)]), True)
    good = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config()).run(codes).excursion_m()[3:-3, 1]
    fixed = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(), calibration=cal).run(hot)
    raw = OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config()).run(hot).excursion_m()[3:-3, 1]
    assert abs(np.median(fixed.excursion_m()[3:-3, 1]) / np.median(good) - 1) < 0.002
    assert abs(np.median(raw) / np.median(good) - 1.02) < 0.003


def test_rates_and_widths_of_the_sweep() -> None:
    for sampling_rate_hz, adc_bits in ((25.0, 10), (100.0, 10), (50.0, 8), (50.0, 12)):
        t = np.arange(int(30 * sampling_rate_hz)) / sampling_rate_hz
        a_v = 0.02 * (4 * np.pi) ** 2 * np.cos(4 * np.pi * t) / STANDARD_GRAVITY_M_S2
        span = 1 << adc_bits
        codes = np.clip(np.floor((np.column_stack([np.zeros_like(t), np.zeros_like(t), 1 + a_v])) * span / 4
                                 + span / 2), 0, span - 1).astype(np.int64)
        h = {ar: np.median(OnlineStepAlgorithm(sampling_rate_hz=sampling_rate_hz, step_config=config(), adc_bits=adc_bits,
                                               arithmetic=ar).run(codes).excursion_m()[3:-3, 1])
             for ar in ("fixed", "float")}
        # the arithmetic costs at most 0.1 mm of h; sampling a 2 Hz step at 25 Hz costs ~5 % (trapezoids)
        assert abs(h["fixed"] - h["float"]) < 1e-4, (sampling_rate_hz, adc_bits, h)
        assert abs(h["float"] - 0.04) < (0.0025 if sampling_rate_hz < 50 else 0.001), (sampling_rate_hz, adc_bits, h)


def test_parameters_are_validated() -> None:
    with pytest.raises(ValueError, match="max_step_s"):
        EventParameters(min_step_s=1.0, max_step_s=0.5)
    with pytest.raises(ValueError, match="median_steps"):
        OnlineParameters(median_steps=4)
    with pytest.raises(ValueError, match="arithmetic"):
        OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config(), arithmetic="double")
    with pytest.raises(ProtocolError, match="leg length"):
        OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=StepConfig(step_format=1))
    with pytest.raises(ValueError, match="ADC codes"):
        OnlineStepAlgorithm(sampling_rate_hz=SAMPLING_RATE_HZ, step_config=config()).feed(np.full((3, 3), 1024))
