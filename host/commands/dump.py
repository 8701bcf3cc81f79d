"""``gaitlog dump``: dump a logger's memory (samples, then the stored step records) over a serial line to a memory
image plus JSON metadata."""

from __future__ import annotations

import argparse
import io
import signal
import sys
from pathlib import Path

from gaitlog.host.commands._options import (
    BAUD,
    TIMEOUT_S,
    add_force_option,
    add_verbosity_options,
    check_outputs,
    out_path,
    verbosity,
    whole,
)
from gaitlog.host.errors import HostError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib, and of
# the few standard modules that `gaitlog --help` does without (tempfile, dataclasses): it imports every
# command module and must stay light (tests/host/commands/test_cli_startup.py).

HELP = ("dump a logger's memory and step records (port, pty path, socket:// or emu:// URL) to a memory image + "
        "metadata")
#: Shown under "examples:" by ``gaitlog dump --help``.
EXAMPLES = (
    "gaitlog dump --port emu://walk.glimg --out copy.glimg",
    "gaitlog dump --port /dev/ttyUSB0 --out walk.glimg --resume",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", required=True,
                        help="serial device, pty path (from `gaitlog serve --pty`), socket://HOST:PORT or emu://IMAGE")
    parser.add_argument("--out", required=True, metavar="IMAGE", help="memory image to write (.glimg); "
                        "metadata goes to IMAGE.json, the partial state of an interrupted dump to IMAGE.part")
    parser.add_argument("--baud", type=BAUD, default=115200, help="baud rate, 8N1 (default 115200)")
    parser.add_argument("--resume", action="store_true", help="continue an interrupted dump from IMAGE.part")
    parser.add_argument("--retries", type=whole(minimum=0, maximum=1000), default=8,
                        help="passes in a row that bring no new byte before the dump gives up on what is still "
                        "missing (default 8; passes that make progress do not count)")
    parser.add_argument("--timeout", type=TIMEOUT_S, default=1.0, metavar="S",
                        help="answer / inter-byte timeout in seconds (default 1.0); a command is resent until "
                        "it is answered, for at most 30 s")
    parser.add_argument("--capture", metavar="FILE", help="also save every byte received (a wire capture that "
                        "`gaitlog decode` reads)")
    add_force_option(parser)
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    from gaitlog.host.link.memory_dump import metadata_path_for

    out = Path(out_path(args.out, "dump.glimg"))
    emu = args.port[len("emu://"):] if args.port.startswith("emu://") else None
    check_outputs({"--out": out, "--out (.json)": metadata_path_for(out), "--capture": args.capture},
                  {"--port emu:// image": emu}, force=args.force)
    capture = io.BytesIO() if args.capture else None

    def _interrupt(signum, frame):  # SIGTERM, and SIGINT even when a shell started us in the background
        raise KeyboardInterrupt

    previous = {sig: signal.signal(sig, _interrupt) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        return _dump(args, out, capture)
    finally:
        for sig, handler in previous.items():  # run in-process (tests, scripts): leave the caller's handlers
            signal.signal(sig, handler)


def _dump(args: argparse.Namespace, out, capture) -> int:

    from gaitlog.atomic_write import atomic_write_bytes
    from gaitlog.host.link.logger_link import LoggerLink
    from gaitlog.host.link.memory_dump import dump_memory, state_path_for

    with LoggerLink(args.port, baud=args.baud, timeout_s=args.timeout, capture=capture) as link:
        try:
            result = dump_memory(link, out, progress=verbosity(args) >= 0, resume=args.resume, retries=args.retries)
        except HostError as err:
            state = state_path_for(out)
            hint = f"; partial state saved in {state}: run again with --resume" if state.exists() else ""
            raise HostError(f"dump interrupted: {err}{hint}") from err
        except KeyboardInterrupt:
            state = state_path_for(out)
            if state.exists():
                print(f"gaitlog dump: partial state saved in {state}: run again with --resume", file=sys.stderr)
            raise
        finally:
            if capture is not None and capture.tell():
                atomic_write_bytes(args.capture, capture.getvalue())
    meta = result.metadata_
    if verbosity(args) >= 0:
        steps = (f", {meta['n_step_records']} of {meta['n_step_records_stored']} step records"
                 if result.header_.step_capacity else "")
        print(f"{out}: {meta['n_valid']} of {meta['n_samples']} samples{steps}, "
              f"{meta['stored_bytes'] + meta['step_stored_bytes']} bytes in "
              f"{meta['duration_s']:.2f} s ({meta['bytes_received']} bytes received, "
              f"{meta['frames_damaged']} damaged frames, {meta['passes']} pass(es)"
              + (", resumed" if meta["resumed"] else "") + ")")
        print(f"metadata: {result.metadata_path_}")
    if verbosity(args) > 0:
        naks = ", ".join(f"{name} {n}" for name, n in sorted(link.stats.naks.items())) or "none"
        print(f"link: {meta['frames_ok']} frames ok, {meta['data_frames_used']} DATA frames used, "
              f"{meta['reread_pieces']} re-read piece(s), {meta['command_retries']} command retries, "
              f"{link.stats.timeouts} timeout(s), NAKs: {naks}")
    if not result.complete_:
        print(f"gaitlog dump: error: {sum(n for _, n in result.missing_ranges_)} bytes still missing after "
              f"{args.retries} re-read passes ({len(meta['missing_samples'])} sample range(s), "
              f"{len(meta['step_record_losses'])} step-record range(s)); the image marks "
              f"them missing; run again with --resume to retry them", file=sys.stderr)
        return 1
    return 0
