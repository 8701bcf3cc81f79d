"""The one exception base of the ``host`` package."""

from __future__ import annotations


class HostError(Exception):
    """The host cannot do what was asked with the data, file or link it was given.

    Messages name the problem and the place (file, offset, frame, line) and say what to do.
    """
