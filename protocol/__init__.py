"""The contract between the gait logger and its host.

The written specification is ``protocol/PROTOCOL.md``; the modules of this package are its executable
form (construct declarations for frames and headers, numpy for bulk sample payloads). This package
imports no other package of the project, and importing it imports nothing heavy (the modules do).

Modules: ``crc`` (CRC-16/XMODEM, CRC-32), ``packing`` (P32 sample words, section 1), ``header`` (device
header and calibration slot, section 2), ``steps`` (step configuration block, per-step records and the step
memory, sections 2.2-2.3), ``frames`` (frames, payloads, resynchronising parser, sections 3-4), ``xmodem``
(XMODEM-1K/CRC sender and blocks, section 5), ``image`` (``.glimg`` memory image with recovery, section 6),
``errors`` (``ProtocolError``), ``atomic_write``.
"""
