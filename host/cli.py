"""The ``gaitlog`` command line.

One module per subcommand lives in ``host/commands/``; each defines

- ``HELP: str`` -- the one-line help shown by ``gaitlog --help``;
- ``configure(parser: argparse.ArgumentParser) -> None`` -- adds its arguments;
- ``run(args: argparse.Namespace) -> int`` -- does the work and returns the exit code;
- ``EXAMPLES: tuple[str, ...]`` -- command lines shown under "examples:" by ``gaitlog COMMAND --help``.

Subcommand modules import only the standard library at module level (heavy libraries, and the standard modules
only a run needs -- tempfile, dataclasses -- are imported inside ``run``) so that ``gaitlog --help`` and
the start-up of every command stay fast: ``gaitlog --help`` loads no numpy and no :mod:`inspect`
(tests/host/commands/test_cli_startup.py). A run registers only its own subcommand (:func:`_named_command`) and
builds only its arguments (:class:`_CommandParser`).

Exit codes: 0 success, 1 data / I/O / protocol / device error (message on stderr, no partial output),
2 usage error (argparse's, or a :class:`~gaitlog.host.errors.UsageError` a command raises: a bad option value
or combination), 130 interrupted, 141 stdout closed by its reader (``| head``). The conventions every command
follows are in ``docs/topics/command-conventions.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import re
import sys
import warnings
from collections.abc import Callable, Iterator, Sequence

import gaitlog.host.commands

#: Order of subcommands in ``gaitlog --help``; modules found but not listed here come after, sorted.
_ORDER = (
    "demo", "record", "serve", "device", "dump", "decode", "info", "calibrate", "estimate", "calibrate_k",
    "evaluate", "compare", "simulate", "sweep", "batch", "plot", "budget", "kinematics",
)


def _command_modules() -> list[str]:
    """The command modules' names, in the order of :data:`_ORDER` (the folder is listed, not searched with
    :mod:`pkgutil`, which loads :mod:`inspect` and with it ast, dis and tokenize: milliseconds of every start)."""
    found = {name.removesuffix(".py") for folder in gaitlog.host.commands.__path__ for name in os.listdir(folder)
             if name.endswith(".py") and not name.startswith("_")}
    return [n for n in _ORDER if n in found] + sorted(found.difference(_ORDER))


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (the problem, the option, where to read more), as
    every other error of ``gaitlog``; exit 2. A mistyped command or action gets the nearest valid one."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {_suggest(message)} (usage: {self.prog} --help)\n")


def _suggest(message: str) -> str:
    """argparse's "invalid choice: 'decod' (choose from 'demo', ...)" as "invalid choice: 'decod' (did you mean
    'decode'?)", through :func:`difflib.get_close_matches`; other messages unchanged."""
    import difflib  # only for a usage error: not loaded by a run

    found = re.search(r"invalid choice: '([^']*)' (\(choose from (.*)\))$", message)
    if not found:
        return message
    choices = re.findall(r"'([^']*)'", found[3])
    close = difflib.get_close_matches(found[1], choices, n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}?" if close else f"choose from {', '.join(choices)}"
    return f"{message[:found.start(2)]}({hint})"


#: The examples of ``gaitlog --help``.
EXAMPLES = (
    "gaitlog demo --out demo-out                     # the whole chain on a simulated walk",
    "gaitlog decode walk.glimg --out walk            # walk.npz, walk.csv (and walk.steps.csv)",
    "gaitlog estimate walk.npz --json                # step lengths and distance, as JSON",
)


def _epilog(examples: Sequence[str]) -> str | None:
    """The "examples:" block under a help text."""
    return "examples:\n" + "\n".join(f"  {line}" for line in examples) if examples else None


def build_parser() -> argparse.ArgumentParser:
    """Return the ``gaitlog`` argument parser with every subcommand registered and configured."""
    return _build(lazy=False)


def _build(*, lazy: bool, only: str | None = None) -> argparse.ArgumentParser:
    """The ``gaitlog`` parser; with ``lazy`` a subcommand's arguments are added only when that subcommand is
    parsed or its help shown (:class:`_CommandParser`), so a run configures one subcommand, not all of them.
    With ``only`` (a command module's name, :func:`_named_command`) the other subcommands are not registered
    at all: their modules are not imported and their parsers not made (argparse looks up its messages'
    translations for every parser it makes)."""
    parser = _Parser(
        prog="gaitlog", epilog=_epilog(EXAMPLES), formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Emulate, dump, decode, calibrate and analyse the PIC16F877 + ADXL202 gait logger.",
    )
    parser.add_argument("--version", action="version", version=f"gaitlog {gaitlog.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=_CommandParser)
    for name in _command_modules() if only is None else [only]:
        module = importlib.import_module(f"gaitlog.host.commands.{name}")
        cmd = sub.add_parser(name.replace("_", "-"), help=module.HELP, description=module.HELP,
                             epilog=_epilog(getattr(module, "EXAMPLES", ())),
                             formatter_class=argparse.RawDescriptionHelpFormatter, configure=module.configure)
        if not lazy:
            cmd.configured()
        cmd.set_defaults(_run=module.run)
    return parser


def _named_command(argv: Sequence[str]) -> str | None:
    """The module of the command ``argv`` starts with, when its first word is exactly a command's name
    (``calibrate-k`` -> ``calibrate_k``); None otherwise (an option first, a mistyped or no command: then every
    subcommand is registered, for ``--help`` and the did-you-mean of a usage error)."""
    if not argv or argv[0].startswith("-"):
        return None
    found = [name for name in _command_modules() if name.replace("_", "-") == argv[0]]
    return found[0] if found else None


class _CommandParser(_Parser):
    """A subcommand's parser: its arguments are added by the command module's ``configure`` on first use
    (parsing its arguments, or formatting its usage or help), or at once by :meth:`configured`. The parsers of
    a subcommand's own actions (``gaitlog device status``) are of this class too, configured by their caller."""

    def __init__(self, *args, configure: Callable[[argparse.ArgumentParser], None] | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._configure: Callable[[argparse.ArgumentParser], None] | None = configure

    def configured(self) -> _CommandParser:
        """This parser with the command's arguments added (once)."""
        if self._configure is not None:
            configure, self._configure = self._configure, None
            configure(self)
        return self

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        return super(_CommandParser, self.configured()).parse_known_args(args, namespace)

    def format_usage(self) -> str:
        return super(_CommandParser, self.configured()).format_usage()

    def format_help(self) -> str:
        return super(_CommandParser, self.configured()).format_help()


#: OpenBLAS's thread count for the commands: one. Their matrix products are small ((n, 3) by (3, 3)), where
#: waking a pool of threads costs more than it saves (tens of ms on a loaded machine), and so does starting the
#: pool when numpy is imported; a value already in the environment is kept.
_BLAS_THREADS_VARIABLE = "OPENBLAS_NUM_THREADS"


def _single_threaded_blas() -> None:
    """Set :data:`_BLAS_THREADS_VARIABLE` to 1 unless it is set, before numpy is imported (after, it would not
    act; a command's worker processes inherit it)."""
    if "numpy" not in sys.modules:
        os.environ.setdefault(_BLAS_THREADS_VARIABLE, "1")


def _known_errors() -> tuple[type[BaseException], ...]:
    from gaitlog.firmware_sim.errors import DeviceError
    from gaitlog.host.errors import HostError
    from gaitlog.protocol.errors import ProtocolError

    return (ProtocolError, DeviceError, HostError, OSError)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``gaitlog`` with ``argv`` (default ``sys.argv[1:]``) and return the exit code."""
    _single_threaded_blas()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = _build(lazy=True, only=_named_command(argv)).parse_args(argv)
    name = " ".join(str(part) for part in (args.command, getattr(args, "action", None)) if part)
    from gaitlog.host.errors import UsageError

    try:
        # a library's warning is one line naming the command, like an error
        with warnings.catch_warnings(), _compile_notice(args):
            warnings.showwarning = lambda message, *_args, **_kw: print(f"gaitlog {name}: warning: {message}",
                                                                          file=sys.stderr)
            if getattr(args, "quiet", False):                     # -q: errors only, and the missing-samples line
                from gaitlog.host.files.losses import MissingSamplesWarning

                warnings.simplefilter("ignore")
                warnings.simplefilter("always", MissingSamplesWarning)
            return int(args._run(args) or 0)
    except KeyboardInterrupt:
        print("gaitlog: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of stdout went away (`gaitlog estimate --json | head`): not an error of ours; silence the
        # interpreter's own flush of the dead pipe at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except UsageError as err:
        print(f"gaitlog {name}: error: {err} (usage: gaitlog {args.command} --help)", file=sys.stderr)
        return 2
    except _known_errors() as err:
        print(f"gaitlog {name}: error: {_error_text(err)}", file=sys.stderr)
        return 1


@contextlib.contextmanager
def _compile_notice(args: argparse.Namespace) -> Iterator[None]:
    """While a command runs, say once on stderr when code is compiled rather than loaded from the cache (the
    first run after an install or an edit waits 20-30 s); not with ``-q``, not from worker processes."""
    from gaitlog.firmware_sim.compiled import compile_listeners

    said, pid = [], os.getpid()

    def notice(what: str) -> None:
        if not said and os.getpid() == pid and not getattr(args, "quiet", False):
            said.append(what)
            print(f"gaitlog: compiling once for this version ({what}); this takes about 30 s", file=sys.stderr,
                  flush=True)

    compile_listeners.append(notice)
    try:
        yield
    finally:
        compile_listeners.remove(notice)


def _error_text(err: BaseException) -> str:
    """The one-line text of a known error; an operating-system error naming its file reads ``FILE: reason``
    (``nothing.glimg: no such file or directory``), not Python's ``[Errno 2] ...``."""
    if isinstance(err, OSError) and err.filename is not None and err.strerror:
        return f"{err.filename}: {err.strerror[0].lower()}{err.strerror[1:]}"
    return str(err)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
