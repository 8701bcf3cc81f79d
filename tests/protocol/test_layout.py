"""gaitlog.protocol.layout.CompiledOnReuse: construct's interpreter and its compiled code give the same values,
bytes and errors for the protocol's blocks, and the switch happens after COMPILE_AFTER_USES calls."""

from __future__ import annotations

import construct as cs
import numpy as np
import pytest

from gaitlog.protocol import header, layout, steps
from gaitlog.protocol.header import CALIBRATION_STRUCT, HEADER_STRUCT, CalibrationSlot, DeviceHeader
from gaitlog.protocol.steps import STEP_CONFIG_STRUCT, StepConfig


def _plain(value):
    """A parsed construct value as plain Python (containers without their ``_``-prefixed context keys)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items() if not k.startswith("_")}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _outcome(fn):
    try:
        return "ok", _plain(fn())
    except cs.ConstructError as err:
        return "error", type(err)


def _blocks() -> list[tuple[cs.Construct, bytes]]:
    cfg = StepConfig(step_format=4, calibrated=True, leg_length_m=0.9, foot_length_m=0.2, k_m1=1.1, k_m2=1.0,
                     k_m4=0.5, k1_m5_m_s=0.3, k2_m5_m=0.2, m4_exponent=0.25)
    cal = CalibrationSlot(np.array([510.0, 512.5, -3.25]), np.eye(3) / 256.0, valid=True)
    good = DeviceHeader(capacity_samples=1024, samples_written=1500, write_index=476, flags=0x02,
                        calibration=cal, step_config=cfg, step_capacity=3276).to_bytes()
    bad_crc = good[:-1] + bytes([good[-1] ^ 0xFF])
    bad_magic = b"GLOX" + good[4:]
    rng = np.random.default_rng(7)
    return ([(HEADER_STRUCT, b) for b in (good, bad_crc, bad_magic)]
            + [(CALIBRATION_STRUCT, cal.to_bytes()), (CALIBRATION_STRUCT, rng.bytes(64))]
            + [(STEP_CONFIG_STRUCT, cfg.to_bytes())] + [(STEP_CONFIG_STRUCT, rng.bytes(32)) for _ in range(5)])


@pytest.mark.parametrize("k", range(11))
def test_interpreted_and_compiled_parse_and_build_alike(k: int) -> None:
    struct, data = _blocks()[k]
    compiled = struct.compile()
    parsed = _outcome(lambda: struct.parse(data))
    assert parsed == _outcome(lambda: compiled.parse(data))
    if parsed[0] == "ok":
        value = struct.parse(data)
        assert struct.build(value) == compiled.build(value)


def test_the_protocol_blocks_compile_only_when_reused() -> None:
    for block in (header._HEADER_FAST, header._CALIBRATION_FAST, steps._STEP_CONFIG_FAST):
        assert isinstance(block, layout.CompiledOnReuse)
    block = layout.CompiledOnReuse(STEP_CONFIG_STRUCT)
    raw = StepConfig(step_format=4, leg_length_m=0.9, foot_length_m=0.2).to_bytes()
    values = []
    for _ in range(layout.COMPILE_AFTER_USES):
        values.append(_plain(block.parse(raw)))
        assert not block.compiled
    values.append(_plain(block.parse(raw)))
    assert block.compiled and all(v == values[0] for v in values)
    assert block.build(block.parse(raw)) == raw
