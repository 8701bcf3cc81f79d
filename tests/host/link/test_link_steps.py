"""gaitlog.host.link.logger_link's step commands over the in-process emu:// device: SET_STEP_CONFIG and READ of the step memory.

Truth is the emulated device's own state (its header and step EEPROM), never the host's output.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.host.errors import HostError
from gaitlog.host.link.logger_link import LoggerLink
from gaitlog.protocol.steps import STEP_ADDRESS_BASE, StepConfig
from gaitlog.units import STANDARD_GRAVITY_M_S2

CONFIG = StepConfig(step_format=4, leg_length_m=0.9, foot_length_m=0.2, m4_exponent=0.25)


@pytest.fixture()
def image(tmp_path):
    """A device whose step memory holds some records (a 2 Hz bounce, tilted: the algorithm finds steps)."""
    t = np.arange(3000) / 50.0
    a_v = 0.02 * (2 * np.pi * 2.0) ** 2 * np.cos(2 * np.pi * 2.0 * t) / STANDARD_GRAVITY_M_S2
    acc = (1.0 + a_v)[:, None] * np.array([0.3, -0.2, 0.93])[None, :]
    logger = Logger(step_config=CONFIG)
    logger.record(Motion(acc_g=acc, sampling_rate_hz=50.0), start_time_s=1_700_000_000)
    assert logger.header.steps_written > 20
    path = tmp_path / "s.glimg"
    logger.save_image(path)
    return path, logger


def test_set_step_config_is_stored_in_the_header(image):
    path, _ = image
    calibrated = StepConfig(step_format=4, calibrated=True, leg_length_m=0.95, foot_length_m=0.21, k_m1=1.1,
                            k_m2=1.05, k_m4=0.5, k1_m5_m_s=0.3, k2_m5_m=0.25, m4_exponent=0.5)
    with LoggerLink(f"emu://{path}", timeout_s=0.5) as link:
        link.set_step_config(calibrated)
        assert link.read_header()[1].step_config == calibrated.quantised()
        # a host that knows an older version: the device stores the version it runs (PROTOCOL.md 2.2)
        # (byte 20 is reserved in a version-1 block: M4's exponent is then the firmware's default, 1/4)
        link.set_step_config(dataclasses.replace(calibrated, step_format=1))
        assert link.read_header()[1].step_config == dataclasses.replace(calibrated, m4_exponent=0.25).quantised()
        # M4's exponent not given (0): the device stores its default, Weinberg's 1/4
        link.set_step_config(dataclasses.replace(calibrated, m4_exponent=0.0))
        assert link.read_header()[1].step_config == dataclasses.replace(calibrated, m4_exponent=0.25).quantised()
        link.set_step_config(StepConfig.off().to_bytes())
        assert not link.read_header()[1].step_config.enabled
        # refused on the host, the field named, nothing sent
        with pytest.raises(HostError, match="leg_length_q15"):
            link.set_step_config(StepConfig(step_format=1))
        # refused by the device: a block section 2.2 refuses (step_format 5)
        with pytest.raises(HostError, match="SET_STEP_CONFIG: NAK BAD_ARGUMENT"):
            link.set_step_config(bytes([5]) + bytes(31))
        link.start(1_700_000_100)
        with pytest.raises(HostError, match="SET_STEP_CONFIG: NAK BUSY"):
            link.set_step_config(CONFIG)
        link.stop()


def test_read_step_memory_gives_the_device_bytes(image):
    path, logger = image
    truth = bytes(logger.step_memory)
    n = logger.header.step_used_bytes
    with LoggerLink(f"emu://{path}", timeout_s=0.5) as link:
        assert link.read_step_memory(0, n) == truth[:n]
        assert link.read_step_memory(20 * 7 + 3, 50) == truth[143:193]
        assert link.read(STEP_ADDRESS_BASE + 20, 20) == truth[20:40]
        last = 20 * logger.header.step_capacity
        assert link.read_step_memory(last - 4, 4) == truth[last - 4: last]
        with pytest.raises(HostError, match="READ: NAK BAD_ADDRESS"):
            link.read_step_memory(last - 4, 8)       # past the end of the step ring
        with pytest.raises(HostError, match="BAD_ADDRESS"):
            link.read(4 * 65536 - 4, 8)              # across the end of the sample memory
        with pytest.raises(HostError, match="offset must be >= 0"):
            link.read_step_memory(-1, 4)
        got = {}
        assert link.dump_stream(STEP_ADDRESS_BASE, n, 100, lambda a, d: got.update({a: d}))
        assert b"".join(got[a] for a in sorted(got)) == truth[:n]
