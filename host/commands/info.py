"""``gaitlog info``: header and status of a memory image (or dump/capture file) or of a live device, with the
step configuration and counters, and for a file how many step records decode."""

from __future__ import annotations

import argparse

HELP = "show the header and status of a memory image or of a live device (--port)"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("image", nargs="?", metavar="IMAGE",
                        help="memory image (.glimg), raw dump or wire capture")
    parser.add_argument("--port", help="ask a live device instead: serial device, pty path, socket:// or emu://")
    parser.add_argument("--baud", type=int, default=115200, help="baud rate with --port (default 115200)")
    parser.add_argument("--timeout", type=float, default=1.0, metavar="S", help="answer timeout with --port")


def header_lines(header) -> list[str]:
    """Readable lines describing a ``protocol.header.DeviceHeader``."""
    fw = int(header.firmware_version)
    flags = [name for name, on in (("OVERWRITE", header.overwrite), ("WRAPPED", header.wrapped),
                                   ("LOGGING", header.logging), ("CAL_VALID", header.calibration.valid),
                                   ("FULL_STOPPED", bool(header.flags & 0x10))) if on]
    cal = header.calibration
    return [
        f"device id        {header.device_id}",
        f"firmware         {fw >> 8}.{fw & 0xFF}   protocol v{header.protocol_version}   header v{header.header_version}",
        f"sample rate      {header.sampling_rate_hz:g} Hz, {header.adc_bits}-bit ADC, {header.axes} axes, packing P32",
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
        algorithm += (f"calibrated: K M1 {q.k_m1:.4f}, M2 {q.k_m2:.4f}, M4 {q.k_m4:.4f} m/(m/s^2)^0.25, "
                      f"M5 S = {q.k1_m5_m_s:.4f}/T {q.k2_m5_m:+.4f} m" if cfg.calibrated else
                      "raw (no K: M1, M2, M4 with K = 1, M5 the cadence in Hz)")
    return [f"step memory      {memory}", f"step algorithm   {algorithm}"]


def run(args: argparse.Namespace) -> int:
    from host.errors import HostError

    if (args.image is None) == (args.port is None):
        raise HostError("give either IMAGE or --port PORT")
    if args.port:
        from host.link.logger_link import LoggerLink

        with LoggerLink(args.port, baud=args.baud, timeout_s=args.timeout) as link:
            info = link.identify()
            status = link.status()
            _, header = link.read_header()
        states = {0: "idle", 1: "logging", 2: "full-stopped"}
        print(f"port             {args.port} at {args.baud} baud")
        print(f"state            {states.get(status['state'], status['state'])}, "
              f"{status['samples_written']} samples written, write index {status['write_index']}")
        print(f"memory           {info['memory_bytes']} bytes")
        print("\n".join(header_lines(header)))
        return 0
    from host.files.decode import decode_file

    rec = decode_file(args.image)
    print(f"file             {args.image}")
    print("\n".join(header_lines(rec.header)))
    print(f"decoded          {rec.n_valid} of {rec.n_samples} stored samples valid, {len(rec.gaps)} gap(s), "
          f"{rec.duration_s:.2f} s")
    _print_listed([f"gap: samples {g.first_sample_number}..{g.last_sample_number}: {g.reason}" for g in rec.gaps],
                  "gap(s)")
    if rec.header.step_capacity or rec.n_step_records:
        print(f"step records     {rec.n_step_records} of {rec.header.n_steps_stored} stored records decode "
              f"({rec.n_steps_dropped} dropped)")
        _print_listed([f"dropped: records {loss.first_record_number}..{loss.last_record_number}: {loss.reason}"
                       for loss in rec.step_losses], "run(s) of dropped records")
    for note in rec.notes:
        print(f"note: {note}")
    return 0


def _print_listed(lines: list[str], what: str, most: int = 20) -> None:
    """The first ``most`` lines, indented, then how many more ``what`` there are."""
    for line in lines[:most]:
        print(f"  {line}")
    if len(lines) > most:
        print(f"  ... {len(lines) - most} more {what}")
