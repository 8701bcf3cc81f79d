"""The kernel compiled for other Q formats (:mod:`gaitlog.firmware_sim.algorithms.format_kernel`): the same text, the
shipped formats bit for bit the kernel built ahead of time, coarser ones further from the float kernel."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms import format_kernel
from gaitlog.firmware_sim.algorithms import formats as fm
from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.protocol.steps import StepConfig
from gaitlog.units import STANDARD_GRAVITY_M_S2

RATE_HZ = 50.0
LEG_M, H_M = 0.9, 0.04


def noisy_sinusoid_codes(seconds: float = 40.0) -> np.ndarray:
    """10-bit codes of a centre of mass moving as ``z = -h/2 cos(2 pi 2 t)`` (h = 4 cm), tilted, with 3 mg noise."""
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    a_v = H_M / 2 * (2 * np.pi * 2.0) ** 2 * np.cos(2 * np.pi * 2.0 * t) / STANDARD_GRAVITY_M_S2
    up = np.array([0.93, -0.2, 0.3]) / np.linalg.norm([0.93, -0.2, 0.3])
    acc = (1.0 + a_v)[:, None] * up + np.random.default_rng(1).normal(0.0, 0.003, (t.size, 3))
    return np.clip(np.floor(acc * 256 + 512), 0, 1023).astype(np.int64)


def run(formats: KernelFormats | None, codes: np.ndarray, kernel_fns=None, arithmetic: str = "fixed"):
    alg = OnlineStepAlgorithm(sampling_rate_hz=RATE_HZ, step_config=StepConfig(step_format=1, leg_length_m=LEG_M,
                                                                               foot_length_m=0.2),
                              formats=formats, arithmetic=arithmetic)
    if kernel_fns is not None:
        alg._process, alg._flush, alg._reset = kernel_fns
        alg.reset()
    return alg.run(codes), alg


def test_default_formats_are_the_module_constants() -> None:
    k = KernelFormats()
    assert k.shipped and k.acc_q == fm.ACC_Q and k.lowpass_q == fm.LOWPASS_Q and k.position2_q == fm.POSITION2_Q
    assert k.position_q == fm.POSITION_Q
    assert k.constants() == dict(F_ACC=fm.F_ACC, F_POS=fm.F_POS, F_GRAV=fm.F_GRAV, F_LP=fm.F_LP, W_LP=fm.W_LP,
                                 F_POS2=fm.F_POS2, F_ACC2=fm.F_ACC2, F_FIR=fm.F_FIR, F_KERNEL=fm.F_KERNEL,
                                 F_EXC=fm.F_EXC, F_EXC2=fm.F_EXC2, F_ROOT=fm.F_ROOT, F_STEP=fm.F_STEP, F_K=fm.F_K,
                                 F_K4=fm.F_K4, F_M5=fm.F_M5, F_TWO_LEN=fm.F_TWO_LEN, F_PARG=fm.F_PARG,
                                 F_PARG2=fm.F_PARG2, W_CODE=fm.W_CODE, W_ACC=fm.W_ACC, W_GRAV=fm.W_GRAV,
                                 W_ACC2=fm.W_ACC2, W_FIR=fm.W_FIR, W_VEL=fm.W_VEL, W_POS=fm.W_POS, W_POS2=fm.W_POS2,
                                 W_EXC=fm.W_EXC, W_EXC2=fm.W_EXC2, W_PARG=fm.W_PARG, W_PARG2=fm.W_PARG2,
                                 W_STEP=fm.W_STEP, W_ROOT=fm.W_ROOT, W_M5=fm.W_M5)
    assert k.mantissa_frac_bits == fm.MANTISSA_Q.frac_bits and k.rounding_label() == "shipped"
    assert k.rounding_constants() == dict(ROUND_MUL=1, ROUND_SHIFT=1, ROUND_DIV=1)
    assert not KernelFormats(acc_frac_bits=10).shipped
    with pytest.raises(ValueError, match="acc_frac_bits"):
        KernelFormats(acc_frac_bits=fm.F_ACC + 1)          # only narrower: the range is kept
    with pytest.raises(ValueError, match="lowpass_frac_bits"):
        KernelFormats(lowpass_frac_bits=0)
    with pytest.raises(ValueError, match="shipped"):
        format_kernel.entry_points(KernelFormats())


def test_shipped_formats_compiled_as_a_variant_are_the_aot_kernel_bit_for_bit() -> None:
    codes = noisy_sinusoid_codes()
    ref, a_ref = run(None, codes)
    var, a_var = run(None, codes, format_kernel.compile_kernel(KernelFormats()))
    for name in ("end", "duration", "toe_off", "heel_strike", "flags", "lengths", "extras"):
        np.testing.assert_array_equal(getattr(var, name), getattr(ref, name), err_msg=name)
    np.testing.assert_array_equal(a_var._cnt, a_ref._cnt)              # calls, cycles, saturations counted alike
    assert ref.n_steps > 60


def test_labels_name_the_formats_and_parse_back() -> None:
    assert KernelFormats().label() == "shipped" and KernelFormats.parse("shipped") == KernelFormats()
    k = KernelFormats.parse("lp12-acc10")
    assert (k.acc_frac_bits, k.lowpass_frac_bits, k.gravity_frac_bits) == (10, 12, fm.F_GRAV)
    assert k.label() == "acc10-lp12" and KernelFormats.parse(k.label()) == k
    assert k.acc_q.total_bits == fm.ACC_Q.total_bits and k.acc_q.frac_bits == 10       # same word, coarser lsb
    assert k.constants()["W_LP"] == fm.W_LP - 4                                        # still saturates at 4 g
    for bad in ("acc", "acc10-acc9", "foo3", "acc14", ""):
        with pytest.raises(ValueError):
            KernelFormats.parse(bad)


def test_coarser_formats_move_the_fixed_point_chain_away_from_float() -> None:
    """The float kernel is the reference: the shipped formats stay within a few 0.1 mm of it, 4 fraction bits of
    a_v and 8 of the lowpass do not (the sweep's question, answered on one synthetic walk)."""
    codes = noisy_sinusoid_codes()
    flt, _ = run(None, codes, arithmetic="float")
    ref, _ = run(None, codes)
    narrow = KernelFormats(acc_frac_bits=4, lowpass_frac_bits=8)
    got, alg = run(narrow, codes)
    assert alg.compiled_by == "variant" and alg.config.formats == narrow and got.formats == narrow
    assert format_kernel.entry_points(narrow)[0] is alg._process          # compiled once per process
    np.testing.assert_array_equal(ref.end, flt.end)
    n = min(flt.n_steps, got.n_steps)
    assert n > 60 and not np.array_equal(got.lengths[:n], ref.lengths[:n])
    err = [np.median(np.abs(s.length_m()[3:n - 3, :4] - flt.length_m()[3:n - 3, :4]), axis=0) for s in (ref, got)]
    assert np.all(err[0] < 5e-4), err[0]                                  # shipped: < 0.5 mm of float (M1-M4)
    assert np.max(err[1]) > 10 * np.max(err[0]) and np.max(err[1]) > 1e-3, err


def test_rounding_and_new_format_labels_parse_back() -> None:
    assert KernelFormats.parse("shipped", "half-up") == KernelFormats()            # the shipped modes, named
    t = KernelFormats.parse("shipped", "truncate")
    assert (t.mul_rounding, t.shift_rounding, t.div_rounding) == ("truncate",) * 3 and t.rounding_label() == "truncate"
    assert t.rounding_constants() == dict(ROUND_MUL=0, ROUND_SHIFT=0, ROUND_DIV=0) and not t.compiled_shipped
    m = KernelFormats.parse("k12-step12-lpint1", "div:convergent+mul:truncate")
    assert (m.k_frac_bits, m.step_frac_bits, m.lowpass_int_bits, m.lowpass_word_bits) == (12, 12, 1, 18)
    assert m.rounding_label() == "mul:truncate+div:convergent" and m.label() == "step12-k12-lpint1"
    assert KernelFormats.parse(m.label(), m.rounding_label()) == m
    assert m.constants()["F_K"] == 12 and m.constants()["F_STEP"] == 12 and m.constants()["W_LP"] == 18
    assert KernelFormats(mantissa_frac_bits=10).compiled_shipped                   # configuration, not compiled
    assert len({format_kernel.cache_key(f) for f in (KernelFormats(), t, m)}) == 3
    for bad in ("mul:floor", "add:truncate", "mul:truncate+mul:half-up", "nearest"):
        with pytest.raises(ValueError, match="rounding"):
            KernelFormats.parse("shipped", bad)
    with pytest.raises(ValueError, match="lowpass_int_bits"):
        KernelFormats(lowpass_int_bits=8)


def test_truncation_biases_the_lengths_down_and_saves_cycles() -> None:
    """Every class truncated (floor): each rounding loses half an lsb on average, so the fixed-point lengths fall
    below the shipped (half-up) ones against float, and the rounding additions are not paid; the mantissa bits
    (configuration) run the shipped compiled kernel."""
    codes = noisy_sinusoid_codes()
    flt, _ = run(None, codes, arithmetic="float")
    ref, a_ref = run(None, codes)
    trunc = KernelFormats.parse("step10-k10", "truncate")
    got, alg = run(trunc, codes)
    assert alg.config.formats == trunc and got.formats == trunc
    n = min(flt.n_steps, ref.n_steps, got.n_steps)
    bias = [np.median(s.length_m()[3:n - 3, :2] - flt.length_m()[3:n - 3, :2]) for s in (ref, got)]
    assert bias[1] < bias[0] - 2.0 ** -11, bias            # two truncations of 2^-10 m: ~1 mm lower
    assert alg.cycles.mean < a_ref.cycles.mean
    mant, a_mant = run(KernelFormats(mantissa_frac_bits=8), codes)
    assert a_mant.compiled_by == "aot"
    # the nominal matrix is a power of two (exact in 8 bits); a device calibration is rounded to 8-bit mantissas
    from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ

    cal = CalibrationQ.from_float(np.array([511.3, 509.8, 515.1]), np.array([[0.0039, 1e-4, 0], [0, 0.00401, 0],
                                                                             [2e-5, 0, 0.00383]]))
    coarse = cal.with_mantissa_bits(8)
    step = 2.0 ** -coarse.matrix_frac_bits
    assert coarse.matrix_frac_bits == cal.matrix_frac_bits - 7 and np.max(np.abs(coarse.mantissa_raw)) < 1 << 8
    assert 0 < np.max(np.abs(coarse.matrix_g_per_count - cal.matrix_g_per_count)) <= step / 2


def test_a_variant_is_built_once_per_machine_and_loaded_without_compiling() -> None:
    """The first process that needs a format set builds its module into the compile cache; another process (a
    sweep's worker) loads it without numba: it cannot have compiled anything."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    from gaitlog.firmware_sim.algorithms import aot_kernel
    from gaitlog.firmware_sim.compiled import cache_base

    if not aot_kernel.enabled():
        pytest.skip("the ahead-of-time kernels are off (GAITLOG_NO_AOT or NUMBA_DISABLE_JIT)")
    narrow = KernelFormats(acc_frac_bits=4, lowpass_frac_bits=8)
    format_kernel.entry_points(narrow)
    folder = format_kernel.variant_folder(narrow)
    if list(folder.parent.glob(folder.name + ".failed")):
        pytest.skip("no compiler here: the variant is JIT-compiled in each process")
    assert len(list(folder.glob("*.so"))) == 1
    script = ("import sys\n"
              "from gaitlog.firmware_sim.algorithms import format_kernel as f\n"
              "fns = f.entry_points(f.KernelFormats(acc_frac_bits=4, lowpass_frac_bits=8))\n"
              "print('numba' in sys.modules, type(fns[0]).__name__)\n")
    env = dict(os.environ, GAITLOG_CACHE_DIR=str(cache_base()),
               PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["False", "builtin_function_or_method"], out.stdout


def _sine_codes(amplitude_g: float, frequency_hz: float = 2.0, seconds: float = 40.0) -> np.ndarray:
    """10-bit codes of a vertical acceleration ``A sin(2 pi f t)`` (ramped in over 4 s, so the gravity estimate
    starts settled), tilted, with 3 mg noise."""
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    a_v = amplitude_g * np.minimum(t / 4.0, 1.0) * np.sin(2 * np.pi * frequency_hz * t)
    up = np.array([0.93, -0.2, 0.3]) / np.linalg.norm([0.93, -0.2, 0.3])
    acc = (1.0 + a_v)[:, None] * up + np.random.default_rng(1).normal(0.0, 0.003, (t.size, 3))
    return np.clip(np.floor(acc * 256 + 512), 0, 1023).astype(np.int64)


def test_a_narrower_lowpass_word_saturates_where_its_range_says() -> None:
    """``lpint0``: the lowpass outputs in a sign + 0 integer + 16 fraction-bit word, range [-1, 1) g. The 3 Hz
    Gaussian (-3 dB at 3 Hz) passes a 2 Hz sine with gain ``2^(-(2/3)^2 / 2)`` = 0.857, and the largest lowpass
    value the chain forms is the step's peak-to-peak rise ``MX - MN`` = 2 x 0.857 A: the word saturates from
    A = 1 / (2 x 0.857) = 0.583 g on. 3 % below it nothing saturates, 3 % above it every step does; the shipped
    19-bit word (±4 g) holds both."""
    gain = 2.0 ** (-((2.0 / 3.0) ** 2) / 2.0)
    limit_g = 2.0 ** 0 / (2.0 * gain)
    narrow = KernelFormats(lowpass_int_bits=0)
    assert narrow.lowpass_word_bits == 17 and narrow.label() == "lpint0"
    below, a_below = run(narrow, _sine_codes(0.97 * limit_g))
    above, a_above = run(narrow, _sine_codes(1.03 * limit_g))
    assert below.n_steps > 60 and a_below.saturations == 0 and a_below.wraps == 0
    assert a_above.saturations >= above.n_steps > 60 and a_above.wraps == 0
    _, shipped = run(None, _sine_codes(1.03 * limit_g))
    assert shipped.saturations == 0
