"""The ``gaitlog`` command line.

One module per subcommand lives in ``host/commands/``; each defines

- ``HELP: str`` -- the one-line help shown by ``gaitlog --help``;
- ``configure(parser: argparse.ArgumentParser) -> None`` -- adds its arguments;
- ``run(args: argparse.Namespace) -> int`` -- does the work and returns the exit code.

Subcommand modules import only the standard library at module level (heavy libraries are imported inside
``run``) so that ``gaitlog --help`` and the start-up of every command stay fast.

Exit codes: 0 success, 1 data / I/O / protocol / device error (message on stderr, no partial output),
2 usage error (argparse), 130 interrupted, 141 stdout closed by its reader (``| head``).
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
import warnings
from collections.abc import Sequence

import gaitlog.host.commands

#: Order of subcommands in ``gaitlog --help``; modules found but not listed here come after, sorted.
_ORDER = (
    "demo", "record", "serve", "device", "dump", "decode", "info", "calibrate", "estimate", "calibrate_k",
    "evaluate", "compare", "simulate", "sweep", "batch", "plot", "budget", "kinematics",
)


def _command_modules() -> list[str]:
    found = {m.name for m in pkgutil.iter_modules(gaitlog.host.commands.__path__) if not m.name.startswith("_")}
    return [n for n in _ORDER if n in found] + sorted(found.difference(_ORDER))


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (the problem, the option, where to read more), as
    every other error of ``gaitlog``; exit 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (usage: {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """Return the ``gaitlog`` argument parser with every subcommand registered."""
    parser = _Parser(
        prog="gaitlog",
        description="Emulate, dump, decode, calibrate and analyse the PIC16F877 + ADXL202 gait logger.",
    )
    parser.add_argument("--version", action="version", version=f"gaitlog {gaitlog.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in _command_modules():
        module = importlib.import_module(f"gaitlog.host.commands.{name}")
        cmd = sub.add_parser(name.replace("_", "-"), help=module.HELP, description=module.HELP)
        module.configure(cmd)
        cmd.set_defaults(_run=module.run)
    return parser


def _known_errors() -> tuple[type[BaseException], ...]:
    from gaitlog.firmware_sim.errors import DeviceError
    from gaitlog.host.errors import HostError
    from gaitlog.protocol.errors import ProtocolError

    return (ProtocolError, DeviceError, HostError, OSError)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``gaitlog`` with ``argv`` (default ``sys.argv[1:]``) and return the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    name = " ".join(str(part) for part in (args.command, getattr(args, "action", None)) if part)
    try:
        with warnings.catch_warnings():   # a library's warning is one line naming the command, like an error
            warnings.showwarning = lambda message, *_args, **_kw: print(f"gaitlog {name}: warning: {message}",
                                                                          file=sys.stderr)
            return int(args._run(args) or 0)
    except KeyboardInterrupt:
        print("gaitlog: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of stdout went away (`gaitlog estimate --json | head`): not an error of ours; silence the
        # interpreter's own flush of the dead pipe at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except _known_errors() as err:
        print(f"gaitlog {name}: error: {_error_text(err)}", file=sys.stderr)
        return 1


def _error_text(err: BaseException) -> str:
    """The one-line text of a known error; an operating-system error naming its file reads ``FILE: reason``
    (``nothing.glimg: no such file or directory``), not Python's ``[Errno 2] ...``."""
    if isinstance(err, OSError) and err.filename is not None and err.strerror:
        return f"{err.filename}: {err.strerror[0].lower()}{err.strerror[1:]}"
    return str(err)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
