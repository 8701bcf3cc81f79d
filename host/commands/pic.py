"""``gaitlog pic verify RECORDING``: run the logger's PIC16 assembly in gpsim on a recording's codes and compare
it with the Python model, stage by stage, byte for byte (:mod:`gaitlog.firmware_sim.pic.gpsim_logger`)."""

from __future__ import annotations

import argparse

from gaitlog.host.commands._options import add_json_option, add_verbosity_options, whole

# The PIC runs load numpy and the decoders: run imports them, so that `gaitlog --help` stays light.

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
    from gaitlog.host.studies.pic_runs import verify_recording

    result = verify_recording(args.recording, limit=args.limit)
    print(result.to_json() if args.json else result.format_table())
    return 0 if result.identical else 1
