"""The firmware's RAM map, read from gpasm's listing of ``logger.asm``: every variable, the overlays, the groups.

The map is the ``cblock`` blocks of ``logger_ram.inc``, ``step_record_ram.inc`` and ``registers.inc`` as gpasm
assembled them. A block that starts at a literal address (``cblock 0x20``) allocates RAM; a block that starts at
a variable (``cblock C0L``) and an ``equ`` whose value names a variable (``B0 equ FX_L``) are overlays: other
names for bytes whose lifetimes do not meet (the include files give each argument). The page buffer and
``W_TEMP``, defined by ``equ``, are allocations too.

:func:`ram_map` parses a listing; :meth:`RamMap.problems` lists what is wrong with it: RAM past the 368 bytes or
outside a bank's general-purpose registers, two allocations on the same byte, an overlay that is not in
:data:`OVERLAYS`, a firmware group (:data:`FIRMWARE_GROUPS`) missing or smaller than the model's figure.

>>> lines = ["                      00001         cblock  0x20",
...          "  00000020            00002         A_L, A_H   ; a",
...          "  00000022            00003         A_END",
...          "                      00004         endc",
...          "  00000020            00005 B_L             equ     A_L"]
>>> m = ram_map("\\n".join(lines), {"A_L": 0x20, "A_H": 0x21, "A_END": 0x22, "B_L": 0x20, "W_TEMP": 0x7F})
>>> [(v.name, v.address, v.size) for v in m.allocations][:3], m.aliases, m.total_bytes
([('A_L', 32, 1), ('A_H', 33, 1), ('A_END', 34, 0)], {'B_L': 'A_L'}, 131)
>>> m.problems()[0]
'alias B_L of A_L is not a documented overlay'

"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from gaitlog.firmware_sim.budget import FIRMWARE_RAM, PIC_RAM_BYTES

__all__ = ["RamVariable", "RamMap", "ram_map", "OVERLAYS", "FIRMWARE_GROUPS", "GPR_RANGES", "PAGE_BUFFER"]

#: General-purpose RAM of the PIC16F877 (DS30292 figure 2-3): (first, end) per bank; 0x70-0x7F is common.
GPR_RANGES = ((0x20, 0x70), (0xA0, 0xF0), (0x110, 0x170), (0x190, 0x1F0), (0x70, 0x80))
#: The page buffer (logger_ram.inc PAGE_A.., defined by equ): words 0-15 in bank 2, 16-31 in bank 3.
PAGE_BUFFER = (("page buffer, words 0-15", 0x110, 64), ("page buffer, words 16-31", 0x190, 64))
#: Every overlay the include files document: the overlay's name -> the variable whose bytes it shares.
#: Overlays of the step record's bank-2 phases (``HS_J`` .. ``P_RSTEP``, ``equ`` with literal addresses) stay
#: inside its own block and are not listed.
OVERLAYS: dict[str, str] = {
    **{n: "FX_L" for n in ("B0", "B1", "B2", "B3")},                    # the P32 word, dead before stage 1's rows
    **{n: r for n, r in zip(("SUM0", "SUM1", "SUM2", "SUM3"), ("REM0", "REM1", "REM2", "SIGNS"))},
    "SGN_T": "COUNT",
    **{n: "C0L" for n in ("GX_L", "GX_H", "GY_L", "GY_H", "GZ_L", "GZ_H")},   # stage 3's g on stage 1's c
    **{n: "C0L" for n in ("Y3_0", "Y3_1", "Y3_2", "M_L", "M_H", "TAP")},      # steps 4-5 on stages 1-3
    **{n: "N2_0" for n in ("IDX_LO", "IDX_HI", "SEL_J", "SEL_LT", "SEL_LE", "SEL_K")},
    "P_C2": "N2_0", "SCR_POS": "GN_L",                                  # the step record on steps 4-5's
    "CALL_E": "E_L", "CALL_S": "S_L", "CALL_M": "FM_L",                # finalise's call record: its inputs
    "HS_J": "WBUF", "HS_K": "WBUF", "HS_BEST": "WBUF", "HS_R": "WBUF",  # the step record's phases
    "REC_END0": "REC", "REC_DUR": "REC", "REC_TO": "REC", "REC_HS": "REC", "REC_FLAGS": "REC",
    "REC_L1": "REC", "REC_L2": "REC", "REC_L3": "REC", "REC_L4": "REC", "REC_L5": "REC", "REC_CRC": "REC",
    "ALG_FLAGS": "AFLAGS", "ALG_LAST_L": "LAST", "ALG_LAST_H": "LAST",
}
#: The firmware's own variable groups besides the algorithm: group -> (its variables, the model's item in
#: :data:`gaitlog.firmware_sim.budget.FIRMWARE_RAM` or None, reserved: True while the part is the model's).
FIRMWARE_GROUPS: dict[str, tuple[tuple[str, ...], str | None, bool]] = {
    "header counters": (("SAMPLE_L", "SAMPLE_H", "SAMPLE_U", "SAMPLE_T", "STEPS_W"), None, False),
    "UART receiver": (("UART_RX",), "UART receiver", True),
    "UART transmitter": (("UART_TX",), "UART transmitter", True),
    "I2C page write": (("I2C_PW",), "I2C driver", True),
}
_SOURCE = re.compile(r"^(?:\s+[0-9A-F]{8})?(?:\s+[0-9A-F]{4}){0,2}\s+\d{5} (.*)$")
_NAME = re.compile(r"[A-Za-z_][A-Za-z_0-9]*")


@dataclass(frozen=True)
class RamVariable:
    """One allocation: name, first address, bytes."""

    name: str
    address: int
    size: int

    @property
    def end(self) -> int:
        return self.address + self.size


@dataclass(frozen=True)
class RamMap:
    """The allocations (``cblock`` at a literal address, the page buffer, ``W_TEMP``), the overlay blocks' and the
    aliases' names (name -> the variable they name), from one listing."""

    allocations: tuple[RamVariable, ...]
    overlays: tuple[RamVariable, ...] = ()
    aliases: dict[str, str] = field(default_factory=dict)

    def variable(self, name: str) -> RamVariable | None:
        return next((v for v in self.allocations if v.name == name), None)

    @property
    def total_bytes(self) -> int:
        return sum(v.size for v in self.allocations)

    def bank_bytes(self) -> dict[str, int]:
        """Bytes allocated per bank (common RAM apart)."""
        names = ("bank 0", "bank 1", "bank 2", "bank 3", "common")
        return {n: sum(v.size for v in self.allocations if lo <= v.address < hi)
                for n, (lo, hi) in zip(names, GPR_RANGES)}

    def groups(self) -> dict[str, int]:
        """Bytes of each :data:`FIRMWARE_GROUPS` group in the map (0: missing)."""
        return {g: sum(v.size for n in names if (v := self.variable(n)) is not None)
                for g, (names, _, _) in FIRMWARE_GROUPS.items()}

    def problems(self) -> list[str]:
        """What is wrong with the map (empty: it fits, nothing overlaps but the documented overlays, every
        firmware group is there at least at the model's size)."""
        out = []
        if self.total_bytes > PIC_RAM_BYTES:
            out.append(f"RAM: {self.total_bytes} of {PIC_RAM_BYTES} bytes")
        for v in self.allocations:
            if v.size and not any(lo <= v.address and v.end <= hi for lo, hi in GPR_RANGES):
                out.append(f"{v.name} (0x{v.address:03X}, {v.size} bytes) is outside the general-purpose RAM")
        live = sorted((v for v in self.allocations if v.size), key=lambda v: v.address)
        for a, b in zip(live, live[1:]):
            if b.address < a.end:
                out.append(f"{a.name} and {b.name} share 0x{b.address:03X}")
        for v in self.overlays:
            if v.name not in OVERLAYS:
                out.append(f"overlay {v.name} (0x{v.address:03X}) is not a documented overlay")
        for name, target in self.aliases.items():
            if OVERLAYS.get(name) is None:
                out.append(f"alias {name} of {target} is not a documented overlay")
        model = {i.name: i.bytes for i in FIRMWARE_RAM}
        for g, size in self.groups().items():
            names, item, _ = FIRMWARE_GROUPS[g]
            if any(self.variable(n) is None for n in names):
                out.append(f"the {g} ({', '.join(names)}) are not in the RAM map")
            elif item is not None and size < model[item]:
                out.append(f"the {g} take {size} bytes, less than the model's {model[item]}")
        return out


def _statements(listing: str):
    """(source text without its comment) of each listing line that carries source."""
    for line in listing.splitlines():
        m = _SOURCE.match(line)
        if m:
            yield m.group(1).split(";", 1)[0].strip()


def ram_map(listing: str, symbols: dict[str, int]) -> RamMap:
    """The RAM map of ``listing`` (gpasm's ``.lst`` text) with its symbol table ``symbols``."""
    blocks: list[tuple[bool, list[str]]] = []
    aliases: dict[str, str] = {}
    current: list[str] | None = None
    for text in _statements(listing):
        words = text.split()
        if len(words) >= 2 and words[0].lower() == "cblock":
            current = []
            blocks.append((bool(re.match(r"^(0x[0-9A-Fa-f]+|\d+|\.\d+)$", words[1])), current))
        elif words and words[0].lower() == "endc":
            current = None
        elif current is not None and words:
            current += [tok.split(":")[0].strip() for tok in text.split(",") if tok.strip()]
        elif len(words) >= 3 and words[1].lower() == "equ":
            aliases[words[0]] = " ".join(words[2:])
    allocations, overlays = [], []
    for primary, names in blocks:
        addrs = [symbols[n] for n in names]
        for i, (n, a) in enumerate(zip(names, addrs)):
            size = (addrs[i + 1] - a) if i + 1 < len(names) else 0 if n.endswith("_END") else 1
            (allocations if primary else overlays).append(RamVariable(n, a, size))
    allocations += [RamVariable(n, a, s) for n, a, s in PAGE_BUFFER] + [RamVariable("W_TEMP", symbols["W_TEMP"], 1)]
    allocated = {v.name for v in allocations} | {v.name for v in overlays}
    named = {}
    for name, expr in aliases.items():
        target = next((t for t in _NAME.findall(expr) if t in allocated), None)
        if target is not None and name not in allocated:
            named[name] = target
    return RamMap(tuple(allocations), tuple(overlays), named)
