"""The on-line kernel compiled for another set of Q formats (a sweep's question: how narrow may a variable be).

The kernel (:mod:`gaitlog.firmware_sim.algorithms.kernel`) takes its formats' fraction bits as compile-time integers
(``F_ACC``...; :mod:`gaitlog.firmware_sim.algorithms.formats`). For a :class:`KernelFormats` (fraction bits of the
chain's main state variables) other than the shipped one, :func:`entry_points` compiles the *same functions* (their code objects) with a
copy of the kernel module's globals in which :meth:`KernelFormats.constants` replace the shipped integers:
no second text of the algorithm, numba folds the new constants exactly as it folds the shipped ones.

The variants are JIT-compiled by numba without its disk cache (the cache is keyed by the source file, which
is the shipped kernel's: a variant must never be loaded as the shipped kernel or the reverse), about 8 s per
format set, once per process (kept in memory, :data:`MAX_VARIANTS` of them). The shipped formats always run
the kernel built ahead of time (:mod:`gaitlog.firmware_sim.algorithms.aot_kernel`). Only the fixed-point arithmetic
has formats; a float kernel is the shipped one.
"""

from __future__ import annotations

import re
import threading
import types
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, fields

from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.formats import (
    ACC_Q,
    GRAVITY_Q,
    LOWPASS_Q,
    POSITION2_Q,
    POSITION_Q,
    word,
)
from gaitlog.firmware_sim.compiled import load_numba
from gaitlog.firmware_sim.fixedpoint import QFormat

__all__ = ["MAX_VARIANTS", "KernelFormats", "compile_kernel", "entry_points"]

#: Format sets whose compiled kernel a process keeps (a sweep cycles through its sets once per walk: keep them all).
MAX_VARIANTS = 32
#: The kernel's entry points (as :data:`gaitlog.firmware_sim.algorithms.aot_kernel.ENTRY_POINTS`).
_NAMES = ("process", "flush", "reset")
#: Each field's shipped format and its short name in a label.
_SHIPPED = {"acc_frac_bits": ACC_Q, "gravity_frac_bits": GRAVITY_Q, "lowpass_frac_bits": LOWPASS_Q,
            "position2_frac_bits": POSITION2_Q}
_SHORT = {"acc_frac_bits": "acc", "gravity_frac_bits": "grav", "lowpass_frac_bits": "lp",
          "position2_frac_bits": "m2pos"}


@dataclass(frozen=True)
class KernelFormats:
    """Fraction bits of the main state variables, the one set of formats a kernel is compiled with.

    The default is the firmware's (:mod:`gaitlog.firmware_sim.algorithms.formats`). Another set gives a variable fewer
    fraction bits (a coarser lsb) in the same word, so its range is never smaller: the question a sweep asks is
    how coarse a variable may be; the word it then needs is its integer bits + these + sign. The kernel text is
    the same; :func:`compile_kernel` compiles it with :meth:`constants` in place of the shipped ``F_*`` (and
    the lowpass word, which saturates at the format's range).

    Attributes
    ----------
    acc_frac_bits
        Calibrated specific force, gravity's output and a_v (``ACC_Q``); the velocity and position
        accumulators sum a_v and keep its fraction bits (``VELOCITY_Q``, ``POSITION_Q``).
    gravity_frac_bits
        The two exponential gravity stages (``GRAVITY_Q``).
    lowpass_frac_bits
        The FIR outputs y3, d10, the impact band and the step amplitude (``LOWPASS_Q``).
    position2_frac_bits
        M2's drift-corrected position and c1, c2 (``POSITION2_Q``).
    """

    acc_frac_bits: int = ACC_Q.frac_bits
    gravity_frac_bits: int = GRAVITY_Q.frac_bits
    lowpass_frac_bits: int = LOWPASS_Q.frac_bits
    position2_frac_bits: int = POSITION2_Q.frac_bits

    def __post_init__(self) -> None:
        for f in fields(self):
            v, top = getattr(self, f.name), _SHIPPED[f.name].frac_bits
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= top:
                raise ValueError(f"{f.name} must be an integer 1 .. {top} (the shipped format's), got {v!r}")

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The fields, in order."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def parse(cls, label: str) -> KernelFormats:
        """The formats of a :meth:`label` (``"shipped"``, or ``acc10-lp12``: the fields named, in any order,
        each with its fraction bits; the others shipped). Raises ValueError naming what is wrong."""
        text = label.strip()
        if text == "shipped":
            return cls()
        by_short = {v: k for k, v in _SHORT.items()}
        kw: dict[str, int] = {}
        for part in text.split("-"):
            m = re.fullmatch(r"([a-z]+[a-z0-9]*?)(\d+)", part)
            if m is None or m.group(1) not in by_short:
                raise ValueError(f"Q formats {label!r}: {part!r} is not NAME+BITS with NAME one of "
                                 f"{', '.join(_SHORT.values())} (e.g. acc10-lp12), nor 'shipped'")
            name = by_short[m.group(1)]
            if name in kw:
                raise ValueError(f"Q formats {label!r}: {m.group(1)} given twice")
            kw[name] = int(m.group(2))
        try:
            return cls(**kw)
        except ValueError as err:
            raise ValueError(f"Q formats {label!r}: {err}") from None

    def label(self) -> str:
        """``"shipped"``, else the fields that differ from it, e.g. ``acc10-lp12`` (:meth:`parse` reads it)."""
        parts = [f"{_SHORT[n]}{getattr(self, n)}" for n in self.field_names()
                 if getattr(self, n) != _SHIPPED[n].frac_bits]
        return "-".join(parts) if parts else "shipped"

    @property
    def shipped(self) -> bool:
        """True for the firmware's own formats (the kernel built ahead of time runs them)."""
        return self == KernelFormats()

    def q(self, name: str) -> QFormat:
        """The format of field ``name`` (e.g. ``"acc_frac_bits"``): the shipped one with these fraction bits
        (same word)."""
        base = _SHIPPED[name]
        return QFormat(base.int_bits + base.frac_bits - getattr(self, name), getattr(self, name),
                       signed=base.signed, word_bits=base.word_bits)

    @property
    def acc_q(self) -> QFormat:
        """a_v's format."""
        return self.q("acc_frac_bits")

    @property
    def position_q(self) -> QFormat:
        """The position accumulator: a_v's fraction bits in ``POSITION_Q``'s word."""
        return QFormat(POSITION_Q.int_bits + POSITION_Q.frac_bits - self.acc_frac_bits, self.acc_frac_bits,
                       word_bits=POSITION_Q.word_bits)

    @property
    def position2_q(self) -> QFormat:
        """M2's position format."""
        return self.q("position2_frac_bits")

    @property
    def lowpass_q(self) -> QFormat:
        """The FIR outputs' format."""
        return self.q("lowpass_frac_bits")

    def theory_bits(self) -> dict[str, int]:
        """The fraction bits the quantisation theory's arithmetic share takes
        (:func:`gaitlog.host.studies.quantisation_theory.arithmetic_sigma_m`'s keywords)."""
        return {"acc_frac_bits": self.acc_frac_bits, "lowpass_frac_bits": self.lowpass_frac_bits}

    def constants(self) -> dict[str, int]:
        """The kernel's compile-time integers these formats replace (names as in ``formats``)."""
        lp = self.lowpass_q
        return {"F_ACC": self.acc_frac_bits, "F_POS": self.acc_frac_bits, "F_GRAV": self.gravity_frac_bits,
                "F_LP": self.lowpass_frac_bits, "W_LP": word(QFormat(LOWPASS_Q.int_bits, lp.frac_bits, word_bits=LOWPASS_Q.word_bits)),
                "F_POS2": self.position2_frac_bits}


_VARIANTS: OrderedDict[KernelFormats, tuple[Callable, Callable, Callable]] = OrderedDict()
_LOCK = threading.Lock()


def _kernel_functions(namespace: dict) -> dict[str, types.FunctionType]:
    """The kernel module's own functions (every one is compiled), as Python functions: a numba dispatcher's or
    a lazy marker's ``py_func``, or the function itself (``NUMBA_DISABLE_JIT=1``)."""
    out = {}
    for name, obj in namespace.items():
        py = getattr(obj, "py_func", obj)
        if isinstance(py, types.FunctionType) and py.__module__ == kernel.__name__:
            out[name] = py
    return out


def compile_kernel(formats: KernelFormats) -> tuple[Callable, Callable, Callable]:
    """``process``, ``flush``, ``reset`` compiled now for ``formats`` (any set, the shipped one included: the
    tests check that this gives the kernel built ahead of time bit for bit); not kept (:func:`entry_points`)."""
    numba = load_numba()
    namespace = dict(vars(kernel))
    namespace.update(formats.constants())
    for name, py in _kernel_functions(vars(kernel)).items():
        fn = types.FunctionType(py.__code__, namespace, py.__name__, py.__defaults__, py.__closure__)
        fn.__qualname__ = f"{py.__qualname__}[{formats.label()}]"
        namespace[name] = numba.njit(cache=False)(fn)
    return tuple(namespace[n] for n in _NAMES)


def entry_points(formats: KernelFormats) -> tuple[Callable, Callable, Callable]:
    """The fixed-point kernel's ``process``, ``flush``, ``reset`` compiled for ``formats`` (module notes).

    Raises ValueError for the shipped formats: they run the kernel built ahead of time.
    """
    if formats.shipped:
        raise ValueError("the shipped formats run the kernel built ahead of time (aot_kernel.entry_points)")
    with _LOCK:
        found = _VARIANTS.get(formats)
        if found is None:
            found = compile_kernel(formats)
            _VARIANTS[formats] = found
            while len(_VARIANTS) > MAX_VARIANTS:
                _VARIANTS.popitem(last=False)
        else:
            _VARIANTS.move_to_end(formats)
    return found
