"""``gaitlog device``: control a live logger: identify it, read its status, start and stop logging, erase its
memory (after confirmation) and set its calibration slot."""

from __future__ import annotations

import argparse
import datetime
import json
import sys
from typing import Any

from gaitlog.host.commands._options import BAUD, TIMEOUT_S, UNIX_TIME_S, add_verbosity_options, verbosity
from gaitlog.host.errors import HostError, UsageError
from gaitlog.protocol.errors import ProtocolError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

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


#: STATUS ``state`` in the user's words.
STATE_WORDS = {0: "idle", 1: "logging", 2: "stopped because the memory is full"}


def run(args: argparse.Namespace) -> int:
    if args.action == "erase" and not args.yes and not sys.stdin.isatty():
        raise UsageError("erase needs a confirmation: run it in a terminal to be asked, or pass --yes")
    slot = _calibration_slot(args) if args.action == "set-calibration" else None
    from gaitlog.host.link.logger_link import LoggerLink

    with LoggerLink(args.port, baud=args.baud, timeout_s=args.timeout) as link:
        info = link.identify()
        if args.action == "identify":
            return _report(args, _identity(info), _identity_lines(args.port, info))
        if args.action == "status":
            return _report(args, _status(link), _status_lines(args.port, info, _status(link)))
        if args.action == "start":
            return _start(args, link, info)
        if args.action == "stop":
            return _stop(args, link, info)
        if args.action == "erase":
            return _erase(args, link, info)
        return _set_calibration(args, link, info, slot)


# ------------------------------------------------------------------------------------------------- reports
def _identity(info: dict[str, int]) -> dict[str, Any]:
    """The IDENTIFY answer in the host's vocabulary (``sampling_rate_hz``, firmware as ``"major.minor"``)."""
    from gaitlog.host.link.logger_link import device_identity

    return device_identity(info)


def _identity_lines(port: str, info: dict[str, int]) -> list[str]:
    ident = _identity(info)
    return [f"logger {ident['device_id']} on {port}",
            f"firmware {ident['firmware_version']}, protocol v{ident['protocol_version']}",
            (f"{ident['adc_bits']}-bit ADC at {ident['sampling_rate_hz']:g} Hz, room for "
             f"{ident['capacity_samples']} samples ({ident['memory_bytes']} bytes)")]


def _status(link) -> dict[str, Any]:
    """STATUS plus what the header says about stored step records and the calibration slot."""
    from gaitlog.protocol.frames import DeviceState

    status = link.status()
    _, header = link.read_header()
    return {"device_id": header.device_id, "state": STATE_WORDS.get(status["state"], str(status["state"])),
            "logging": status["state"] == DeviceState.LOGGING, "overwrite": header.overwrite,
            "samples_written": status["samples_written"], "samples_stored": header.n_stored,
            "capacity_samples": header.capacity_samples, "write_index": status["write_index"],
            "start_time_utc": header.start_time.isoformat() if header.start_time_s else None,
            "step_records_stored": header.n_steps_stored, "step_algorithm_on": bool(header.step_config.enabled),
            "calibration_set": bool(header.calibration.valid)}


def _status_lines(port: str, info: dict[str, int], st: dict[str, Any]) -> list[str]:
    full = 100.0 * st["samples_stored"] / st["capacity_samples"]
    mode = "overwriting the oldest samples when full" if st["overwrite"] else "stopping when full"
    return [f"logger {st['device_id']} on {port}: {st['state']}"
            + (f" ({mode})" if st["logging"] else ""),
            (f"{st['samples_stored']} samples stored of {st['capacity_samples']} ({full:.1f} % full), "
             f"{st['samples_written']} written since the last erase"),
            f"{st['step_records_stored']} step records stored; on-line step algorithm "
            + ("on" if st["step_algorithm_on"] else "off"),
            "calibration slot: " + ("set" if st["calibration_set"] else "empty (the nominal map is used)")]


def _report(args: argparse.Namespace, data: dict[str, Any], lines: list[str]) -> int:
    if args.json:
        print(json.dumps(data, indent=2))
    elif verbosity(args) >= 0:
        print("\n".join(lines))
    return 0


def _say(args: argparse.Namespace, message: str) -> None:
    if verbosity(args) >= 0:
        print(message)


# ------------------------------------------------------------------------------------------------- actions
def _start(args: argparse.Namespace, link, info: dict[str, int]) -> int:
    from gaitlog.protocol.frames import DeviceState

    before = link.status()
    if before["state"] == DeviceState.LOGGING:
        raise HostError(f"logger {info['device_id']} on {args.port} is already logging "
                        f"({before['samples_written']} samples written): nothing changed")
    link.start(args.start_time, overwrite=args.overwrite)
    after = _status(link)
    when = datetime.datetime.fromisoformat(after["start_time_utc"]) if after["start_time_utc"] else None
    mode = "overwrites the oldest samples when full" if args.overwrite else "stops when the memory is full"
    _say(args, f"logger {info['device_id']} is logging since {when.isoformat() if when else '?'} "
               f"({after['samples_stored']} samples already stored; it {mode})")
    return 0


def _stop(args: argparse.Namespace, link, info: dict[str, int]) -> int:
    from gaitlog.protocol.frames import DeviceState

    was = link.status()["state"]
    link.stop()
    st = _status(link)
    if was != DeviceState.LOGGING:
        _say(args, f"logger {info['device_id']} was not logging ({st['state']}); "
                   f"{st['samples_stored']} samples stored")
    else:
        _say(args, f"logger {info['device_id']} stopped logging: {st['samples_stored']} samples and "
                   f"{st['step_records_stored']} step records stored")
    return 0


def _erase(args: argparse.Namespace, link, info: dict[str, int]) -> int:
    st = _status(link)
    if st["logging"]:
        raise HostError(f"logger {info['device_id']} on {args.port} is logging: stop it first "
                        "(`gaitlog device stop`); nothing erased")
    what = (f"{st['samples_stored']} stored samples and {st['step_records_stored']} step records of logger "
            f"{info['device_id']} on {args.port}")
    if not args.yes:
        answer = input(f"Erase {what}? The calibration and step configuration are kept. [y/N] ")
        if answer.strip().lower() not in ("y", "yes"):
            raise HostError("erase not confirmed: nothing erased")
    link.erase()
    _say(args, f"erased {what}")
    return 0


def _calibration_slot(args: argparse.Namespace) -> bytes:
    """The 64-byte slot from ``CAL.json`` (or the empty slot for ``--nominal``), checked before any
    connection is made."""
    from gaitlog.protocol.header import CALIBRATION_SIZE

    if args.nominal:
        return bytes(CALIBRATION_SIZE)
    from gaitlog.host.accelerometer.calibration import AccCalibration

    try:
        cal = AccCalibration.load(args.calibration)
    except OSError as err:
        raise HostError(f"cannot read the calibration file {args.calibration}: {err.strerror or err}") from err
    try:
        return cal.to_header_calibration().to_bytes()
    except (ProtocolError, ValueError) as err:
        raise HostError(f"{args.calibration}: does not fit the logger's calibration slot: {err}") from err


def _set_calibration(args: argparse.Namespace, link, info: dict[str, int], slot: bytes) -> int:
    from gaitlog.protocol.header import CalibrationSlot

    cal = CalibrationSlot.from_bytes(slot, info["adc_bits"])
    link.set_calibration(slot)
    _, header = link.read_header()
    stored = header.calibration
    if stored.valid != cal.valid or (cal.valid and stored.to_bytes() != slot):
        raise HostError(f"logger {info['device_id']} acknowledged the calibration but its header does not hold it")
    if cal.valid:
        offset = ", ".join(f"{v:.3f}" for v in stored.offset_counts)
        _say(args, f"calibration of {args.calibration} stored in logger {info['device_id']}: offset {offset} "
                   "counts (fixed point: offset to 1/65536 count, matrix to 2^-30 g/count)")
    else:
        _say(args, f"calibration slot of logger {info['device_id']} cleared: it uses the nominal map "
                   f"(±2 g over the {info['adc_bits']}-bit ADC span)")
    return 0
