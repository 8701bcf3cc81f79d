"""``gaitlog pic verify RECORDING``: run the logger's PIC16 assembly in gpsim on a recording's codes and compare
it with the Python model, stage by stage, byte for byte (:mod:`gaitlog.firmware_sim.pic.gpsim_logger`)."""

from __future__ import annotations

import argparse

from gaitlog.host.commands._options import add_json_option, add_verbosity_options, whole
from gaitlog.host.errors import HostError

HELP = "run the logger's PIC16 assembly in gpsim on a recording and compare it with the Python model"
#: Shown under "examples:" by ``gaitlog pic --help``.
EXAMPLES = (
    "gaitlog pic verify walk.glimg",
    "gaitlog pic verify walk.glimg --limit 500 --json",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=("verify",),
                        help="verify: the assembly's packed words, steps 1-5 of the algorithm and its foot-flats "
                             "against the model's")
    parser.add_argument("recording", metavar="RECORDING",
                        help="a recording gaitlog decode reads (memory image, raw dump, wire capture)")
    parser.add_argument("--limit", type=whole(minimum=1), metavar="N",
                        help="compare the first N samples only (default: all; gpsim runs a few times real time)")
    add_json_option(parser, "the comparison")
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ, nominal_calibration_q
    from gaitlog.firmware_sim.pic.gpsim_logger import PicError, missing_tools, verify
    from gaitlog.host.files.decode import decode_file

    rec = decode_file(args.recording)
    why = missing_tools()
    if why:
        raise HostError(f"pic verify needs gputils and gpsim: {why}")
    if rec.adc_bits != 10:
        raise HostError(f"{args.recording}: {rec.adc_bits}-bit codes; the PIC16F877's converter has 10 bits")
    keep = np.flatnonzero(rec.valid)
    if keep.size == 0:
        raise HostError(f"{args.recording}: no valid samples to run")
    if args.limit is not None:
        keep = keep[:args.limit]
    cal = rec.header.calibration if rec.header is not None else None
    cal_q = CalibrationQ.from_protocol(cal) if cal is not None else nominal_calibration_q()
    try:
        result = verify(rec.codes[keep], rec.flags[keep], cal_q, sampling_rate_hz=rec.sampling_rate_hz,
                        source=str(args.recording), first_sample_number=int(rec.sample_numbers[keep[0]]))
    except (PicError, ValueError) as err:
        raise HostError(f"{args.recording}: {err}") from err
    print(result.to_json() if args.json else result.format_table())
    return 0 if result.identical else 1
