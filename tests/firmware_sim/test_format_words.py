"""Narrower words of the Q formats (:class:`gaitlog.firmware_sim.algorithms.format_kernel.KernelFormats`' word
fields): every store of a value of a format saturates at its word, where the analytic range says, as many times
as ``gaitlog ranges``' machinery predicts from the shipped run; a word holding the observed range changes nothing."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.adc import Adc
from gaitlog.firmware_sim.algorithms import formats as fm
from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.algorithms.state import G1, G2, WORD_OF
from gaitlog.firmware_sim.budget import ram_budget
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.ranges import RangeCollector
from gaitlog.firmware_sim.world.subject import random_subjects
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.protocol.steps import StepConfig, StepFlag

#: Each word token, the shipped format it narrows and its container.
WORDS = {"wcode": fm.centred_q(10), "wacc": fm.ACC_Q, "wgrav": fm.GRAVITY_Q, "wsq": fm.ACC2_Q, "wkern": fm.KERNEL_Q,
         "wfir": fm.FIR_SUM_Q, "wvel": fm.VELOCITY_Q, "wpos": fm.POSITION_Q, "wm2pos": fm.POSITION2_Q,
         "wexc": fm.EXCURSION_Q, "wexcc": fm.EXCURSION2_Q, "wleg": fm.LENGTH_Q, "wtwoleg": fm.TWO_LENGTH_Q,
         "wparg": fm.PENDULUM_ARG_Q, "wpargc": fm.PENDULUM_ARG2_Q, "wstep": fm.STEP_Q, "wk": fm.K_Q, "wkw": fm.K4_Q,
         "wroot": fm.ROOT4_Q, "wcad": fm.M5_Q}


def test_every_word_parses_back_and_none_is_wider_than_its_container() -> None:
    for token, q in WORDS.items():
        assert KernelFormats.parse(f"{token}{q.total_bits}") == KernelFormats()        # the shipped word
        narrow = KernelFormats.parse(f"{token}{q.word_bits - 3}")
        assert narrow.label() == f"{token}{q.word_bits - 3}" and KernelFormats.parse(narrow.label()) == narrow
        with pytest.raises(ValueError, match=rf"2 \.\. {q.word_bits} bits"):
            KernelFormats.parse(f"{token}{q.word_bits + 1}")
    assert KernelFormats.parse("lpint1-wgrav24-acc10").label() == "acc10-lpint1-wgrav24"
    # every format of formats.py has a word that sweeps, as its fraction bits do
    for name in fm.__all__:
        q = getattr(fm, name)
        if hasattr(q, "frac_bits"):
            frac, word = KernelFormats.sweep_fields(q)
            assert frac is not None and (word is not None or q is fm.MANTISSA_Q), name
            assert KernelFormats().of(q) == q, name


def test_a_narrower_word_is_fewer_integer_bits_and_saturates_at_its_range() -> None:
    """``F`` with ``W`` bits: ``(2^(W-1) - 1) / 2^frac`` and ``-2^(W-1) / 2^frac`` (unsigned ``(2^W - 1) / 2^frac``)."""
    k = KernelFormats.parse("wacc12-wstep13-wgrav24")
    assert k.acc_q.max_value == pytest.approx((2 ** 11 - 1) / 2 ** 13) and k.acc_q.min_raw == -(2 ** 11)
    assert k.q("step_frac_bits").max_value == pytest.approx((2 ** 13 - 1) / 2 ** 14)
    assert k.q("gravity_frac_bits").int_bits == fm.GRAVITY_Q.int_bits - 8
    c = k.constants()
    assert (c["W_ACC"], c["W_STEP"], c["W_GRAV"]) == (12, -13, 24)
    assert c["F_ACC"] == fm.F_ACC and c["W_ACC2"] == fm.W_ACC2          # the rest shipped


def test_a_narrower_signed_word_saturates_at_its_twos_complement_limits() -> None:
    """A still logger, nominal calibration: gravity is the calibrated f from the first sample on (the warm-up's
    shift starts at 0), ``±2^29`` raw in Q2.29. In a 30-bit word (Q0.29) +1 g is beyond ``2^29 - 1`` and -1 g is
    the word's minimum, ``-2^29``: z up, every sample's f stored as gravity saturates once, at ``2^29 - 1``, in
    both stages; upside down nothing saturates and gravity is the shipped run's."""
    still = {"up": np.tile([512, 512, 768], (300, 1)), "down": np.tile([512, 512, 256], (300, 1))}
    words = KernelFormats(gravity_word_bits=30)
    assert words.q("gravity_frac_bits").max_raw == 2 ** 29 - 1 and words.q("gravity_frac_bits").min_raw == -2 ** 29
    cfg = dict(sampling_rate_hz=50.0, step_config=StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2))
    for side, z_raw, sat in (("up", 2 ** 29 - 1, 300), ("down", -2 ** 29, 0)):
        narrow, shipped = OnlineStepAlgorithm(**cfg, formats=words), OnlineStepAlgorithm(**cfg)
        narrow.feed(still[side])
        shipped.feed(still[side])
        g = narrow.state_values()
        assert g[G1 + 2] == g[G2 + 2] == z_raw and g[G1] == g[G2 + 1] == 0, side
        assert narrow.saturations == sat and shipped.saturations == 0, side
        assert shipped.state_values()[G2 + 2] == (2 ** 29 if side == "up" else -2 ** 29)
        assert narrow.newest_vertical_acceleration() == shipped.newest_vertical_acceleration() == 0


def test_configuration_words_saturate_the_configured_values_in_the_shipped_kernel() -> None:
    """K = 1.1 in a 15-bit unsigned word of 15 fraction bits (UQ0.15): it saturates at 1 - 2^-15; the foot of
    0.2 m in a 12-bit leg word (UQ-3.15, below 0.125 m) at 4095 lsb."""
    sc = StepConfig(step_format=1, calibrated=True, leg_length_m=0.9, foot_length_m=0.2, k_m1=1.1, k_m2=0.9,
                    k_m4=0.5)
    k = KernelFormats.parse("wk15-wleg12")
    assert k.compiled_shipped and not k.shipped
    alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=sc, formats=k)
    v = alg.config.cfg_v
    assert alg.compiled_by != "variant" and v[kernel.CV_K1] == 2 ** 15 - 1 and v[kernel.CV_K2] == sc.raw["k_m2_q15"]
    assert v[kernel.CV_TWO_LEG] == 2 ** 12 - 1                   # 2 l: the saturated leg's bits, one fraction bit fewer
    assert v[kernel.CV_FOOT] == 2 ** 12 >> 1                     # the saturated foot in UQ2.14, rounded half up
    # the leg stored with 13 fraction bits: 0.9 m = 29491 / 2^15 -> 7373 / 2^13, 2 l = 7373 << 2 in UQ2.14
    coarse = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=sc, formats=KernelFormats.parse("leg13"))
    assert sc.raw["leg_length_q15"] == 29491 and coarse.config.cfg_v[kernel.CV_TWO_LEG] == 7373 << 2


def test_a_narrower_state_word_saves_its_bytes_in_the_ram_budget() -> None:
    """Gravity's six 32-bit words in 24 bits: 6 bytes; in 16 bits: 12; the lowpass's 19 bits (3 bytes) in 16:
    five words, 5 bytes; a word that keeps its bytes saves none."""
    base = ram_budget(50.0).total_bytes
    assert ram_budget(50.0, formats=KernelFormats()).total_bytes == base
    assert base - ram_budget(50.0, formats=KernelFormats.parse("wgrav24")).total_bytes == 6
    assert base - ram_budget(50.0, formats=KernelFormats.parse("wgrav16-lp13")).total_bytes == 12 + 5
    assert ram_budget(50.0, formats=KernelFormats.parse("wacc12-wfir20")).total_bytes == base
    assert set(WORD_OF.values()) <= set(dir(KernelFormats()))


@pytest.fixture(scope="module")
def walk():
    """One simulated walker (varied excursions), its logger's set-up and the shipped fixed-point run."""
    subject = random_subjects(1, seed=0)[0]
    sc = StepConfig(step_format=1, leg_length_m=subject.leg_length_m, foot_length_m=subject.foot_length_m)
    logger = Logger(adc=Adc(), step_config=sc)
    codes = logger.record(Walking(subject=subject, seed=0)).codes
    h = logger.header
    setup = dict(sampling_rate_hz=h.sampling_rate_hz, step_config=h.step_config, calibration=h.calibration,
                 adc_bits=h.adc_bits)
    alg = OnlineStepAlgorithm(**setup)
    return setup, codes, alg.run(codes), alg


def test_words_holding_the_observed_range_change_nothing_and_a_narrower_one_clips_what_ranges_counts(walk) -> None:
    """M1's excursion in the word ``gaitlog ranges`` proposes for it (margin 0): the records are the shipped
    ones. M2's and M3's excursions in one bit fewer than proposed: each stored h beyond ``(2^W - 1) / 2^18`` m is
    that value, the step flagged SATURATED, every other record field as shipped; the kernel counts as many
    saturations as the ranges (counted at that word) report for the row."""
    setup, codes, ref, a_ref = walk
    rc = RangeCollector()
    rc.add(OnlineStepAlgorithm(**setup), codes)
    rows = rc.report(margin_bits=0)
    w1, w2 = rows.row("h (M1)").proposed_bits, rows.row("h (M2), h1 (M3)").proposed_bits - 1
    words = KernelFormats(excursion_word_bits=w1, excursion2_word_bits=w2)
    limit = (1 << w2) - 1
    h = ref.extras[:, 1:3]
    beyond = h > limit
    assert w1 < 16 and w2 < 16 and 0 < beyond.sum() < beyond.size                 # some clipped, not all

    alg = OnlineStepAlgorithm(**setup, formats=words)
    got = alg.run(codes)
    assert alg.compiled_by == "variant"
    for name in ("end", "duration", "toe_off", "heel_strike"):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
    np.testing.assert_array_equal(got.extras[:, 0], ref.extras[:, 0])          # M1's h: its word holds it
    np.testing.assert_array_equal(got.extras[:, 1:3], np.minimum(h, limit))    # M2, M3: clipped at the word
    clipped = beyond.any(axis=1)
    np.testing.assert_array_equal(got.flags, ref.flags | np.where(clipped, int(StepFlag.SATURATED), 0))
    np.testing.assert_array_equal(got.lengths[~clipped], ref.lengths[~clipped])
    np.testing.assert_array_equal(got.lengths[:, [0, 3, 4]], ref.lengths[:, [0, 3, 4]])
    assert a_ref.saturations == 0

    counted = RangeCollector(words)
    counted.add(OnlineStepAlgorithm(**setup), codes)
    report = counted.report(margin_bits=0)
    assert report.row("h (M1)").saturations == 0
    assert report.row("h (M2), h1 (M3)").saturations == alg.saturations == int(beyond.sum())
    assert report.row("h (M2), h1 (M3)").format == str(words.of(fm.EXCURSION2_Q))


def test_fewer_pendulum_argument_bits_cost_what_the_square_roots_floor_says(walk) -> None:
    """``2 l h - h^2`` with 20 fraction bits (M1 and M2/M3, shipped 30 and 32): its square root keeps 10, floored,
    so M1's and M2's lengths ``2 sqrt(2 l h - h^2)`` fall below the exact value of the records' own h by less than
    ``2 x 2^-10`` m (plus the argument's rounding), where the shipped ones are within ``2 x 2^-15`` m; the
    excursions are the shipped ones."""
    setup, codes, ref, _ = walk
    alg = OnlineStepAlgorithm(**setup, formats=KernelFormats.parse("parg20-pargc20"))
    got = alg.run(codes)
    np.testing.assert_array_equal(got.extras, ref.extras)
    two_l = alg.config.cfg_v[kernel.CV_TWO_LEG] / 2 ** fm.F_TWO_LEN
    for col, f_h in ((0, fm.F_EXC), (1, fm.F_EXC2)):
        h = ref.extras[:, col] / 2 ** f_h
        ok = (ref.duration > 0) & (h > 0) & (h < two_l)
        exact = 2 * np.sqrt(two_l * h[ok] - h[ok] ** 2)
        shipped, coarse = (r.lengths[ok, col] / 2 ** fm.F_STEP for r in (ref, got))
        assert np.all(np.abs(shipped - exact) < 2 * 2 ** -15 + 2 ** -14), col
        below = exact - coarse
        assert np.all(below > -2 ** -14) and np.all(below < 2 * 2 ** -10 + 2 ** -14), (col, below.min(), below.max())
        assert below.mean() > 2 ** -11                     # the floor's bias: about half the root's lsb, doubled
