"""``gaitlog calibrate``: fit an accelerometer calibration to the static holds of a recording."""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
from pathlib import Path
from typing import Any

HELP = "Fit offsets, scales and axis angles to the static poses of a recording (.npz or CSV) and write JSON."

#: Column triples recognised in a CSV header (case-insensitive), in order of preference, with their unit.
_KNOWN_COLUMNS: tuple[tuple[tuple[str, str, str], str | None], ...] = (
    (("x_counts", "y_counts", "z_counts"), "counts"),
    (("x_g", "y_g", "z_g"), "g"),
    (("acc_x", "acc_y", "acc_z"), None),
    (("ax", "ay", "az"), None),
    (("accx", "accy", "accz"), None),
    (("x", "y", "z"), None),
)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``gaitlog calibrate``."""
    parser.add_argument("input", type=Path, metavar="INPUT",
                        help="decoded recording (.npz from `gaitlog decode`), memory image (.glimg) or CSV of "
                             "3-axis samples")
    parser.add_argument("--out", type=Path, required=True, metavar="CAL.json", help="calibration file to write")
    parser.add_argument("--model", choices=("9-param", "6-param"), default="9-param",
                        help="9-param: offsets, scales and 3 axis angles (default); 6-param: orthogonal axes")
    csv_opts = parser.add_argument_group("CSV input")
    csv_opts.add_argument("--units", choices=("counts", "g", "m/s2"),
                          help="unit of the CSV columns (default: from the column names x_counts / x_g)")
    csv_opts.add_argument("--rate", type=float, metavar="HZ",
                          help="sampling rate in Hz (default: from a time_s column)")
    csv_opts.add_argument("--columns", metavar="X,Y,Z",
                          help="the three columns to use: header names or 0-based indices "
                               "(default: x_counts/x_g/acc_x/ax/x triples, or the only three columns)")
    csv_opts.add_argument("--skip-rows", type=int, default=0, metavar="N",
                          help="lines to skip before the header or the first data line (default 0); a first "
                               "line that is not all numbers is taken as the header")
    csv_opts.add_argument("--zero-counts", type=float, metavar="C",
                          help="nominal 0 g code for rest detection (counts; default: estimated from the holds)")
    csv_opts.add_argument("--counts-per-g", type=float, metavar="K",
                          help="nominal counts per g for rest detection (default: estimated from the holds)")
    det = parser.add_argument_group("rest detection")
    det.add_argument("--hold", type=float, default=3.0, metavar="S", help="minimum hold, seconds (default 3)")
    det.add_argument("--sd-factor", type=float, default=1.3, metavar="F",
                     help="moving-SD threshold as a multiple of the noise floor (default 1.3)")
    det.add_argument("--min-angle", type=float, default=10.0, metavar="DEG",
                     help="holds closer than this to a longer hold are near-duplicates (default 10)")


def _parse_float(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        from host.errors import HostError

        raise HostError(f"{where}: {text!r} is not a number") from None
    return value


def _read_csv(path: Path, args: argparse.Namespace) -> tuple[Any, float, str]:
    """Samples ``(n, 3)`` float, rate in Hz and unit (``counts`` or ``g``) from a CSV file."""
    import numpy as np

    from firmware_sim.world.base import STANDARD_GRAVITY_M_S2
    from host.errors import HostError

    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise HostError(f"{path}: not a CSV text file (byte {err.start} is not UTF-8); give a decoded "
                        "recording (.npz), a memory image (.glimg) or a CSV") from err
    try:
        dialect: Any = csv.Sniffer().sniff(text[:4096], delimiters=",;\t ")
    except csv.Error:
        dialect = csv.excel
    try:
        reader = csv.reader(io.StringIO(text, newline=""), dialect)
        rows = [(i + 1, r) for i, r in enumerate(reader) if i >= args.skip_rows and any(c.strip() for c in r)]
    except csv.Error as err:
        raise HostError(f"{path}: cannot read as CSV ({err})") from err
    if not rows:
        raise HostError(f"{path}: no data lines (after skipping {args.skip_rows})")
    header: list[str] | None = None
    first = rows[0][1]

    def numeric(cell: str) -> bool:
        try:
            float(cell)
            return True
        except ValueError:
            return False

    if not all(numeric(c) for c in first if c.strip()):
        header = [c.strip() for c in first]
        rows = rows[1:]
    if not rows:
        raise HostError(f"{path}: a header but no data lines")
    ncol = len(rows[0][1])
    unit_hint: str | None = None
    if args.columns:
        parts = [p.strip() for p in args.columns.split(",")]
        if len(parts) != 3:
            raise HostError(f"--columns: expected three columns X,Y,Z, got {args.columns!r}")
        cols = []
        for p in parts:
            if p.isdigit():
                cols.append(int(p))
            elif header is not None and p.lower() in [h.lower() for h in header]:
                cols.append([h.lower() for h in header].index(p.lower()))
            else:
                have = f"header columns {header}" if header else "no header line"
                raise HostError(f"{path}: --columns: no column {p!r} ({have})")
        for triple, unit in _KNOWN_COLUMNS:
            if header and tuple(header[c].lower() for c in cols if c < len(header)) == triple:
                unit_hint = unit
    else:
        cols = []
        if header is not None:
            lower = [h.lower() for h in header]
            for triple, unit in _KNOWN_COLUMNS:
                if all(t in lower for t in triple):
                    cols = [lower.index(t) for t in triple]
                    unit_hint = unit
                    break
        if not cols:
            if ncol == 3:
                cols = [0, 1, 2]
            else:
                raise HostError(f"{path}: cannot tell which 3 of the {ncol} columns are x, y, z; "
                                f"give --columns (header: {header})")
    time_col = None
    if header is not None and "time_s" in [h.lower() for h in header]:
        time_col = [h.lower() for h in header].index("time_s")
    data = np.empty((len(rows), 3))
    times = np.empty(len(rows)) if time_col is not None and args.rate is None else None
    for k, (line, row) in enumerate(rows):
        if len(row) <= max(cols):
            raise HostError(f"{path}, line {line}: {len(row)} fields, column {max(cols)} missing")
        for j, c in enumerate(cols):
            cell = row[c].strip()
            name = header[c] if header else f"column {c}"
            if not cell:
                raise HostError(f"{path}, line {line}: {name} is empty (a missing sample); calibrate the .npz "
                                "recording instead, whose gaps are skipped, or remove the line")
            v = _parse_float(cell, f"{path}, line {line}, {name}")
            if not math.isfinite(v):
                raise HostError(f"{path}, line {line}: {name} is {cell!r}, not a finite number")
            data[k, j] = v
        if times is not None:
            times[k] = _parse_float(row[time_col].strip(), f"{path}, line {line}, time_s")  # type: ignore[index]
    unit = args.units or unit_hint
    if unit is None:
        raise HostError(f"{path}: the unit of the columns is not known; give --units counts|g|m/s2")
    rate = args.rate
    if rate is None:
        if times is None or len(times) < 2:
            raise HostError(f"{path}: no time_s column to take the sampling rate from; give --rate HZ")
        dt = float(np.median(np.diff(times)))
        if not dt > 0:
            raise HostError(f"{path}: time_s is not increasing; give --rate HZ")
        rate = 1.0 / dt
    if not (math.isfinite(rate) and rate > 0):
        raise HostError(f"--rate must be a positive number of Hz, got {rate}")
    if unit == "m/s2":
        data = data / STANDARD_GRAVITY_M_S2
        unit = "g"
    return data, rate, unit


def _fmt(v: Any, spec: str = "+10.4f") -> str:
    return " ".join(format(float(x), spec) for x in v)


def run(args: argparse.Namespace) -> int:
    """Detect the static holds, fit the model, print a summary and write the JSON atomically."""
    import numpy as np

    from host.accelerometer.calibration import ANGLE_NAMES, AccCalibrator
    from host.errors import HostError

    path: Path = args.input
    if not path.is_file():
        raise HostError(f"{path}: no such file")
    zero: Any = args.zero_counts
    per_g: Any = args.counts_per_g
    valid_range = None
    with path.open("rb") as fh:
        magic = fh.read(4)
    if magic in (b"PK\x03\x04", b"GLIM"):
        if args.units not in (None, "counts"):
            raise HostError(f"{path}: a decoded recording holds ADC counts; --units {args.units} does not apply")
        if magic == b"GLIM":  # a memory image straight from `gaitlog record` / `gaitlog dump`
            from host.files.decode import decode_file

            rec = decode_file(path)
        else:
            from host.files.recording import Recording

            rec = Recording.load(path)
        acc = rec.codes.astype(np.float64)
        acc[~np.asarray(rec.valid, dtype=bool)] = np.nan
        rate, unit = float(rec.sampling_rate_hz), "counts"
        span = 2 ** int(rec.adc_bits)
        zero = span / 2 if zero is None else zero
        per_g = span / 4 if per_g is None else per_g
        valid_range = (0.0, float(span - 1))
        source = f"{path} ({rec.n_valid} valid samples of {rec.n_samples}, {rate:g} Hz, {rec.adc_bits}-bit)"
    else:
        acc, rate, unit = _read_csv(path, args)
        if unit == "g":
            zero, per_g = 0.0, 1.0
        source = f"{path} ({len(acc)} samples, {rate:g} Hz, {unit})"
    cal_run = AccCalibrator(model=args.model, hold_s=args.hold, sd_factor=args.sd_factor,
                            min_angle_deg=args.min_angle)
    cal_run.calibrate(acc, sampling_rate_hz=rate, input_unit=unit, zero=zero, unit_per_g=per_g,
                      valid_range=valid_range)
    cal = cal_run.calibration_
    det = cal_run.detector_
    out = sys.stdout
    print(f"input: {source}", file=out)
    print(f"static poses: {cal.n_poses} used, {len(det.rejected_)} holds rejected "
          f"(hold >= {args.hold:g} s, noise floor {_fmt(det.noise_floor_, '.3g')} {unit})", file=out)
    chi2 = "n/a" if cal.chi2_per_dof is None else f"{cal.chi2_per_dof:.3g}"
    print(f"model: {cal.model}; |a| - 1 g over the poses: rms {cal.residual_rms_g * 1e3:.3f} mg, "
          f"max {cal.residual_max_g * 1e3:.3f} mg; chi2/dof {chi2}; direction coverage "
          f"{cal.min_direction_sv:.3f} (0.577 ideal)", file=out)
    print(f"offset ({unit}):        {_fmt(cal.offset)}", file=out)
    print(f"scale ({unit} per g):   {_fmt(cal.scale_per_g)}", file=out)
    print("angles (deg):         " + "  ".join(f"{n} {a:+.4f}" for n, a in zip(ANGLE_NAMES, cal.angles_deg,
                                                                                 strict=True)), file=out)
    print(f"calibrated_g = M @ (raw - offset), M (g per {unit}):", file=out)
    for row in cal.matrix:
        print(f"    {_fmt(row, '+.8e')}", file=out)
    print(f"pose  samples          mean ({unit})                       |a|-1 (mg)", file=out)
    for i, (w, r) in enumerate(zip(cal_run.windows_, cal.pose_residuals_g, strict=True)):
        print(f"{i + 1:4d}  {w.start:>7d}-{w.stop:<7d}  {_fmt(w.mean, '+10.4f')}   {r * 1e3:+8.3f}", file=out)
    for w, reason in det.rejected_:
        print(f"rejected samples {w.start}-{w.stop}: {reason}", file=out)
    cal.save(args.out)
    print(f"wrote {args.out}", file=out)
    return 0
