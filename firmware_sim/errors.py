"""The one exception base of the ``firmware_sim`` package."""

from __future__ import annotations


class DeviceError(Exception):
    """The emulated device, its world or its configuration cannot do what was asked.

    Messages say what was expected, what was found and, where useful, what to do.
    """
