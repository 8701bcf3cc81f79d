"""The on-line kernel compiled for another set of Q formats (a sweep's question: how narrow may a variable be).

The kernel (:mod:`gaitlog.firmware_sim.algorithms.kernel`) takes its formats' fraction bits as compile-time integers
(``F_ACC``...; :mod:`gaitlog.firmware_sim.algorithms.formats`). For a :class:`KernelFormats` (fraction bits of the
chain's main state variables) other than the shipped one, :func:`entry_points` compiles the *same functions* (their code objects) with a
copy of the kernel module's globals in which :meth:`KernelFormats.constants` replace the shipped integers:
no second text of the algorithm, numba folds the new constants exactly as it folds the shipped ones.

A variant is compiled ahead of time into the compile cache, once per machine: an extension module in
``aot-<sources>-<formats>`` beside the shipped kernel's (:func:`variant_folder`; the hash of the compiled sources
and a digest of every field of the formats, :func:`cache_key`), built by the first process that needs it under
the shipped module's lock protocol (:func:`gaitlog.firmware_sim.algorithms.aot_kernel.build_or_wait`): the other
processes (a sweep's Dask workers) wait for it and load it, and later runs load it in milliseconds. numba's
own disk cache is not used (it is keyed by the source file, which is the shipped kernel's: a variant must never be
loaded as the shipped kernel or the reverse). Without a compiler (or with ``GAITLOG_NO_AOT=1``) a variant is
JIT-compiled, about 8-25 s, once per process. Either way a process keeps :data:`MAX_VARIANTS` of them in memory.
The shipped formats always run the shipped kernel built ahead of time. Only the fixed-point arithmetic has
formats; a float kernel is the shipped one.

**Rounding.** :class:`KernelFormats` also holds the rounding mode of each operation class (products, right
shifts, quotients: :data:`gaitlog.firmware_sim.algorithms.arithmetic.ROUNDING_CLASSES`): a variant's kernel calls
the arithmetic's fixed-point functions compiled with those modes in place of the shipped ``ROUND_*`` constants.
"""

from __future__ import annotations

import hashlib
import re
import threading
import types
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from pathlib import Path

from gaitlog.firmware_sim.algorithms import aot_kernel, arithmetic, kernel
from gaitlog.firmware_sim.algorithms.formats import (
    ACC2_Q,
    ACC_Q,
    EXCURSION2_Q,
    EXCURSION_Q,
    FIR_SUM_Q,
    GRAVITY_Q,
    K4_Q,
    K_Q,
    KERNEL_Q,
    LENGTH_Q,
    LOWPASS_Q,
    M5_Q,
    MANTISSA_Q,
    PENDULUM_ARG2_Q,
    PENDULUM_ARG_Q,
    POSITION2_Q,
    POSITION_Q,
    ROOT4_Q,
    STEP_Q,
    TWO_LENGTH_Q,
    VELOCITY_Q,
    centred_q,
    word,
)
from gaitlog.firmware_sim.compiled import jit_options, load_numba
from gaitlog.firmware_sim.fixedpoint import ROUNDING_MODES, QFormat

__all__ = ["MAX_VARIANTS", "KernelFormats", "cache_key", "compile_kernel", "entry_points", "variant_folder",
           "SHIPPED_ROUNDING"]

#: Format sets whose compiled kernel a process keeps (a sweep cycles through its sets once per walk: keep them all).
MAX_VARIANTS = 32
#: The kernel's entry points (as :data:`gaitlog.firmware_sim.algorithms.aot_kernel.ENTRY_POINTS`).
_NAMES = ("process", "flush", "reset")
#: Each fraction-bits field's shipped format, its short name in a label (letters only: the bits follow) and the
#: kernel constant it replaces (None: the configuration's, not compiled in).
_SHIPPED = {"acc_frac_bits": ACC_Q, "gravity_frac_bits": GRAVITY_Q, "lowpass_frac_bits": LOWPASS_Q,
            "position2_frac_bits": POSITION2_Q, "acc2_frac_bits": ACC2_Q, "fir_frac_bits": FIR_SUM_Q,
            "kernel_frac_bits": KERNEL_Q, "excursion_frac_bits": EXCURSION_Q, "excursion2_frac_bits": EXCURSION2_Q,
            "root_frac_bits": ROOT4_Q, "step_frac_bits": STEP_Q, "k_frac_bits": K_Q, "k4_frac_bits": K4_Q,
            "m5_frac_bits": M5_Q, "mantissa_frac_bits": MANTISSA_Q, "leg_frac_bits": LENGTH_Q,
            "two_leg_frac_bits": TWO_LENGTH_Q, "pendulum_arg_frac_bits": PENDULUM_ARG_Q,
            "pendulum_arg2_frac_bits": PENDULUM_ARG2_Q}
_SHORT = {"acc_frac_bits": "acc", "gravity_frac_bits": "grav", "lowpass_frac_bits": "lp",
          "position2_frac_bits": "m2pos", "acc2_frac_bits": "sq", "fir_frac_bits": "fir", "kernel_frac_bits": "kern",
          "excursion_frac_bits": "exc", "excursion2_frac_bits": "excc", "root_frac_bits": "root",
          "step_frac_bits": "step", "k_frac_bits": "k", "k4_frac_bits": "kw", "m5_frac_bits": "cad",
          "mantissa_frac_bits": "mant", "leg_frac_bits": "leg", "two_leg_frac_bits": "twoleg",
          "pendulum_arg_frac_bits": "parg", "pendulum_arg2_frac_bits": "pargc", "lowpass_int_bits": "lpint"}
_CONSTANT = {"acc2_frac_bits": "F_ACC2", "fir_frac_bits": "F_FIR", "kernel_frac_bits": "F_KERNEL",
             "excursion_frac_bits": "F_EXC", "excursion2_frac_bits": "F_EXC2", "root_frac_bits": "F_ROOT",
             "step_frac_bits": "F_STEP", "k_frac_bits": "F_K", "k4_frac_bits": "F_K4", "m5_frac_bits": "F_M5",
             "two_leg_frac_bits": "F_TWO_LEN"}
#: Each word field (``<name>_word_bits``: where the format's values saturate, sign included): its shipped format,
#: the frac field whose bits its format has (None: a format without one), its kernel constant (None: the
#: configuration's, saturated when the algorithm is configured) and its label token after ``w`` (None: the frac
#: field's short name, ``wacc12``); the lowpass's word is ``lowpass_int_bits`` (``lpint``).
_WORDS = {
    "code_word_bits": (centred_q(10), None, "W_CODE", "code"),
    "acc_word_bits": (ACC_Q, "acc_frac_bits", "W_ACC", None),
    "gravity_word_bits": (GRAVITY_Q, "gravity_frac_bits", "W_GRAV", None),
    "acc2_word_bits": (ACC2_Q, "acc2_frac_bits", "W_ACC2", None),
    "kernel_word_bits": (KERNEL_Q, "kernel_frac_bits", None, None),
    "fir_word_bits": (FIR_SUM_Q, "fir_frac_bits", "W_FIR", None),
    "velocity_word_bits": (VELOCITY_Q, "acc_frac_bits", "W_VEL", "vel"),
    "position_word_bits": (POSITION_Q, "acc_frac_bits", "W_POS", "pos"),
    "position2_word_bits": (POSITION2_Q, "position2_frac_bits", "W_POS2", None),
    "excursion_word_bits": (EXCURSION_Q, "excursion_frac_bits", "W_EXC", None),
    "excursion2_word_bits": (EXCURSION2_Q, "excursion2_frac_bits", "W_EXC2", None),
    "leg_word_bits": (LENGTH_Q, "leg_frac_bits", None, None),
    "two_leg_word_bits": (TWO_LENGTH_Q, "two_leg_frac_bits", None, None),
    "pendulum_arg_word_bits": (PENDULUM_ARG_Q, "pendulum_arg_frac_bits", "W_PARG", None),
    "pendulum_arg2_word_bits": (PENDULUM_ARG2_Q, "pendulum_arg2_frac_bits", "W_PARG2", None),
    "step_word_bits": (STEP_Q, "step_frac_bits", "W_STEP", None),
    "k_word_bits": (K_Q, "k_frac_bits", None, None),
    "k4_word_bits": (K4_Q, "k4_frac_bits", None, None),
    "root_word_bits": (ROOT4_Q, "root_frac_bits", "W_ROOT", None),
    "m5_word_bits": (M5_Q, "m5_frac_bits", "W_M5", None),
}
_SHORT.update({name: "w" + (token or _SHORT[frac]) for name, (_, frac, _, token) in _WORDS.items()})
#: Fields that only change the configuration the kernel is given (not compiled in): the shipped kernel runs them.
_CONFIGURATION_ONLY = ("mantissa_frac_bits", "leg_frac_bits", "kernel_word_bits", "leg_word_bits",
                       "two_leg_word_bits", "k_word_bits", "k4_word_bits")
#: The rounding fields (operation classes of :data:`gaitlog.firmware_sim.algorithms.arithmetic.ROUNDING_CLASSES`).
_ROUNDING = {"mul_rounding": "mul", "shift_rounding": "shift", "div_rounding": "div"}
#: The firmware's rounding mode of every class.
SHIPPED_ROUNDING = "half-up"


@dataclass(frozen=True)
class KernelFormats:
    """Fraction bits and words of the Q formats, the one set of formats a kernel is compiled with.

    The default is the firmware's (:mod:`gaitlog.firmware_sim.algorithms.formats`). Another set gives a variable fewer
    fraction bits (a coarser lsb) in the same word, so its range is never smaller: the question a sweep asks is
    how coarse a variable may be; the word it then needs is its integer bits + these + sign. The kernel text is
    the same; :func:`compile_kernel` compiles it with :meth:`constants` in place of the shipped ``F_*`` and
    ``W_*``.

    **Words** (``<format>_word_bits``, label ``w`` + the format's name: ``wacc12``, ``wgrav24``...): the bits,
    sign included, where a format's values saturate, at most its shipped container (16, 24 or 32 bits). A narrower
    word is fewer integer bits: every store of a value of that format (each primitive's result word) saturates at
    ``(2^(W-1) - 1) / 2^frac`` and ``-2^(W-1) / 2^frac`` (signed, two's complement; unsigned at ``(2^W - 1) / 2^frac``
    and 0), counted, as the shipped code saturates every result (the PIC's saturating routines, never a wrap).
    Formats of configuration only (the FIR weights, leg and foot, K, K4: ``kernel``, ``leg``, ``twoleg``, ``k``,
    ``kw``) saturate when the algorithm is configured; the shipped kernel runs them. The lowpass's word is ``lowpass_int_bits`` (``lpint``: it keeps
    its integer bits, not its word, when its fraction bits shrink); the mantissas' is their fraction bits (block
    floating point).

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
    acc2_frac_bits: int = ACC2_Q.frac_bits
    fir_frac_bits: int = FIR_SUM_Q.frac_bits
    kernel_frac_bits: int = KERNEL_Q.frac_bits
    excursion_frac_bits: int = EXCURSION_Q.frac_bits
    excursion2_frac_bits: int = EXCURSION2_Q.frac_bits
    root_frac_bits: int = ROOT4_Q.frac_bits
    step_frac_bits: int = STEP_Q.frac_bits
    k_frac_bits: int = K_Q.frac_bits
    k4_frac_bits: int = K4_Q.frac_bits
    m5_frac_bits: int = M5_Q.frac_bits
    mantissa_frac_bits: int = MANTISSA_Q.frac_bits
    leg_frac_bits: int = LENGTH_Q.frac_bits
    two_leg_frac_bits: int = TWO_LENGTH_Q.frac_bits
    pendulum_arg_frac_bits: int = PENDULUM_ARG_Q.frac_bits
    pendulum_arg2_frac_bits: int = PENDULUM_ARG2_Q.frac_bits
    lowpass_int_bits: int = LOWPASS_Q.int_bits
    code_word_bits: int = centred_q(10).total_bits
    acc_word_bits: int = ACC_Q.total_bits
    gravity_word_bits: int = GRAVITY_Q.total_bits
    acc2_word_bits: int = ACC2_Q.total_bits
    kernel_word_bits: int = KERNEL_Q.total_bits
    fir_word_bits: int = FIR_SUM_Q.total_bits
    velocity_word_bits: int = VELOCITY_Q.total_bits
    position_word_bits: int = POSITION_Q.total_bits
    position2_word_bits: int = POSITION2_Q.total_bits
    excursion_word_bits: int = EXCURSION_Q.total_bits
    excursion2_word_bits: int = EXCURSION2_Q.total_bits
    leg_word_bits: int = LENGTH_Q.total_bits
    two_leg_word_bits: int = TWO_LENGTH_Q.total_bits
    pendulum_arg_word_bits: int = PENDULUM_ARG_Q.total_bits
    pendulum_arg2_word_bits: int = PENDULUM_ARG2_Q.total_bits
    step_word_bits: int = STEP_Q.total_bits
    k_word_bits: int = K_Q.total_bits
    k4_word_bits: int = K4_Q.total_bits
    root_word_bits: int = ROOT4_Q.total_bits
    m5_word_bits: int = M5_Q.total_bits
    mul_rounding: str = SHIPPED_ROUNDING
    shift_rounding: str = SHIPPED_ROUNDING
    div_rounding: str = SHIPPED_ROUNDING

    def __post_init__(self) -> None:
        for name in self.field_names():
            v, top = getattr(self, name), _SHIPPED[name].frac_bits
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= top:
                raise ValueError(f"{name} must be an integer 1 .. {top} (the shipped format's), got {v!r}")
        top = LOWPASS_Q.word_bits - 1 - self.lowpass_frac_bits
        w = self.lowpass_int_bits
        if isinstance(w, bool) or not isinstance(w, int) or not 0 <= w <= top:
            raise ValueError(f"lowpass_int_bits must be an integer 0 .. {top} (sign + integer + fraction bits within "
                             f"the {LOWPASS_Q.word_bits}-bit RAM word), got {w!r}")
        for name, (q, _, _, _) in _WORDS.items():
            w = getattr(self, name)
            if isinstance(w, bool) or not isinstance(w, int) or not 2 <= w <= q.word_bits:
                raise ValueError(f"{name} ({_SHORT[name]}) must be an integer 2 .. {q.word_bits} bits (at most "
                                 f"{q}'s {q.word_bits}-bit container), got {w!r}")
        for name in _ROUNDING:
            if getattr(self, name) not in ROUNDING_MODES:
                raise ValueError(f"{name} must be one of {', '.join(ROUNDING_MODES)}, got {getattr(self, name)!r}")

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The fraction-bits fields, in order."""
        return tuple(f.name for f in fields(cls) if f.name.endswith("_frac_bits"))

    @classmethod
    def parse(cls, label: str, rounding: str = "shipped") -> KernelFormats:
        """The formats of a :meth:`label` (``"shipped"``, or ``acc10-lp12-wgrav24``: the fields named, in any
        order, each with its bits, ``lpint1`` the lowpass's integer bits; the others shipped) and the rounding of
        a :meth:`rounding_label` (``"shipped"``, a mode for every class, or ``mul:truncate+div:convergent``).
        Raises ValueError naming what is wrong."""
        modes = cls.parse_rounding(rounding)
        text = label.strip()
        if text == "shipped":
            return cls(**modes)
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
            return cls(**kw, **modes)
        except ValueError as err:
            raise ValueError(f"Q formats {label!r}: {err}") from None

    @staticmethod
    def sweep_fields(q: QFormat) -> tuple[str | None, str | None]:
        """The fields that sweep shipped format ``q`` (one of ``formats``' objects): its fraction bits' and its
        word's (``lowpass_int_bits`` for ``LOWPASS_Q``); None where it has none (``MANTISSA_Q``'s word: the
        shared exponent keeps the range, fewer bits are fewer fraction bits)."""
        frac = "acc_frac_bits" if q is VELOCITY_Q or q is POSITION_Q else next(
            (n for n, s in _SHIPPED.items() if s is q), None)
        word = "lowpass_int_bits" if q is LOWPASS_Q else next((n for n, (s, *_) in _WORDS.items() if s is q), None)
        return frac, word

    @staticmethod
    def token(field_name: str) -> str:
        """A field's name in a :meth:`label` (``acc``, ``wacc`` ...: its bits follow)."""
        return _SHORT[field_name]

    @staticmethod
    def configuration_only(field_name: str) -> bool:
        """True for a field the kernel is not compiled with (the configuration's values are stored in it)."""
        return field_name in _CONFIGURATION_ONLY

    @staticmethod
    def parse_rounding(label: str) -> dict[str, str]:
        """The rounding fields of a :meth:`rounding_label` (ValueError naming what is wrong)."""
        text = label.strip()
        if text == "shipped":
            return {}
        if text in ROUNDING_MODES:
            return dict.fromkeys(_ROUNDING, text)
        by_class = {v: k for k, v in _ROUNDING.items()}
        out: dict[str, str] = {}
        for part in text.split("+"):
            cls_name, _, mode = part.partition(":")
            if cls_name not in by_class or mode not in ROUNDING_MODES:
                raise ValueError(f"rounding {label!r}: {part!r} is not CLASS:MODE with CLASS one of "
                                 f"{', '.join(by_class)} and MODE one of {', '.join(ROUNDING_MODES)} (e.g. "
                                 f"mul:truncate+div:convergent), nor a MODE alone, nor 'shipped'")
            if by_class[cls_name] in out:
                raise ValueError(f"rounding {label!r}: {cls_name} given twice")
            out[by_class[cls_name]] = mode
        return out

    def label(self) -> str:
        """``"shipped"``, else the fields that differ from it, e.g. ``acc10-lp12`` (:meth:`parse` reads it; the
        rounding is :meth:`rounding_label`'s)."""
        parts = [f"{_SHORT[n]}{getattr(self, n)}" for n in self.field_names()
                 if getattr(self, n) != _SHIPPED[n].frac_bits]
        if self.lowpass_int_bits != LOWPASS_Q.int_bits:
            parts.append(f"{_SHORT['lowpass_int_bits']}{self.lowpass_int_bits}")
        parts += [f"{_SHORT[n]}{getattr(self, n)}" for n, (q, _, _, _) in _WORDS.items()
                  if getattr(self, n) != q.total_bits]
        return "-".join(parts) if parts else "shipped"

    def rounding_label(self) -> str:
        """``"shipped"``, one mode (every class), or the classes that differ, e.g. ``mul:truncate``."""
        modes = {n: getattr(self, n) for n in _ROUNDING}
        if all(m == SHIPPED_ROUNDING for m in modes.values()):
            return "shipped"
        if len(set(modes.values())) == 1:
            return next(iter(modes.values()))
        return "+".join(f"{_ROUNDING[n]}:{m}" for n, m in modes.items() if m != SHIPPED_ROUNDING)

    @property
    def shipped(self) -> bool:
        """True for the firmware's own formats (the kernel built ahead of time runs them)."""
        return self == KernelFormats()

    @property
    def compiled_shipped(self) -> bool:
        """True when the kernel's compile-time constants are the firmware's (the kernel built ahead of time runs
        them; the calibration's mantissa bits, the leg's fraction bits and the configuration's words only change
        the configuration)."""
        return replace(self, **{n: getattr(KernelFormats(), n) for n in _CONFIGURATION_ONLY}).shipped

    def rounding_constants(self) -> dict[str, int]:
        """The arithmetic's rounding constants these modes replace (``ROUND_MUL``...)."""
        return {arithmetic.ROUNDING_CLASSES[c]: ROUNDING_MODES[getattr(self, n)] for n, c in _ROUNDING.items()}

    def q(self, name: str) -> QFormat:
        """The format of field ``name`` (e.g. ``"acc_frac_bits"``): :meth:`of` its shipped format."""
        return self.of(_SHIPPED[name])

    def of(self, shipped: QFormat) -> QFormat:
        """Shipped format ``shipped`` (one of ``formats``' objects) in these formats: its fraction bits, saturating
        at its word (sign included; the lowpass's: sign + ``lowpass_int_bits`` + fraction bits), in its shipped
        container."""
        frac, word = self.sweep_fields(shipped)
        f = getattr(self, frac) if frac is not None else shipped.frac_bits
        bits = (self.lowpass_word_bits if word == "lowpass_int_bits" else getattr(self, word) if word is not None
                else shipped.total_bits)
        return QFormat(bits - int(shipped.signed) - f, f, signed=shipped.signed, word_bits=shipped.word_bits)

    def code_q(self, adc_bits: int) -> QFormat:
        """The centred codes' and the calibration offsets' format (``centred_q``) in ``code_word_bits``."""
        base = centred_q(adc_bits)
        return QFormat(self.code_word_bits - 1 - base.frac_bits, base.frac_bits, word_bits=base.word_bits)

    @property
    def acc_q(self) -> QFormat:
        """a_v's format."""
        return self.q("acc_frac_bits")

    @property
    def position_q(self) -> QFormat:
        """The position accumulator: a_v's fraction bits in ``position_word_bits``."""
        return self.of(POSITION_Q)

    @property
    def position2_q(self) -> QFormat:
        """M2's position format."""
        return self.q("position2_frac_bits")

    @property
    def lowpass_q(self) -> QFormat:
        """The FIR outputs' format."""
        return self.q("lowpass_frac_bits")

    @property
    def lowpass_word_bits(self) -> int:
        """The lowpass outputs' word, where they saturate: sign + integer + fraction bits (shipped 19, in a
        24-bit RAM word)."""
        return 1 + self.lowpass_int_bits + self.lowpass_frac_bits

    def theory_bits(self) -> dict[str, int]:
        """The fraction bits the quantisation theory's arithmetic share takes
        (:func:`gaitlog.host.studies.quantisation_theory.arithmetic_sigma_m`'s keywords)."""
        return {"acc_frac_bits": self.acc_frac_bits, "lowpass_frac_bits": self.lowpass_frac_bits,
                "excursion_frac_bits": (self.excursion_frac_bits, self.excursion2_frac_bits),
                "step_frac_bits": self.step_frac_bits, "k_frac_bits": self.k_frac_bits,
                "k4_frac_bits": self.k4_frac_bits}

    def constants(self) -> dict[str, int]:
        """The kernel's compile-time integers these formats replace (names as in ``formats``)."""
        return {"F_ACC": self.acc_frac_bits, "F_POS": self.acc_frac_bits, "F_GRAV": self.gravity_frac_bits,
                "F_LP": self.lowpass_frac_bits, "W_LP": self.lowpass_word_bits,
                "F_POS2": self.position2_frac_bits,
                **{c: getattr(self, n) for n, c in _CONSTANT.items()},
                # the pendulum's argument keeps at most the product's own bits (2 l's and h's)
                "F_PARG": min(self.pendulum_arg_frac_bits, self.two_leg_frac_bits + self.excursion_frac_bits),
                "F_PARG2": min(self.pendulum_arg2_frac_bits, self.two_leg_frac_bits + self.excursion2_frac_bits),
                **{c: (getattr(self, n) if q.signed else -getattr(self, n))
                   for n, (q, _, c, _) in _WORDS.items() if c is not None}}


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


def _rounding_arithmetic(formats: KernelFormats, numba: types.ModuleType) -> types.ModuleType:
    """The arithmetic vocabulary of the fixed point (:data:`arithmetic.FIXED`) compiled with ``formats``' rounding
    constants, as a module the kernel's copy calls (``ar.mul`` ...): the same functions' code, other globals."""
    namespace = dict(vars(arithmetic))
    namespace.update(formats.rounding_constants())
    module = types.ModuleType(f"{arithmetic.__name__}[{formats.rounding_label()}]")
    for name, py in arithmetic.FIXED.items():
        fn = types.FunctionType(py.__code__, namespace, py.__name__, py.__defaults__, py.__closure__)
        setattr(module, name, numba.njit(cache=False)(fn))
    return module


def _variant_namespace(formats: KernelFormats) -> dict:
    """A copy of the kernel module's globals with ``formats``' constants, its rounding's arithmetic, and every
    kernel function re-bound to it as a numba dispatcher (compiled when first called or exported; with the shipped
    function's options: numba's runtime off but where it allocates)."""
    numba = load_numba()
    namespace = dict(vars(kernel))
    namespace.update(formats.constants())
    namespace["ar"] = _rounding_arithmetic(formats, numba)
    for name, py in _kernel_functions(vars(kernel)).items():
        fn = types.FunctionType(py.__code__, namespace, py.__name__, py.__defaults__, py.__closure__)
        fn.__qualname__ = f"{py.__qualname__}[{formats.label()}/{formats.rounding_label()}]"
        namespace[name] = numba.njit(cache=False, **jit_options(vars(kernel)[name]))(fn)
    return namespace


def compile_kernel(formats: KernelFormats) -> tuple[Callable, Callable, Callable]:
    """``process``, ``flush``, ``reset`` JIT-compiled now for ``formats`` (any set, the shipped one included: the
    tests check that this gives the kernel built ahead of time bit for bit); not kept (:func:`entry_points`).
    Fixed point only: the arithmetic is the fixed-point one, with ``formats``' rounding modes."""
    namespace = _variant_namespace(formats)
    return tuple(namespace[n] for n in _NAMES)


def cache_key(formats: KernelFormats) -> str:
    """A short digest of every field of ``formats``: the name of its compiled module in the compile cache."""
    text = ",".join(f"{f.name}={getattr(formats, f.name)}" for f in fields(formats))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def variant_folder(formats: KernelFormats) -> Path:
    """The compile cache's folder of ``formats``' module: beside the shipped kernel's (:func:`aot_kernel.aot_dir`,
    the same hash of the compiled sources), ``aot-<sources>-<formats>``."""
    shipped = aot_kernel.aot_dir()
    return shipped.with_name(f"{shipped.name}-{cache_key(formats)}")


def _cached_module(formats: KernelFormats) -> tuple[Callable, Callable, Callable] | None:
    """``formats``' entry points from the compile cache's module: loaded, else built (by this process, or by
    another one of this machine, waited for: module notes); None when it cannot be built or is turned off."""
    if not aot_kernel.enabled():
        return None
    key = cache_key(formats)
    names = tuple(f"{n}_fixed" for n in _NAMES)
    module = aot_kernel.build_or_wait(
        variant_folder(formats), module_name=f"{aot_kernel.MODULE_NAME}_{key}", names=names,
        exports=lambda: aot_kernel.kernel_exports(_variant_namespace(formats), ("fixed",)),
        what=f" for formats {formats.label()}, rounding {formats.rounding_label()}")
    return None if module is None else tuple(getattr(module, n) for n in names)


def entry_points(formats: KernelFormats) -> tuple[Callable, Callable, Callable]:
    """The fixed-point kernel's ``process``, ``flush``, ``reset`` compiled for ``formats`` (module notes).

    Raises ValueError for the shipped formats: they run the kernel built ahead of time.
    """
    if formats.compiled_shipped:
        raise ValueError("the shipped formats run the kernel built ahead of time (aot_kernel.entry_points)")
    with _LOCK:
        found = _VARIANTS.get(formats)
        if found is None:
            found = _cached_module(formats) or compile_kernel(formats)
            _VARIANTS[formats] = found
            while len(_VARIANTS) > MAX_VARIANTS:
                _VARIANTS.popitem(last=False)
        else:
            _VARIANTS.move_to_end(formats)
    return found
