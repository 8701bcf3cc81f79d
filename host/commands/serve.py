"""``gaitlog serve``: serve a memory image as a live device on a pseudo-terminal or a TCP port."""

from __future__ import annotations

import argparse
import signal
import sys
import time

from gaitlog.host.commands._options import BAUD, TCP_PORT, add_verbosity_options, verbosity

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

HELP = ("serve a memory image as a live logger (its header's step configuration included) on a pty (prints its path) "
        "or a TCP port, until Ctrl-C")
#: Shown under "examples:" by ``gaitlog serve --help``.
EXAMPLES = (
    "gaitlog serve walk.glimg --tcp 5000",
    "gaitlog serve walk.glimg --pty --persist",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("image", metavar="IMAGE", help="memory image (.glimg) the device starts from")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--pty", action="store_true", help="serve on a pseudo-terminal (default)")
    where.add_argument("--tcp", type=TCP_PORT, metavar="PORT", help="serve on 127.0.0.1:PORT (0: any free port)")
    parser.add_argument("--baud", type=BAUD, default=115200, help="baud rate of the device's UART (default 115200)")
    parser.add_argument("--persist", action="store_true",
                        help="save what the link changes (START/STOP logging, ERASE, SET_CALIBRATION, "
                             "SET_STEP_CONFIG) back to IMAGE on exit, as the EEPROM keeps it (default: IMAGE is left "
                             "unchanged)")
    parser.add_argument("--wire-time", action="store_true",
                        help="pace the device's bytes at the baud rate (10 bits per byte, 8N1), as a real line")
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    from gaitlog.firmware_sim.algorithms.online import load_kernels
    from gaitlog.firmware_sim.device import Logger

    logger = Logger.from_image(args.image, image_path=args.image) if args.persist else Logger.from_image(args.image)
    if logger.header.step_config.enabled:
        load_kernels()          # a START over the port must not wait for a compilation
    if args.tcp is not None:
        from gaitlog.firmware_sim.transport import serve_tcp

        server = serve_tcp(logger, port=args.tcp, baud=args.baud, wire_time=args.wire_time)
    else:
        # POSIX only (tty): not imported for --tcp
        from gaitlog.firmware_sim.pty_server import serve_pty

        server = serve_pty(logger, baud=args.baud, wire_time=args.wire_time)
    def _interrupt(signum, frame):  # SIGTERM (and SIGINT even when a shell started us in the background)
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGINT, _interrupt)
    with server:
        # the banner first, the address last: whoever reads the address (a script, a test) and then stops the
        # server with a signal has every line; and a signal at any point from here on is a normal stop
        try:
            if verbosity(args) >= 0:
                print(f"serving {args.image} at {args.baud} baud{' (wire time)' if args.wire_time else ''}; "
                      "Ctrl-C to stop", file=sys.stderr, flush=True)
            if verbosity(args) > 0:
                h = logger.header
                print(f"logger {h.device_id}: {h.n_stored} samples and {h.n_steps_stored} step records stored, "
                      f"{h.sampling_rate_hz:g} Hz, on-line step algorithm {'on' if h.step_config.enabled else 'off'}"
                      + ("; changes are saved to the image on exit" if args.persist else ""), file=sys.stderr,
                      flush=True)
            print(server.url if args.tcp is not None else server.path, flush=True)
            while True:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
    return 0
