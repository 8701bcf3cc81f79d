"""``gaitlog device``: control a live logger: identify it, read its status, start and stop logging, erase its
memory (after confirmation) and set its calibration slot."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from gaitlog.host.commands._options import BAUD, TIMEOUT_S, UNIX_TIME_S, add_verbosity_options, verbosity
from gaitlog.host.errors import HostError, UsageError

# The link loads numpy and pyserial: run imports it, so that `gaitlog --help` stays light
# (tests/host/commands/test_cli_startup.py).

HELP = "control a live logger (--port): identify, status, start, stop, erase, set-calibration"
#: Shown under "examples:" by ``gaitlog device --help``.
EXAMPLES = (
    "gaitlog device status --port emu://walk.glimg",
    "gaitlog device start --port /dev/ttyUSB0",
)

_PORT_HELP = ("the logger: serial device (/dev/ttyUSB0, COM3), pty path from `gaitlog serve --pty`, "
              "socket://HOST:PORT from `gaitlog serve --tcp`, or emu://IMAGE (the in-process emulator)")


def _link_options(parser: argparse.ArgumentParser) -> None:
    """The connection flags, as ``gaitlog info`` and ``gaitlog dump`` spell them."""
    parser.add_argument("--port", required=True, help=_PORT_HELP)
    parser.add_argument("--baud", type=BAUD, default=115200, help="baud rate, 8N1 (default 115200)")
    parser.add_argument("--timeout", type=TIMEOUT_S, default=1.0, metavar="S",
                        help="answer timeout in seconds (default 1.0); a command is resent until it is answered, "
                        "for at most 30 s")
    add_verbosity_options(parser)


def configure(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    ident = actions.add_parser("identify", help="which logger is on the port: id, firmware, protocol, ADC, "
                               "sampling rate, capacity")
    _link_options(ident)
    ident.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    status = actions.add_parser("status", help="is it logging, how many samples and step records are stored, "
                                "is a calibration set")
    _link_options(status)
    status.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    start = actions.add_parser("start", help="start logging (stops when the memory is full; --overwrite: ring mode)")
    _link_options(start)
    start.add_argument("--overwrite", action="store_true",
                       help="ring mode: overwrite the oldest samples when the memory is full (default: stop)")
    start.add_argument("--start-time", type=UNIX_TIME_S, metavar="UNIX_S",
                       help="Unix time of the first sample (default: now, from this computer's clock)")
    stop = actions.add_parser("stop", help="stop logging")
    _link_options(stop)
    erase = actions.add_parser("erase", help="erase every stored sample and step record (asks first; the "
                               "calibration and step configuration are kept)")
    _link_options(erase)
    erase.add_argument("--yes", action="store_true", help="do not ask (needed when not run in a terminal)")
    cal = actions.add_parser("set-calibration", help="store an accelerometer calibration in the logger's "
                             "calibration slot (from `gaitlog calibrate`), or clear it with --nominal")
    _link_options(cal)
    which = cal.add_mutually_exclusive_group(required=True)
    which.add_argument("calibration", nargs="?", metavar="CAL.json",
                       help="calibration file written by `gaitlog calibrate` (input unit: ADC counts)")
    which.add_argument("--nominal", action="store_true",
                       help="clear the slot: the logger uses the nominal map (±2 g over the ADC span)")


def run(args: argparse.Namespace) -> int:
    if args.action == "erase" and not args.yes and not sys.stdin.isatty():
        raise UsageError("erase needs a confirmation: run it in a terminal to be asked, or pass --yes")
    from gaitlog.host.link.device_control import DeviceControl, LoggerLink, calibration_slot

    slot = calibration_slot(None if args.nominal else args.calibration) if args.action == "set-calibration" else None
    with LoggerLink(args.port, baud=args.baud, timeout_s=args.timeout) as link:
        device = DeviceControl(link, args.port)
        if args.action == "identify":
            return _report(args, device.identity(), device.identity_lines())
        if args.action == "status":
            return _report(args, device.status(), device.status_lines(device.status()))
        if args.action == "start":
            message = device.start(args.start_time, overwrite=args.overwrite)
        elif args.action == "stop":
            message = device.stop()
        elif args.action == "erase":
            what = device.erasable()
            if not args.yes:
                answer = input(f"Erase {what}? The calibration and step configuration are kept. [y/N] ")
                if answer.strip().lower() not in ("y", "yes"):
                    raise HostError("erase not confirmed: nothing erased")
            link.erase()
            message = f"erased {what}"
        else:
            message = device.set_calibration(slot, args.calibration)
    if verbosity(args) >= 0:
        print(message)
    return 0


def _report(args: argparse.Namespace, data: dict[str, Any], lines: list[str]) -> int:
    if args.json:
        print(json.dumps(data, indent=2))
    elif verbosity(args) >= 0:
        print("\n".join(lines))
    return 0
