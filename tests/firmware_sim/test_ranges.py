"""Range collection (firmware_sim/ranges.py): ranges known analytically, a saturating input, the
proposals, and that observing does not change the records."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.formats import ACC_Q, GRAVITY_Q
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.ranges import TRACKED, RangeCollector, smallest_format
from gaitlog.protocol.header import CalibrationSlot
from gaitlog.protocol.steps import StepConfig
from gaitlog.units import STANDARD_GRAVITY_M_S2

RATE_HZ = 50.0
CFG = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)


def _algorithm(**kw) -> OnlineStepAlgorithm:
    return OnlineStepAlgorithm(sampling_rate_hz=RATE_HZ, step_config=CFG, **kw)


def _report(codes: np.ndarray, *, margin_bits: int = 1, **kw):
    c = RangeCollector()
    c.add(_algorithm(**kw), codes, name="test")
    return c.report(margin_bits=margin_bits)


def _sinusoid_codes(seconds: float = 30.0) -> np.ndarray:
    """The centre of mass of online.py's example: z = -2 cm cos(4 pi t) (h = 4 cm, 2 steps/s), on z."""
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    acc = np.zeros((t.size, 3))
    acc[:, 2] = 1 - 0.02 * (4 * np.pi) ** 2 * np.cos(4 * np.pi * t) / STANDARD_GRAVITY_M_S2
    return np.clip(np.floor(acc * 256 + 512), 0, 1023).astype(np.int64)


def test_still_tilted_logger_has_the_ranges_gravity_gives():
    # 45 degrees between x and z: 181 counts of 256 on each (0.70703 g), nominal calibration
    r = _report(np.tile([512 + 181, 512, 512 + 181], (300, 1)), margin_bits=0)
    f, g2, av = r.row("f (x, y, z)"), r.row("G2 (x, y, z)"), r.row("a_v")
    assert (f.min_raw, f.max_raw) == (0, 181 * 32)                     # Q2.13: 181/256 g
    assert (r.row("G1 (x, y, z)").min_raw, r.row("G1 (x, y, z)").max_raw) == (0, 181 * 32 << 16)
    assert (g2.min_raw, g2.max_raw) == (0, 181 * 32 << 16)             # gravity = f from the first sample
    assert r.row("g rounded (x, y, z)").max_raw == 181 * 32
    assert r.row("|g|^2").min_raw == r.row("|g|^2").max_raw == 2 * (181 * 32) ** 2
    assert abs(av.min_raw) <= 1 and abs(av.max_raw) <= 1                 # a_v = |g| - |g| (one lsb of rounding)
    assert g2.headroom_bits == round(math.log2(GRAVITY_Q.max_raw / (181 * 32 << 16)), 2)
    assert f.proposed == "Q0.13" and f.proposed_bits == 14                # 0.707 g needs no integer bit
    assert r.kernel_saturations == 0 and not r.saturated() and r.n_steps == 0


def test_gravity_proposal_follows_the_margin():
    codes = np.tile([512, 512, 768], (100, 1))                          # 1 g on z
    assert _report(codes, margin_bits=0).row("G2 (x, y, z)").proposed == "Q1.29"
    assert _report(codes, margin_bits=1).row("G2 (x, y, z)").proposed == "Q2.29"
    assert _report(codes, margin_bits=3).row("G2 (x, y, z)").proposed_bits == 34


def test_walking_sinusoid_gives_the_analytic_velocity_position_and_excursion():
    r = _report(_sinusoid_codes())
    assert r.n_steps > 40
    a_peak_g = 0.02 * (4 * np.pi) ** 2 / STANDARD_GRAVITY_M_S2              # 0.322 g
    # the trough is exact; the top is higher while the gravity estimate warms up (a running mean from sample 0)
    assert r.row("a_v").min_real == pytest.approx(-a_peak_g, rel=0.02)
    assert a_peak_g <= r.row("a_v").max_real <= a_peak_g * 1.5
    ts = 1 / RATE_HZ
    v_peak_units = 0.02 * 4 * np.pi / (STANDARD_GRAVITY_M_S2 * ts / 2)  # V counts 2 g Ts
    v = r.row("V (M1 pass)")
    assert v.max_real - v.min_real == pytest.approx(2 * v_peak_units, rel=0.1)
    # P (4 g Ts^2), derived from a_v and the windows, gives the kernel's own largest h of M1 (from 0 here)
    p_max_m = r.row("P (M1 pass)").max_real * STANDARD_GRAVITY_M_S2 * ts * ts / 4
    assert r.row("P (M1 pass)").min_raw >= 0
    assert p_max_m == pytest.approx(r.row("h (M1)").max_real, rel=0.002)
    assert r.row("h (M2), h1 (M3)").max_real == pytest.approx(0.04, rel=0.02)   # drift-corrected: h = 4 cm
    # M2's p2, derived with c1 and c2 from the kernel's own first pass, gives the kernel's largest h of M2
    p2_max_m = r.row("p2 (M2 pass)").max_real * STANDARD_GRAVITY_M_S2 * ts * ts / 4
    assert p2_max_m == pytest.approx(r.row("h (M2), h1 (M3)").max_real, rel=0.002)
    assert r.row("FIR accumulator").min_raw is None and r.row("FIR accumulator").how == "none"


def test_a_saturating_input_is_reported_at_its_limit():
    # a calibration four times the nominal gain: full-scale codes are 8 g, beyond Q2.13's 4 g
    cal = CalibrationSlot(offset_counts=np.full(3, 512.0), matrix_g_per_count=np.eye(3) / 64.0, valid=True)
    codes = np.tile([512, 512, 576], (200, 1))
    codes[100:110, 0] = 1023
    r = _report(codes, calibration=cal)
    f = r.row("f (x, y, z)")
    assert f.max_raw == ACC_Q.max_raw and f.saturations == 10 and f.headroom_bits == 0.0
    assert r.kernel_saturations >= 10
    assert f in r.saturated() and "f (x, y, z) (ACC_Q) 10x" in r.headline()
    assert "f (x, y, z)" in r.format_table().split("\n")[-3]


def test_observing_does_not_change_the_records():
    codes = _sinusoid_codes(12.0)
    plain = _algorithm().run(codes).to_records(0)
    seen = _algorithm()
    steps = []
    feed, flush = seen.feed, seen.flush
    seen.feed = lambda block, **kw: steps.append(feed(block, **kw)) or steps[-1]
    seen.flush = lambda **kw: steps.append(flush(**kw)) or steps[-1]
    c = RangeCollector()
    c.add(seen, codes)
    assert c.report().n_steps == plain.size > 10
    got = np.concatenate([s.to_records(0) for s in steps])
    assert got.tobytes() == plain.tobytes()


def test_every_format_has_a_row():
    from gaitlog.firmware_sim.algorithms import formats

    named = {n for n in formats.__all__ if n.endswith("_Q")} | {"CENTRED_Q"}
    assert named == {t.format_name for t in TRACKED}


def test_smallest_format_edges():
    assert smallest_format(-32768, 32767, ACC_Q, 0) == (2, 16)
    assert smallest_format(-32769, 0, ACC_Q, 0) == (3, 17)
    assert smallest_format(0, 0, ACC_Q, 0) == (-13, 1)


def _slow_walk_codes(seconds: float = 40.0, step_hz: float = 1.0) -> np.ndarray:
    """A centre of mass z = -3 cm cos(2 pi f t) on z: one step per 1 / f s (50 samples at 1 Hz)."""
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    acc = np.zeros((t.size, 3))
    acc[:, 2] = 1 - 0.03 * (2 * np.pi * step_hz) ** 2 * np.cos(2 * np.pi * step_hz * t) / STANDARD_GRAVITY_M_S2
    return np.clip(np.floor(acc * 256 + 512), 0, 1023).astype(np.int64)


@pytest.mark.parametrize("k2_m5_m, saturates", [(-1.0, True), (-0.8, False)])
def test_m5_below_zero_is_reported_where_k1_fs_over_n_plus_k2_is_negative(k2_m5_m, saturates):
    # M5 = K1/T + K2 with K1 = 0.9 m s: negative for T > 0.9 / -K2, i.e. for the 1 s steps when K2 = -1 m
    # (0.9 - 1 = -0.1 m, stored as 0 in the unsigned UQ2.14 and counted by the kernel), +0.1 m when K2 = -0.8
    cfg = StepConfig(step_format=1, calibrated=True, leg_length_m=0.9, foot_length_m=0.2, k_m1=1.0, k_m2=1.0,
                     k_m4=1.0, k1_m5_m_s=0.9, k2_m5_m=k2_m5_m)
    c = RangeCollector()
    c.add(OnlineStepAlgorithm(sampling_rate_hz=RATE_HZ, step_config=cfg), _slow_walk_codes(), name="1 s steps")
    r = c.report()
    row = r.row("K1 fs / N + K2 (M5)")
    windowed = r.n_steps - 1                                   # the first record has no window
    assert windowed > 30
    assert row.how == "derived" and row.n_values == windowed
    assert row.max_real == pytest.approx(0.9 + k2_m5_m, abs=0.01)        # the 50-sample steps
    assert row.saturations == (windowed if saturates else 0) == r.kernel_saturations == r.saturated_records
    assert r.row("length M5").saturations == 0                # the record reads 0: only the derived row sees it
    if saturates:
        assert row.min_real < 0 and row.proposed.startswith("Q") and "K1 fs / N + K2 (M5)" in r.headline()
    else:
        assert row.min_real > 0 and row.proposed.startswith("UQ")
