"""Flags shared by the ``gaitlog`` subcommands: ``-q/--quiet`` and ``-v/--verbose``.

One meaning everywhere: ``-q`` drops the summary lines, warnings and progress (errors are still printed, and
output the user asked for by a flag -- ``--json``, a table on stdout -- is still written); ``-v`` adds detail.
Commands print their summary through :func:`printer` rather than redirecting stdout.
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gaitlog.firmware_sim.sampling import DEFAULT_SAMPLING_RATE_HZ
from gaitlog.host.errors import HostError, UsageError
from gaitlog.host.storage.json_text import json_text
from gaitlog.host.storage.limits import DEFAULT_MAX_MISSING_PERCENT
from gaitlog.protocol.adc_bits import MAX_SIMULATED_ADC_BITS, MAX_STORED_ADC_BITS

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib, and of
# the few standard modules that `gaitlog --help` does without (tempfile, dataclasses): it imports every
# command module and must stay light (tests/host/commands/test_cli_startup.py).


def add_verbosity_options(parser: argparse.ArgumentParser) -> None:
    """Add ``-q/--quiet`` and ``-v/--verbose`` (repeatable) to ``parser``; they exclude each other."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true", help="print only errors (no progress, no summary)")
    group.add_argument("-v", "--verbose", action="count", default=0, help="say more (repeat for more detail)")


def add_max_missing_option(parser: argparse.ArgumentParser) -> None:
    """``--max-missing PCT``: the missing share above which the command exits 1 (outputs still written, marked)."""
    parser.add_argument("--max-missing", type=number(minimum=0, maximum=100, unit="%"),
                        default=DEFAULT_MAX_MISSING_PERCENT, metavar="PCT",
                        help="exit 1 when more than PCT %% of a recording's samples are missing (default "
                             f"{DEFAULT_MAX_MISSING_PERCENT:g}); the outputs are written all the same, and the "
                             "missing samples are marked in them")


def verbosity(args: argparse.Namespace) -> int:
    """-1 with ``--quiet``, else the number of ``--verbose`` flags (0 by default)."""
    return -1 if getattr(args, "quiet", False) else int(getattr(args, "verbose", 0) or 0)


def printer(args: argparse.Namespace, level: int = 0) -> Callable[..., None]:
    """``print`` when :func:`verbosity` is at least ``level`` (0: the summary, 1: ``-v`` detail), else a no-op;
    a no-op too with ``--json`` (standard output holds the JSON document only)."""
    return print if verbosity(args) >= level and not getattr(args, "json", False) else _silent


def add_json_option(parser: argparse.ArgumentParser, what: str = "the tables") -> None:
    """``--json``: print ``what`` as one JSON document on stdout instead of the text (:func:`print_json`)."""
    parser.add_argument("--json", action="store_true", help=f"print {what} as one JSON document instead of text")


def print_json(doc: object) -> None:
    """Print ``doc`` as JSON (:func:`gaitlog.host.storage.json_text.json_text`: numpy values as numbers and lists,
    NaN and infinities as null)."""
    print(json_text(doc))


def _silent(*_args: object, **_kwargs: object) -> None:
    """The :func:`printer` of a suppressed level."""


def add_logger_rate_option(parser: argparse.ArgumentParser, what: str = "", *, maximum_hz: float | None = None,
                           default: str = "the logger's, 50 Hz as in Alvarez et al.") -> None:
    """``--logger-rate HZ``: the emulated logger's sampling rate (not the input's: that is ``--rate``); read it
    with :func:`logger_rate_hz`. ``what`` completes the help (e.g. "for --simulate"); ``maximum_hz`` replaces
    :data:`LOGGER_RATE_HZ`'s 1000 Hz (an instrument's channels, whose budget check gives the reason)."""
    kind = LOGGER_RATE_HZ if maximum_hz is None else number(minimum=1, maximum=maximum_hz, unit="Hz")
    parser.add_argument("--logger-rate", type=kind, metavar="HZ",
                        help=f"the emulated logger's sampling rate{' ' + what if what else ''}, Hz "
                             f"(default: {default})")


def logger_rate_hz(args: argparse.Namespace) -> float:
    """``--logger-rate``, else the logger's default (:data:`gaitlog.firmware_sim.sampling.DEFAULT_SAMPLING_RATE_HZ`);
    a :class:`~gaitlog.host.errors.HostError` unless positive and finite."""
    if args.logger_rate is None:
        return DEFAULT_SAMPLING_RATE_HZ
    if not (math.isfinite(args.logger_rate) and args.logger_rate > 0):
        raise UsageError(f"--logger-rate must be a positive number of Hz, got {args.logger_rate:g}")
    return float(args.logger_rate)


# ------------------------------------------------------------------------------------------ number options
def number(*, minimum: float | None = None, maximum: float | None = None, above: float | None = None,
           unit: str = "") -> Callable[[str], float]:
    """An argparse ``type`` for a finite number in a range: ``minimum <= x <= maximum`` and ``x > above``.

    A bad value is a usage error naming the option (argparse prefixes ``argument --hold:``), e.g.
    ``must be a finite number > 0 s, got 'nan'``.

    >>> number(above=0, unit="s")("1.5")
    1.5
    >>> number(above=0, unit="s")("nan")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: must be a finite number > 0 s, got 'nan'
    """
    bounds = " and ".join(b for b in (
        f">= {minimum:g}" if minimum is not None else "", f"> {above:g}" if above is not None else "",
        f"<= {maximum:g}" if maximum is not None else "") if b)
    wanted = f"a finite number{' ' + bounds if bounds else ''}{' ' + unit if unit else ''}"
    return _argument_type("number", float, wanted, lambda value: (
        math.isfinite(value) and (minimum is None or value >= minimum) and (maximum is None or value <= maximum)
        and (above is None or value > above)))


def whole(*, minimum: int | None = None, maximum: int | None = None, why: str = "") -> Callable[[str], int]:
    """An argparse ``type`` for a whole number in ``minimum..maximum`` (a usage error naming the option;
    ``why`` is appended to the message of a value out of range).

    >>> whole(minimum=1)("0")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: must be a whole number >= 1, got '0'
    """
    bounds = (f"{minimum}..{maximum}" if minimum is not None and maximum is not None else
              f">= {minimum}" if minimum is not None else f"<= {maximum}" if maximum is not None else "")
    wanted = f"a whole number{' ' + bounds if bounds else ''}"
    return _argument_type("whole number", int, wanted, lambda value: (
        (minimum is None or value >= minimum) and (maximum is None or value <= maximum)), why=why)


def _argument_type(name: str, convert: Callable[[str], Any], wanted: str, accept: Callable[[Any], bool], *,
                   why: str = "") -> Callable[[str], Any]:
    """The argparse ``type`` of :func:`number` and :func:`whole`: ``convert(text)``, refused unless ``accept``
    (``must be <wanted>, got '<text>'``, and ``why`` after a value ``accept`` refuses); ``name`` is its
    ``__name__``."""

    def parse(text: str) -> Any:
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {wanted}, got {text!r}") from None
        if not accept(value):
            raise argparse.ArgumentTypeError(f"must be {wanted}, got {text!r}{why}")
        return value

    parse.__name__ = name
    return parse


def add_adc_bits_option(parser: argparse.ArgumentParser, *, stored: bool, what: str = "") -> None:
    """``--adc-bits B`` (default 10), one rule everywhere (:mod:`gaitlog.protocol.adc_bits`): 1 to 10 bits where
    the codes go through the emulated logger, which stores them in 10-bit fields (``stored``), 1 to 12 where
    they are simulated and compared, never stored. A value outside is a usage error (exit 2) that says so."""
    top = MAX_STORED_ADC_BITS if stored else MAX_SIMULATED_ADC_BITS
    why = (f" (the logger stores {MAX_STORED_ADC_BITS}-bit codes; up to {MAX_SIMULATED_ADC_BITS} bits only where codes "
           "are simulated and never stored: compare --simulate, sweep)") if stored else ""
    parser.add_argument("--adc-bits", type=whole(minimum=1, maximum=top, why=why), default=10, metavar="B",
                        help=f"ADC bits{' ' + what if what else ''}, 1-{top} (default 10)")


#: ``--seed``: what numpy's generators take.
SEED = whole(minimum=0, maximum=2**63 - 1)
#: A Unix time the logger's 32-bit header field holds (``--start-time``).
UNIX_TIME_S = whole(minimum=0, maximum=2**32 - 1)
#: A sampling rate of an input or of the emulated logger, Hz.
SAMPLING_RATE_HZ = number(above=0, maximum=100_000, unit="Hz")
#: The emulated logger's sampling rate, Hz (the PIC16F877 budget's range: ``gaitlog budget``).
LOGGER_RATE_HZ = number(minimum=1, maximum=1000, unit="Hz")
#: A serial line's baud rate (``--baud``).
BAUD = whole(minimum=50, maximum=4_000_000)
#: An answer / inter-byte timeout (``--timeout``), s: finite (nan or inf would wait forever) and positive.
TIMEOUT_S = number(above=0, maximum=3600, unit="s")
#: A TCP port to listen on (0: any free port).
TCP_PORT = whole(minimum=0, maximum=65535)
#: A length of a body segment or a walked distance, m.
POSITIVE_M = number(above=0, maximum=100_000, unit="m")


# ------------------------------------------------------------------------------------------ output paths
def add_force_option(parser: argparse.ArgumentParser, what: str = "existing output files") -> None:
    """``--force``: overwrite ``what``; without it an existing output is refused (:func:`check_outputs`,
    :func:`check_output_folder`) before any work."""
    parser.add_argument("--force", action="store_true", help=f"overwrite {what} (refused without --force)")


def out_path(value: str | None, name: str) -> str | None:
    """``--out`` as every command reads it: a file name (for ``decode``, a prefix), or a folder -- a value that
    ends with ``/`` or names an existing folder -- in which the output is called ``name`` (made by the command
    from its input's name: ``decode walk.glimg --out outdir/`` writes ``outdir/walk.npz``). None stays None.

    >>> out_path("results/", "walk.png")
    'results/walk.png'
    >>> out_path("walk_steps.csv", "walk.png")
    'walk_steps.csv'
    """
    if value is None:
        return None
    text = os.fspath(value)
    if text.endswith(("/", os.sep)) or Path(text).is_dir():
        return os.path.join(text, name)
    return value


def input_stem(path: object) -> str:
    """The name an input gives its outputs in a folder: its file name without the suffix (``walk.glimg`` ->
    ``walk``; an IPOL ``1-1_lb.txt`` -> ``1-1_lb``)."""
    return Path(str(path).rstrip("/")).stem


def check_outputs(outputs: dict[str, object], inputs: dict[str, object], *, force: bool | None = None) -> None:
    """Refuse, before any work, outputs that would overwrite an input or that cannot be written.

    ``outputs`` and ``inputs`` map the option (``"--out"``) or the argument's name (``"INPUT"``) to a path (None:
    not given). An output is refused when it is the same file as an input (:func:`os.path.samefile`, or the
    same resolved path: a symlink or another spelling is caught), the same as another output, a folder, or in a
    folder that does not exist; and, with ``force`` False (``--force`` not given), when it exists. ``force``
    None: the command itself continues an existing output (``record --append``, ``dump --resume``). Raises
    :class:`~gaitlog.host.errors.HostError` naming the option and the files.
    """
    def same(a: Path, b: Path) -> bool:
        try:
            if a.exists() and b.exists():
                return os.path.samefile(a, b)
        except OSError:
            pass
        return a.resolve() == b.resolve()

    seen: dict[str, Path] = {}
    for option, value in outputs.items():
        if value is None:
            continue
        out = Path(value)  # type: ignore[arg-type]
        for name, source in inputs.items():
            if source is not None and same(out, Path(source)):  # type: ignore[arg-type]
                raise HostError(f"{option} {out}: is the input {name} {source}: it would be overwritten; choose "
                                "another file")
        for other, path in seen.items():
            if same(out, path):
                raise HostError(f"{option} {out}: is also {other}: choose two different files")
        if out.is_dir():
            raise HostError(f"{option} {out}: is a folder; give a file name")
        folder = out.parent
        if not folder.is_dir():
            what = "is not a folder" if folder.exists() else "does not exist"
            raise HostError(f"{option} {out}: the folder {folder} {what}")
        _check_writable(option, out, folder)
        seen[option] = out
    if force is False:
        for option, out in seen.items():
            if out.exists() or out.is_symlink():
                raise HostError(f"{option} {out}: exists; give --force to overwrite it")


def check_output_folder(option: str, folder: object, *, force: bool | None = None) -> None:
    """Refuse, before any work, an output folder (created when missing) that cannot be made or written: an
    existing file, a path under a file, a place where no file can be created; with ``force`` False
    (``--force`` not given), a folder that is not empty (None: the command resumes into its own folder, or
    decides itself). A :class:`HostError` naming ``option``."""
    path = Path(folder)  # type: ignore[arg-type]
    if path.exists() and not path.is_dir():
        raise HostError(f"{option} {path}: exists and is not a folder")
    existing = path
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise HostError(f"{option} {path}: {existing} is a file, not a folder")
    _check_writable(option, path, existing)
    if force is False and path.is_dir() and any(path.iterdir()):
        raise HostError(f"{option} {path}: exists and is not empty; give --force to write into it")


def _check_writable(option: str, out: object, folder: object) -> None:
    """A :class:`HostError` unless a file can be created in ``folder`` (tried: permissions, read-only or
    pseudo file systems, a full quota)."""
    import tempfile  # not at the top: it loads shutil and random, which `gaitlog --help` does without

    try:
        with tempfile.TemporaryFile(dir=folder):  # type: ignore[call-overload]
            pass
    except OSError as err:
        raise HostError(f"{option} {out}: cannot write in {folder}: {err.strerror or err}") from None
