"""Options shared by every ``gaitlog`` command (not a command: the underscore keeps it out of ``--help``)."""

from __future__ import annotations

import argparse


def add_verbosity_options(parser: argparse.ArgumentParser) -> None:
    """``-q/--quiet`` and ``-v/--verbose`` (repeatable); read them with :func:`verbosity`."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_const", const=-1, dest="verbosity",
                       help="print only errors (no summary, no progress bar)")
    group.add_argument("-v", "--verbose", action="count", dest="verbosity",
                       help="print more (repeat for more detail)")


def verbosity(args: argparse.Namespace) -> int:
    """-1 with ``-q``, 0 by default, 1 or more with ``-v`` (``-vv`` = 2)."""
    return int(getattr(args, "verbosity", None) or 0)
