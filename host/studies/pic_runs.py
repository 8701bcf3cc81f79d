"""A recording's ADC codes run through the logger's assembly in gpsim: ``gaitlog pic verify``
(:func:`verify_recording`, every stage against the golden model) and ``gaitlog budget --measure``
(:mod:`gaitlog.host.studies.logger_budget`, cycles per sample) read the recording the same way
(:func:`assembly_input`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ, nominal_calibration_q
from gaitlog.firmware_sim.pic import gpsim_logger
from gaitlog.firmware_sim.pic.gpsim_logger import PicError
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_file
from gaitlog.host.files.recording import Recording

__all__ = ["AssemblyInput", "assembly_input", "verify_recording"]


@dataclass(frozen=True)
class AssemblyInput:
    """What the assembly runs: the first valid samples' codes and flags, the header's calibration in the PIC's
    fixed point (the nominal map without one), the rate and the first sample's number."""

    codes: np.ndarray
    flags: np.ndarray
    calibration_q: CalibrationQ
    sampling_rate_hz: float
    first_sample_number: int
    source: str


def assembly_input(rec: Recording, path: str | Path, limit: int | None) -> AssemblyInput:
    """The first ``limit`` (all with None) valid samples of ``rec`` (read from ``path``), for the assembly; the
    caller checks that they are 10-bit codes and that there are some."""
    keep = np.flatnonzero(rec.valid)[:limit]
    cal = rec.header.calibration if rec.header is not None else None
    return AssemblyInput(codes=rec.codes[keep], flags=rec.flags[keep],
                         calibration_q=CalibrationQ.from_protocol(cal) if cal is not None else nominal_calibration_q(),
                         sampling_rate_hz=rec.sampling_rate_hz,
                         first_sample_number=int(rec.sample_numbers[keep[0]]) if keep.size else 0, source=str(path))


def verify_recording(path: str | Path, *, limit: int | None = None):
    """``gaitlog pic verify``: the first ``limit`` valid samples of the recording at ``path`` (anything ``gaitlog
    decode`` reads) through the assembly in gpsim and the golden model
    (:func:`gaitlog.firmware_sim.pic.gpsim_logger.verify`); its result.

    Raises
    ------
    HostError
        gputils or gpsim is missing, the codes are not 10-bit, no sample is valid, or gpsim fails.
    """
    rec = decode_file(path)
    why = gpsim_logger.missing_tools()  # looked up when called (tests replace it)
    if why:
        raise HostError(f"pic verify needs gputils and gpsim: {why}")
    if rec.adc_bits != 10:
        raise HostError(f"{path}: {rec.adc_bits}-bit codes; the PIC16F877's converter has 10 bits")
    if not np.any(rec.valid):
        raise HostError(f"{path}: no valid samples to run")
    run = assembly_input(rec, path, limit)
    try:
        return gpsim_logger.verify(run.codes, run.flags, run.calibration_q, sampling_rate_hz=run.sampling_rate_hz,
                      source=run.source, first_sample_number=run.first_sample_number)
    except (PicError, ValueError) as err:
        raise HostError(f"{path}: {err}") from err
