"""Flags shared by the ``gaitlog`` subcommands: ``-q/--quiet`` and ``-v/--verbose``."""

from __future__ import annotations

import argparse


def add_verbosity_options(parser: argparse.ArgumentParser) -> None:
    """Add ``-q/--quiet`` and ``-v/--verbose`` (repeatable) to ``parser``; they exclude each other."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true", help="print only errors (no progress, no summary)")
    group.add_argument("-v", "--verbose", action="count", default=0, help="say more (repeat for more detail)")


def verbosity(args: argparse.Namespace) -> int:
    """-1 with ``--quiet``, else the number of ``--verbose`` flags (0 by default)."""
    return -1 if getattr(args, "quiet", False) else int(getattr(args, "verbose", 0) or 0)
