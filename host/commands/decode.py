"""``gaitlog decode``: memory image, raw XMODEM dump or wire capture -> samples as CSV and NPZ."""

from __future__ import annotations

import argparse
import importlib.util

HELP = "decode a memory image, raw dump or wire capture to PREFIX.csv and PREFIX.npz (gaps reported)"


def _have_calibration_module() -> bool:
    try:
        return importlib.util.find_spec("host.calibration") is not None
    except ImportError:  # pragma: no cover
        return False


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT", help="memory image (.glimg), raw dump (rx output) or wire capture")
    parser.add_argument("--out", required=True, metavar="PREFIX", help="writes PREFIX.csv and PREFIX.npz")
    if _have_calibration_module():
        parser.add_argument("--calibration", metavar="CAL.json",
                            help="convert counts to g with this calibration (default: the header's "
                                 "calibration slot, else the nominal map)")
    parser.add_argument("--quiet", action="store_true", help="print nothing on success")


def run(args: argparse.Namespace) -> int:
    from host.decode import decode_file, save_outputs

    rec = decode_file(args.input)
    calibration = None
    note = rec.default_calibration()[1]
    if getattr(args, "calibration", None):
        from host.calibration import AccCalibration

        calibration = AccCalibration.load(args.calibration)
        if getattr(calibration, "input_unit", "counts") != "counts":
            from host.errors import HostError

            raise HostError(f"{args.calibration}: this calibration takes {calibration.input_unit}; decoding "
                            "needs a calibration of ADC counts (input_unit 'counts')")
        note = f"g from the calibration {args.calibration}"
    npz, csv = save_outputs(rec, args.out, calibration)
    if not args.quiet:
        print(f"{args.input}: {rec.summary()}")
        print(note)
        print(f"wrote {csv} and {npz}")
    return 0
