"""ADC: codes for 0 g and +-1 g, clipping to the code range, bits and reference, timer error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitlog.firmware_sim.adc import Adc
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.sensor import SensorModel


def _expected_code(acc_g: float, *, gain: float = 4.0, bits: int = 10, vlo: float = 0.0, vhi: float = 5.0) -> int:
    v = 2.5 + gain * 0.312 * acc_g
    return min(max(math.floor((v - vlo) / (vhi - vlo) * 2**bits), 0), 2**bits - 1)


def test_codes_for_zero_and_one_g() -> None:
    sensor = SensorModel.ideal(noise_density_g_rthz=0.0)
    adc = Adc()
    v = sensor.static_v(np.array([[0.0, 1.0, -1.0]]))
    codes = adc.convert(v)[0].tolist()
    assert codes == [512, _expected_code(1.0), _expected_code(-1.0)] == [512, 767, 256]


def test_clipping_to_the_code_range_and_configurable_bits() -> None:
    direct = Adc(gain=1.0)  # converter input = sensor voltage
    assert direct.convert(np.array([-1.0, 0.0, 4.99, 5.0, 7.0])).tolist() == [0, 0, 1021, 1023, 1023]
    adc = Adc()  # gain 4 around 2.5 V: +-0.625 V of sensor output spans the converter
    assert adc.convert(np.array([2.5 - 0.7, 2.5 - 0.625, 2.5 + 0.6249, 2.5 + 0.7])).tolist() == [0, 0, 1023, 1023]
    adc8 = Adc(adc_bits=8)
    assert adc8.convert(np.array([2.5, 5.0])).tolist() == [128, 255]
    narrow = Adc(gain=1.0, vref_low_v=2.5 - 0.624, vref_high_v=2.5 + 0.624)  # VREF+- around the 0 g level
    assert narrow.convert(np.array([2.5, 2.5 + 0.3125])).tolist() == [512, 768]
    with pytest.raises(DeviceError):
        Adc(adc_bits=12)
    with pytest.raises(DeviceError):
        Adc(vref_low_v=3.0, vref_high_v=1.0)


def test_timer_instants_and_ppm_error() -> None:
    t = Adc(sampling_rate_hz=50.0).sample_times_s(0.0, 10.0)
    assert t.size == 501 and t[1] == pytest.approx(0.02)
    fast = Adc(sampling_rate_hz=50.0, timer_error_ppm=100.0)
    tf = fast.sample_times_s(0.0, 1000.0)
    assert tf[-1] == pytest.approx((tf.size - 1) / (50.0 * 1.0001))
    assert tf.size == 50006  # 100 ppm fast: 5 extra samples in 1000 s


def test_sample_and_hold_interpolates_the_fine_grid() -> None:
    rate = 500.0
    ramp = np.linspace(2.0, 3.0, 1001)  # 2 s ramp, volts
    v = np.c_[ramp, ramp, ramp]
    adc = Adc(gain=1.0)
    times = np.array([0.0, 0.5, 1.001, 2.0])
    codes = adc.sample(v, rate, 0.0, times)[:, 0]
    expected = [math.floor((2.0 + 0.5 * t) / 5.0 * 1024) for t in times]
    assert codes.tolist() == expected
