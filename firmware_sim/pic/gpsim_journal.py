"""Header version 3's page-commit journal entry in PIC16 assembly (``journal.asm``), run in gpsim.

:func:`run_journal_entry` assembles ``journal_bench.asm`` with one entry's inputs (the commit ``m``, the run's step
records, its ``recording_number`` and ``recording_nonce``), runs it in gpsim with an I2C EEPROM (gpsim's
``e24xx256``, answering the step EEPROM's block-0 control byte 0xA0) on the MSSP, and returns what went over the
bus, the 16 bytes read back from the EEPROM afterwards and ``journal_write``'s cycles (from the call to its return:
the page write and the acknowledge polling of its write cycle). The Python model's entry is
:func:`gaitlog.protocol.journal_ring.entry_bytes` at :func:`~gaitlog.protocol.journal_ring.ring_address`: the
tests compare the two. The routine is not yet called from ``logger.asm``'s sample path.
"""

from __future__ import annotations

import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.firmware_sim.pic.gpsim_bench import PIC_DIR, copy_sources
from gaitlog.protocol.journal_ring import ENTRY_BYTES_V3, entry_bytes, ring_address

__all__ = ["JOURNAL_BENCH_ASM", "JournalEntryRun", "run_journal_entry", "JOURNAL_BUS", "PROBE_ENTRIES",
           "journal_entry_cycles"]

JOURNAL_BENCH_ASM = PIC_DIR / "journal_bench.asm"
#: gpsim's I2C bus for the bench: the 24xx256 with its address pins low, so that it answers 0xA0 (the 24LC1025's
#: block 0, where the journal ring is); the logger's runs pull A2 high for the scratch ring's block 1 (0xA8).
JOURNAL_BUS = tuple(c for c in gl.I2C_SETUP if "a2" not in c.lower())
_MARK, _BACK = 0x20, 0x31                      # journal_bench.asm MARK, BACK
_SSPBUF = 0x13
_MARK_CYCLES = 2                               # MOVLW, MOVWF of a mark


@dataclass(frozen=True)
class JournalEntryRun:
    """One entry written by ``journal_write`` in gpsim.

    ``sent``: the bytes the MSSP sent between the call and the return, in order (the page write's control byte,
    address and 16 data bytes, then each acknowledge poll's control byte); ``read_back``: the 16 bytes read from
    the EEPROM at the model's address afterwards; ``cycles``: the instruction cycles of ``journal_write``, its
    ``CALL`` and ``RETURN`` included."""

    sent: bytes
    read_back: bytes
    cycles: int

    @property
    def address(self) -> int:
        """The byte address of the page write (its two address bytes)."""
        return (self.sent[1] << 8) | self.sent[2]

    @property
    def data(self) -> bytes:
        """The page write's data bytes as sent."""
        return self.sent[3:3 + ENTRY_BYTES_V3]

    @property
    def polls(self) -> int:
        """Control bytes sent after the data: the acknowledge polls (the last one acknowledged)."""
        return len(self.sent) - 3 - ENTRY_BYTES_V3


def run_journal_entry(m: int, *, steps: int, recording_number: int, recording_nonce: int,
                      timeout_s: float = 60.0) -> JournalEntryRun:
    """``journal_write`` on one entry in gpsim. Raises :class:`~.gpsim_logger.PicError` without gputils/gpsim or
    when gpasm or gpsim fails."""
    why = gl.missing_tools()
    if why:
        raise gl.PicError(why)
    values = {"E_M": m, "E_S": steps, "E_R": recording_number, "E_N": recording_nonce,
              "E_ADDR": ring_address(m, recording_number=recording_number)}
    with tempfile.TemporaryDirectory(prefix="gpsim-journal-") as tmp:
        copy_sources(Path(tmp), JOURNAL_BENCH_ASM)
        defines = [f"-D{k}=0x{int(v) & 0xFFFFFFFF:X}" for k, v in values.items()]
        proc = subprocess.run(["gpasm", "-q", "-p", "p16f877", *defines, JOURNAL_BENCH_ASM.name], capture_output=True,
                              text=True, timeout=60, cwd=tmp)
        cod = Path(tmp) / JOURNAL_BENCH_ASM.with_suffix(".cod").name
        if proc.returncode != 0 or not cod.exists():
            raise gl.PicError(f"gpasm failed on {JOURNAL_BENCH_ASM.name}: {(proc.stdout + proc.stderr).strip()[-300:]}")
        logged = [_MARK, _SSPBUF, *range(_BACK, _BACK + ENTRY_BYTES_V3)]
        log = gl._gpsim(gl._Build(cod, {}), logged, "e done", timeout_s, bus=JOURNAL_BUS)
    cyc, addr, val = gl._writes(log, set(logged))
    marks = cyc[addr == _MARK]
    if marks.size != 3:
        raise gl.PicError(f"the journal bench logged {marks.size} marks, not 3")
    inside = (cyc > marks[0]) & (cyc < marks[1]) & (addr == _SSPBUF)
    back = {int(a): int(v) for a, v in zip(addr, val) if _BACK <= a < _BACK + ENTRY_BYTES_V3}
    return JournalEntryRun(bytes(val[inside].astype(np.uint8).tolist()),
                           bytes(back.get(_BACK + i, 0) for i in range(ENTRY_BYTES_V3)),
                           int(marks[1] - marks[0] - _MARK_CYCLES))


#: The entries :func:`journal_entry_cycles` times: a run's first four (commits 2-8, a few records) of a logger's
#: 1,234th recording, and one late in a long run (the step count saturated).
PROBE_ENTRIES = ((2, 0, 1234, 0x5EED0001), (4, 1, 1234, 0x5EED0001), (6, 3, 1234, 0x5EED0001),
                 (8, 4, 1234, 0x5EED0001), (250_000, 70_000, 1234, 0x5EED0001))


def journal_entry_cycles() -> float:
    """``journal_write``'s mean cycles over :data:`PROBE_ENTRIES` in gpsim (each entry checked against the model's
    bytes). Raises :class:`~.gpsim_logger.PicError` without gputils/gpsim, when gpsim fails or when an entry
    differs from the model's."""
    cycles = []
    for m, steps, number, nonce in PROBE_ENTRIES:
        run = run_journal_entry(m, steps=steps, recording_number=number, recording_nonce=nonce)
        want = entry_bytes(m, steps=steps, recording_number=number, recording_nonce=nonce)
        if run.data != want or run.read_back != want or run.address != ring_address(m, recording_number=number):
            raise gl.PicError(f"journal.asm's entry of commit {m} is not the model's: {run.data.hex()} at "
                              f"0x{run.address:04X}")
        cycles.append(run.cycles)
    return float(np.mean(cycles))
