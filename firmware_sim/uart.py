"""The PIC16F877 USART's bit timing: baud rate from the crystal and SPBRG, and the time of one byte.

Asynchronous mode, BRGH = 1: ``baud = Fosc / (16 · (SPBRG + 1))`` (BRGH = 0: ``/64``); the firmware picks
``SPBRG = round(Fosc / (16 · baud)) − 1``. One 8N1 character is 10 bit times (start, 8 data, stop).

The default crystal is 18.432 MHz, a "baud-rate" crystal: SPBRG = 9 gives exactly 115200 (0 % error), and
exact rates at 9600, 19200 and 57600 too. The 20 MHz crystal the PIC allows at most gives SPBRG = 10 and
113,636 baud at a nominal 115200 (−1.36 %, within the ±2 % a UART tolerates, HARDWARE.md).

Examples
--------
>>> u = UartTiming()
>>> u.spbrg, u.actual_baud, u.error_percent
(9, 115200.0, 0.0)
>>> v = UartTiming(fosc_hz=20e6)
>>> v.spbrg, round(v.actual_baud), round(v.error_percent, 2)
(10, 113636, -1.36)
>>> round(245_760 * UartTiming().byte_time_s, 2)
21.33
"""

from __future__ import annotations

from dataclasses import dataclass

from gaitlog.firmware_sim.errors import DeviceError

__all__ = ["UartTiming", "BITS_PER_BYTE_8N1"]

#: start + 8 data + stop bits.
BITS_PER_BYTE_8N1 = 10


@dataclass(frozen=True)
class UartTiming:
    """Baud-rate generator settings.

    Parameters
    ----------
    baud
        Requested (nominal) baud rate.
    fosc_hz
        PIC oscillator frequency (crystal), Hz.
    brgh
        High-speed baud select (divider 16 instead of 64).
    """

    baud: int = 115200
    fosc_hz: float = 18_432_000.0
    brgh: bool = True

    def __post_init__(self) -> None:
        if self.baud <= 0 or self.fosc_hz <= 0:
            raise DeviceError(f"baud and fosc_hz must be > 0, got {self.baud}, {self.fosc_hz}")
        if not 0 <= self.spbrg <= 255:
            raise DeviceError(
                f"{self.baud} baud cannot be made from {self.fosc_hz / 1e6:g} MHz (SPBRG {self.spbrg} outside 0..255)"
            )
        if abs(self.error_percent) > 5.0:
            raise DeviceError(f"{self.baud} baud from {self.fosc_hz / 1e6:g} MHz is off by {self.error_percent:.1f} %")

    @property
    def divider(self) -> int:
        """16 (BRGH = 1) or 64."""
        return 16 if self.brgh else 64

    @property
    def spbrg(self) -> int:
        """Baud-rate register value the firmware loads."""
        return int(round(self.fosc_hz / (self.divider * self.baud))) - 1

    @property
    def actual_baud(self) -> float:
        """The rate the USART really runs at."""
        return self.fosc_hz / (self.divider * (self.spbrg + 1))

    @property
    def error_percent(self) -> float:
        """Relative error of the real rate against the nominal one, %."""
        return (self.actual_baud / self.baud - 1.0) * 100.0

    @property
    def byte_time_s(self) -> float:
        """Duration of one 8N1 character at the real rate, s."""
        return BITS_PER_BYTE_8N1 / self.actual_baud
