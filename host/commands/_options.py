"""Flags shared by the ``gaitlog`` subcommands: ``-q/--quiet`` and ``-v/--verbose``.

One meaning everywhere: ``-q`` drops the summary lines, warnings and progress (errors are still printed, and
output the user asked for by a flag -- ``--json``, a table on stdout -- is still written); ``-v`` adds detail.
Commands print their summary through :func:`printer` rather than redirecting stdout.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable


def add_verbosity_options(parser: argparse.ArgumentParser) -> None:
    """Add ``-q/--quiet`` and ``-v/--verbose`` (repeatable) to ``parser``; they exclude each other."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true", help="print only errors (no progress, no summary)")
    group.add_argument("-v", "--verbose", action="count", default=0, help="say more (repeat for more detail)")


def verbosity(args: argparse.Namespace) -> int:
    """-1 with ``--quiet``, else the number of ``--verbose`` flags (0 by default)."""
    return -1 if getattr(args, "quiet", False) else int(getattr(args, "verbose", 0) or 0)


def printer(args: argparse.Namespace, level: int = 0) -> Callable[..., None]:
    """``print`` when :func:`verbosity` is at least ``level`` (0: the summary, 1: ``-v`` detail), else a no-op."""
    return print if verbosity(args) >= level else _silent


def _silent(*_args: object, **_kwargs: object) -> None:
    """The :func:`printer` of a suppressed level."""


def add_logger_rate_option(parser: argparse.ArgumentParser, what: str = "") -> None:
    """``--logger-rate HZ``: the emulated logger's sampling rate (not the input's: that is ``--rate``); read it
    with :func:`logger_rate_hz`. ``what`` completes the help (e.g. "for --simulate")."""
    parser.add_argument("--logger-rate", type=float, metavar="HZ",
                        help=f"the emulated logger's sampling rate{' ' + what if what else ''}, Hz "
                             "(default: the logger's, 50 Hz as in Alvarez et al.)")


def logger_rate_hz(args: argparse.Namespace) -> float:
    """``--logger-rate``, else the logger's default (:data:`firmware_sim.adc.DEFAULT_SAMPLING_RATE_HZ`); a
    :class:`~host.errors.HostError` unless positive and finite."""
    import math

    from firmware_sim.adc import DEFAULT_SAMPLING_RATE_HZ
    from host.errors import HostError

    if args.logger_rate is None:
        return DEFAULT_SAMPLING_RATE_HZ
    if not (math.isfinite(args.logger_rate) and args.logger_rate > 0):
        raise HostError(f"--logger-rate must be a positive number of Hz, got {args.logger_rate:g}")
    return float(args.logger_rate)
