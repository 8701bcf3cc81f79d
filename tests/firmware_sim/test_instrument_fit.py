"""The instrument check: Morris' platform fits the logger, Hall's 10 kHz rate sensors do not (with the reason
and the closest configuration), each limit from its datasheet figure."""

from __future__ import annotations

import pytest

from firmware_sim.instrument_fit import (
    ANALOG_INPUTS,
    InstrumentPlan,
    adc_time_per_channel_s,
    check_fit,
    memory_bytes_per_s,
)


def test_the_limits_from_their_datasheet_figures() -> None:
    # 19.72 µs acquisition + 12 x 32/18.432 MHz conversion + 40 instruction cycles
    assert adc_time_per_channel_s() == pytest.approx(19.72e-6 + 12 * 32 / 18.432e6 + 160 / 18.432e6)
    assert memory_bytes_per_s() == pytest.approx(128 / (131 * 9 / 400e3 + 0.005))


@pytest.mark.parametrize("n", [5, 6])
def test_morris_platform_fits_at_100_hz(n: int) -> None:
    rep = check_fit(InstrumentPlan(tuple(f"acc{i}" for i in range(n)), 100.0))
    assert rep.fits and not rep.reasons
    assert rep.duration_s == pytest.approx(262_144 / (8 * 100))  # 5-6 channels: two 32-bit words a sample


def test_hall_at_10_khz_is_refused_with_reason_and_closest_rate() -> None:
    plan = InstrumentPlan(("Ax", "Ay", "Az", "Bx", "By", "Bz"), 10_000.0)
    rep = check_fit(plan)
    assert not rep.fits
    text = rep.message(plan)
    assert "ADC: 6 conversions" in text and "memory: 8 bytes x 10000 Hz" in text
    assert rep.max_rate_hz == pytest.approx(min(1 / (6 * adc_time_per_channel_s()), memory_bytes_per_s() / 8))
    assert "closest that fits: 6 channels at 2013 Hz" in text
    assert check_fit(InstrumentPlan(plan.channels, 2013.0)).fits
    assert not check_fit(InstrumentPlan(plan.channels, 2014.0)).fits


def test_more_channels_than_inputs() -> None:
    plan = InstrumentPlan(tuple(f"c{i}" for i in range(ANALOG_INPUTS + 1)), 50.0)
    rep = check_fit(plan)
    assert not rep.fits and "8 analog inputs" in rep.message(plan) and "closest that fits: 8 channels" in rep.message(plan)
