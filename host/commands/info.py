"""``gaitlog info``: header and status of a memory image (or dump/capture file) or of a live device, with the
step configuration and counters, and for a file how many step records decode."""

from __future__ import annotations

import argparse

from gaitlog.host.commands._options import BAUD, TIMEOUT_S, add_verbosity_options, verbosity
from gaitlog.host.errors import UsageError

# The decoders and the link load numpy: run imports them, so that `gaitlog --help` stays light
# (tests/host/commands/test_cli_startup.py).

HELP = "show the header and status of a memory image or of a live device (--port)"
#: Shown under "examples:" by ``gaitlog info --help``.
EXAMPLES = (
    "gaitlog info walk.glimg",
    "gaitlog info walk.glimg --json",
    "gaitlog info --port emu://walk.glimg",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("image", nargs="?", metavar="IMAGE",
                        help="memory image (.glimg), raw dump or wire capture")
    parser.add_argument("--port", help="ask a live device instead: serial device, pty path, socket:// or emu://")
    parser.add_argument("--baud", type=BAUD, default=115200, help="baud rate with --port (default 115200)")
    parser.add_argument("--timeout", type=TIMEOUT_S, default=1.0, metavar="S", help="answer timeout with --port")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    if (args.image is None) == (args.port is None):
        raise UsageError("give either IMAGE or --port PORT")
    if args.port:
        from gaitlog.host.link.device_control import device_info

        report = device_info(args.port, baud=args.baud, timeout_s=args.timeout)
    else:
        from gaitlog.host.files.info_report import file_info

        report = file_info(args.image, most=None if verbosity(args) > 0 else 20)
    if args.json:
        print(report.to_json())
    elif verbosity(args) >= 0:
        print(report.format_table())
    return 0
