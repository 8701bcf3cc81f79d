"""The sweep's simulated subject S05 (8 subjects, seed 0, the paper's protocol): its multi-speed K has a
negative M5 intercept, and one step of its slow excursion's turn is detected 54 samples long, beyond
M5's zero crossing ``K1 fs / -K2``; ``ranges`` reports that one saturation on M5's derived row (it is the
kernel's only one)."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm, OnlineSteps
from gaitlog.firmware_sim.ranges import RangeCollector
from gaitlog.host.files.replay import step_config_for
from gaitlog.host.studies.compare import compare_walk
from gaitlog.host.studies.sweep_grid import analog_walk

RATE_HZ, ADC_BITS = 50.0, 12


@pytest.mark.slow
def test_s05_m5_goes_negative_once_on_a_long_detected_step():
    subject, walk = analog_walk(0, 5, 8, "paper")                 # the sweep's task seed 0, subject index 5
    assert subject.subject_id == "S05"
    sw = walk.sample(RATE_HZ)
    result = compare_walk(sw, subject, adc_bits=ADC_BITS)
    k = result.runs["online-fixed"].calibrations["multi-speed"]
    assert result.runs["online-fixed"].saturated == 1             # what the sweep reported for this task
    assert k.k2_m5_m < 0
    zero_crossing = k.k1_m5_m_s * RATE_HZ / -k.k2_m5_m            # samples: M5 < 0 for longer steps
    alg = OnlineStepAlgorithm(sampling_rate_hz=RATE_HZ, adc_bits=ADC_BITS, calibration=sw.calibration(ADC_BITS),
                              step_config=step_config_for(leg_length_m=subject.leg_length_m,
                                                          foot_length_m=subject.foot_length_m, k_fit=k))
    c = RangeCollector()
    c.add(alg, sw.codes(ADC_BITS), name="S05")
    r = c.report()
    row = r.row("K1 fs / N + K2 (M5)")
    assert row.saturations == 1 == r.kernel_saturations == r.saturated_records
    assert [x.variable for x in r.saturated()] == ["K1 fs / N + K2 (M5)"]
    # independently: the records' windows (the algorithm fed in blocks) longer than the zero crossing
    fresh = OnlineStepAlgorithm(sampling_rate_hz=RATE_HZ, adc_bits=ADC_BITS, calibration=sw.calibration(ADC_BITS),
                                step_config=alg.config.step_config)
    steps = OnlineSteps.concatenate([fresh.feed(sw.codes(ADC_BITS).astype(np.int64)), fresh.flush()])
    long_steps = np.flatnonzero(steps.duration > zero_crossing)
    assert 47 < zero_crossing < 48 and long_steps.size == 1
    n = int(steps.duration[long_steps[0]])
    # M5 of that step, K1 fs / N + K2 in float, within the kernel's rounding: about -0.13 m
    assert row.min_real == pytest.approx(k.k1_m5_m_s * RATE_HZ / n + k.k2_m5_m, abs=2e-4)
    assert row.min_real < -0.1
    # where: the slow excursion's turn (the walk's truth), whose steps last at most 0.72 s, not N / fs
    t_end_s = sw.times_s[int(steps.end[long_steps[0]])]
    ex = walk.truth_["excursions"]
    slow = [i for i, label in enumerate(ex["speed_label"]) if str(label) == "slow"]
    assert len(slow) == 1 and ex["turn_start_s"][slow[0]] <= t_end_s <= ex["turn_end_s"][slow[0]]
    truth = walk.truth_["steps"]
    assert np.max(np.asarray(truth["next_foot_flat_s"]) - np.asarray(truth["foot_flat_s"])) < 0.75 < n / RATE_HZ
