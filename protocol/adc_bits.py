"""The ADC width rule, stated once: how many bits an ADC code may have.

A logger stores each code in a 10-bit field of the P32 word (``PROTOCOL.md`` section 1), so a device's
converter has 1 to :data:`MAX_STORED_ADC_BITS` bits. Studies that quantise a simulated sensor at other widths
(never stored in a P32 word) go up to :data:`MAX_SIMULATED_ADC_BITS`.

Examples
--------
>>> adc_bits_problem(10) is None, adc_bits_problem(11)
(True, '11 is not an integer in 1..10')
>>> check_adc_bits(12, max_bits=MAX_SIMULATED_ADC_BITS)
12
"""

from __future__ import annotations

from gaitlog.protocol.errors import ProtocolError

__all__ = ["MAX_SIMULATED_ADC_BITS", "MAX_STORED_ADC_BITS", "adc_bits_problem", "check_adc_bits"]

#: Width of a code field of the P32 word: the widest converter a logger can store.
MAX_STORED_ADC_BITS = 10
#: Widest converter the simulation studies quantise to (codes compared, never packed).
MAX_SIMULATED_ADC_BITS = 12


def adc_bits_problem(adc_bits: object, *, max_bits: int = MAX_STORED_ADC_BITS) -> str | None:
    """What is wrong with ``adc_bits`` as a converter width of 1 to ``max_bits`` bits, or None when nothing."""
    try:
        whole = int(adc_bits)  # type: ignore[call-overload]
    except (TypeError, ValueError, OverflowError):
        whole = None
    if isinstance(adc_bits, bool) or whole is None or whole != adc_bits or not 1 <= whole <= max_bits:
        return f"{adc_bits!r} is not an integer in 1..{max_bits}"
    return None


def check_adc_bits(adc_bits: object, *, max_bits: int = MAX_STORED_ADC_BITS, what: str = "adc_bits",
                   error: type[Exception] = ProtocolError) -> int:
    """``adc_bits`` as an int, or ``error("<what>: <problem>")`` (each layer passes its own error class).

    Raises
    ------
    ProtocolError
        (or ``error``) when ``adc_bits`` is not an integer in ``1..max_bits``.
    """
    problem = adc_bits_problem(adc_bits, max_bits=max_bits)
    if problem is not None:
        raise error(f"{what}: {problem}")
    return int(adc_bits)  # type: ignore[call-overload]
