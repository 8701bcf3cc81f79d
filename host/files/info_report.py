"""What ``gaitlog info`` says of a memory image, raw dump or wire capture (:func:`file_info`) and the words it
describes a device header in (:func:`header_lines`, :func:`header_dict`; a live device's report,
:func:`gaitlog.host.link.device_control.device_info`, uses them too)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gaitlog.firmware_sim.algorithms.parameters import M4_EXPONENT
from gaitlog.host.files.decode import decode_file
from gaitlog.protocol.header import firmware_version_text
from gaitlog.protocol.steps import ONLINE_ALGORITHM_VERSION

__all__ = ["InfoReport", "file_info", "header_dict", "header_lines", "step_lines"]


@dataclass(frozen=True)
class InfoReport:
    """``data``: the JSON-ready document; ``lines``: the text."""

    data: dict[str, Any]
    lines: list[str]

    def to_json(self) -> str:
        return json.dumps(self.data, indent=2)

    def format_table(self) -> str:
        return "\n".join(self.lines)


def header_lines(header) -> list[str]:
    """Readable lines describing a ``gaitlog.protocol.header.DeviceHeader``."""
    flags = [name for name, on in (("OVERWRITE", header.overwrite), ("WRAPPED", header.wrapped),
                                   ("LOGGING", header.logging), ("CAL_VALID", header.calibration.valid),
                                   ("FULL_STOPPED", header.full_stopped)) if on]
    cal = header.calibration
    return [
        f"device id        {header.device_id}",
        f"firmware         {firmware_version_text(header.firmware_version)}   protocol v{header.protocol_version}   header v{header.header_version}",
        f"sampling rate    {header.sampling_rate_hz:g} Hz, {header.adc_bits}-bit ADC, {header.axes} axes, packing P32",
        f"start time       {header.start_time.isoformat()} ({header.start_time_s})",
        f"capacity         {header.capacity_samples} samples",
        f"samples written  {header.samples_written} (stored {header.n_stored}, oldest is sample "
        f"{header.first_sample_number} in slot {header.first_slot})",
        f"write index      {header.write_index}",
        f"flags            {' '.join(flags) or '-'}",
        "calibration      " + ("affine: offset " + ", ".join(f"{v:.3f}" for v in cal.offset_counts) + " counts"
                               if cal.valid else "none (nominal map: ±2 g over the ADC span)"),
        *step_lines(header),
    ]


def step_lines(header) -> list[str]:
    """Readable lines describing the step memory counters and the step configuration (PROTOCOL.md 2.2, 2.3)."""
    cfg = header.step_config
    if not header.step_capacity:
        memory = "none (a device without step memory)"
    else:
        memory = (f"{header.step_capacity} records; {header.steps_written} written (stored {header.n_steps_stored}, "
                  f"oldest is record {header.first_step_number} in slot {header.first_step_slot}), write index "
                  f"{header.step_write_index}")
    if not cfg.enabled:
        algorithm = "off (plain logging)"
    else:
        q = cfg.quantised()
        algorithm = (f"on-line version {int(cfg.step_format)}, leg {q.leg_length_m:.4f} m, "
                     f"foot {q.foot_length_m:.4f} m, ")
        if cfg.older_algorithm:                                 # an older firmware's records
            algorithm += (f"records by {cfg.older_algorithm} (this host replays version "
                          f"{int(ONLINE_ALGORITHM_VERSION)}), ")
        p4 = q.m4_exponent if q.m4_exponent > 0 else (M4_EXPONENT if int(cfg.step_format) >= 4 else 0.5)
        algorithm += (f"calibrated: K M1 {q.k_m1:.4f}, M2 {q.k_m2:.4f}, M4 {q.k_m4:.4f} m/(m/s^2)^{p4:g}, "
                      f"M5 S = {q.k1_m5_m_s:.4f}/T {q.k2_m5_m:+.4f} m" if cfg.calibrated else
                      "raw (no K: M1, M2, M4 with K = 1, M5 the cadence in Hz)")
    return [f"step memory      {memory}", f"step algorithm   {algorithm}"]


def header_dict(header) -> dict[str, Any]:
    """A ``gaitlog.protocol.header.DeviceHeader`` as JSON-ready values in the host's words (units in the keys)."""
    cfg = header.step_config
    return {
        "device_id": header.device_id, "firmware_version": firmware_version_text(header.firmware_version),
        "protocol_version": header.protocol_version, "header_version": header.header_version,
        "sampling_rate_hz": header.sampling_rate_hz, "adc_bits": header.adc_bits, "axes": header.axes,
        "start_time_utc": header.start_time.isoformat(), "start_time_s": header.start_time_s,
        "capacity_samples": header.capacity_samples, "samples_written": header.samples_written,
        "samples_stored": header.n_stored, "first_sample_number": header.first_sample_number,
        "first_slot": header.first_slot, "write_index": header.write_index,
        "overwrite": header.overwrite, "wrapped": header.wrapped, "logging": header.logging,
        "full_stopped": header.full_stopped, "calibration_set": bool(header.calibration.valid),
        "calibration_offset_counts": header.calibration.offset_counts.tolist() if header.calibration.valid else None,
        "step_capacity": header.step_capacity, "steps_written": header.steps_written,
        "step_records_stored": header.n_steps_stored, "step_write_index": header.step_write_index,
        "step_algorithm_on": bool(cfg.enabled), "step_algorithm_calibrated": bool(cfg.enabled and cfg.calibrated),
    }


def file_info(path: str | Path, *, most: int | None = 20) -> InfoReport:
    """``gaitlog info IMAGE``: the header of the memory image, raw dump or wire capture at ``path`` and what
    decodes of it (its gaps and dropped step records: the first ``most``, all with None)."""
    rec = decode_file(path)
    gaps = [{"first_sample_number": g.first_sample_number, "last_sample_number": g.last_sample_number,
             "reason": g.reason} for g in rec.gaps]
    losses = [{"first_record_number": g.first_record_number, "last_record_number": g.last_record_number,
               "reason": g.reason} for g in rec.step_losses]
    data = {"file": str(path), "header": header_dict(rec.header),
            "samples": {"n_stored": rec.n_samples, "n_valid": rec.n_valid, "duration_s": rec.duration_s,
                        "gaps": gaps},
            "step_records": {"n_stored": rec.header.n_steps_stored, "n_decoded": rec.n_step_records,
                             "n_dropped": rec.n_steps_dropped, "dropped": losses},
            "notes": list(rec.notes)}
    lines = [f"file             {path}", *header_lines(rec.header),
             (f"decoded          {rec.n_valid} of {rec.n_samples} stored samples valid, {len(rec.gaps)} gap(s), "
              f"{rec.duration_s:.2f} s")]
    lines += _listed([f"gap: samples {g['first_sample_number']}..{g['last_sample_number']}: {g['reason']}"
                      for g in gaps], "gap(s)", most)
    if rec.header.step_capacity or rec.n_step_records:
        lines.append(f"step records     {rec.n_step_records} of {rec.header.n_steps_stored} stored records decode "
                     f"({rec.n_steps_dropped} dropped)")
        lines += _listed([f"dropped: records {g['first_record_number']}..{g['last_record_number']}: {g['reason']}"
                          for g in losses], "run(s) of dropped records", most)
    lines += [f"note: {note}" for note in rec.notes]
    return InfoReport(data, lines)


def _listed(lines: list[str], what: str, most: int | None) -> list[str]:
    """The first ``most`` lines (all with None), indented, then how many more ``what`` there are."""
    shown = lines if most is None else lines[:most]
    more = [f"  ... {len(lines) - len(shown)} more {what} (-v lists them all)"] if len(lines) > len(shown) else []
    return [f"  {line}" for line in shown] + more
