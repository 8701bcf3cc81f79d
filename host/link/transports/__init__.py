"""pyserial URL handlers of gaitlog (``serial.protocol_handler_packages`` entry ``"gaitlog.host.link.transports"``).

:func:`register` makes ``serial.serial_for_url("emu://...")`` find :mod:`gaitlog.host.link.transports.protocol_emu`.
"""

from __future__ import annotations

import serial

PACKAGE = "gaitlog.host.link.transports"


def register() -> None:
    """Add this package to pyserial's URL-handler search path (idempotent)."""
    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)
