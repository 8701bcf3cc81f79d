"""The one exception base of the ``host`` package."""

from __future__ import annotations


class HostError(Exception):
    """The host cannot do what was asked with the data, file or link it was given.

    Messages name the problem and the place (file, offset, frame, line) and say what to do.
    """


class UsageError(HostError):
    """A bad option value or combination of options that the argument parser cannot see and the command
    finds: ``gaitlog`` exits 2 with it, as with the parser's own usage errors (a data or I/O error exits 1).

    The message names the option and what it takes, e.g. ``--adc-bits 12: ...``.
    """
