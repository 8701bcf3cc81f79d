"""pyserial URL handlers of gaitlog (``serial.protocol_handler_packages`` entry ``"host.transports"``).

:func:`register` makes ``serial.serial_for_url("emu://...")`` find :mod:`host.transports.protocol_emu`.
"""

from __future__ import annotations

PACKAGE = "host.transports"


def register() -> None:
    """Add this package to pyserial's URL-handler search path (idempotent)."""
    import serial

    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)
