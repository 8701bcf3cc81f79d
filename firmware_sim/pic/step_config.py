"""The step record's configuration bytes, as ``step_record.asm`` reads them from the PIC's data EEPROM.

The ``CFG_*`` offsets of ``step_record_ram.inc``, filled from the kernel's configuration arrays
(:class:`~gaitlog.firmware_sim.algorithms.online.OnlineConfig`'s ``cfg_i`` and ``cfg_v``); the logger's harness
(:mod:`~gaitlog.firmware_sim.pic.gpsim_logger`) and the step bench (:mod:`~gaitlog.firmware_sim.pic.gpsim_steps`)
both write them.
"""

from __future__ import annotations

import numpy as np

from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.formats import F_EXC, F_EXC2, F_POS, F_POS2
from gaitlog.protocol.steps import StepFlag

__all__ = ["MAX_R3", "MAX_R_EVENTS", "CFG_W3", "config_bytes", "s32_le_bytes"]

#: Radii the RAM map holds (step_record_ram.inc): the 3 Hz window, the heel strike's and toe-off's.
MAX_R3, MAX_R_EVENTS = 9, 5
#: Offset of the 3 Hz weights in the configuration (step_record_ram.inc CFG_W3).
CFG_W3 = 36


def _u16(v: int, what: str) -> list[int]:
    v = int(v)
    if not 0 <= v <= 0xFFFF:
        raise ValueError(f"{what} = {v} does not fit the configuration's 16-bit word")
    return [v & 0xFF, v >> 8]


def s32_le_bytes(v: int) -> list[int]:
    """``v`` as four little-endian bytes (two's complement)."""
    v = int(v) & 0xFFFFFFFF
    return [(v >> (8 * i)) & 0xFF for i in range(4)]


def config_bytes(cfg_i: np.ndarray, cfg_v: np.ndarray, *, calibrated: bool = True,
                 m4_eighths: int | None = None) -> list[int]:
    """The step configuration as ``step_record.asm`` reads it from the data EEPROM (``CFG_*`` offsets of
    ``step_record_ram.inc``), from the kernel's configuration arrays (``OnlineConfig.cfg_i``, ``cfg_v``).

    Raises ValueError where the assembly's RAM or word widths do not hold the configuration.
    """
    ci = {k: int(cfg_i[v]) for k, v in kernel.CI.items()}
    if ci["R3"] > MAX_R3 or max(ci["R10"], ci["R5"]) > MAX_R_EVENTS:
        raise ValueError(f"FIR radii r3 = {ci['R3']}, r10 = {ci['R10']}, r5 = {ci['R5']}: the RAM map holds "
                         f"r3 <= {MAX_R3} and r10, r5 <= {MAX_R_EVENTS} (50 Hz)")
    if ci["MAX_STEP"] > 255 or ci["HS_BEFORE"] + ci["HS_AFTER"] + 1 > 255 or ci["TO_SPAN"] > 255 \
            or ci["HS_BEFORE"] + ci["HS_DELAY"] > 128:
        raise ValueError("the step's sample counts must fit the record's bytes")
    exc1_mul = F_POS - ci["EXC_SHIFT1"] + ci["UNIT_FRAC"] - F_EXC
    exc2_mul = F_POS2 - ci["EXC_SHIFT2"] + ci["UNIT_FRAC"] - F_EXC2
    if not (0 <= exc1_mul <= 31 and 0 <= exc2_mul <= 31):
        raise ValueError(f"the excursions' product shifts {exc1_mul}, {exc2_mul} are outside 0 .. 31")
    if m4_eighths is None:                      # the configuration's own (online.py: the step configuration's p)
        m4_eighths = ci["M4_EIGHTHS"]
    w10_at = CFG_W3 + 2 * (ci["R3"] + 1)
    w5_at = w10_at + 2 * (ci["R10"] + 1)
    head = [ci["R3"], ci["R10"], ci["R5"], ci["MAX_STEP"], ci["HS_BEFORE"], ci["HS_AFTER"], ci["HS_DELAY"],
            ci["TO_SPAN"], ci["EXC_SHIFT1"], exc1_mul, ci["EXC_SHIFT2"], exc2_mul,
            int(m4_eighths),
            0 if calibrated else int(StepFlag.UNCALIBRATED), w10_at, w5_at]
    v = {k: int(cfg_v[i]) for k, i in kernel.CV.items() if i < len(cfg_v)}
    words = []
    for name in ("TWO_LEG", "FOOT", "K1", "K2", "K4", "UNIT"):
        words += _u16(v[name], name)
    words += s32_le_bytes(v["K1FS"]) + s32_le_bytes(v["K2M5"])
    out = head + words
    assert len(out) == CFG_W3
    for w0, r in ((kernel.CV_W3, ci["R3"]), (ci["W10"], ci["R10"]), (ci["W5"], ci["R5"])):
        for t in range(r + 1):
            out += _u16(cfg_v[w0 + t], "a FIR weight")
    return out
