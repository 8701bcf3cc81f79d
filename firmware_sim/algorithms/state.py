"""The on-line step algorithm's RAM: every variable it keeps, declared once, with its PIC word.

The compiled kernel (:mod:`gaitlog.firmware_sim.algorithms.kernel`) keeps its persistent state in nothing but the
arrays laid out here: ``values`` (arithmetic values: ``int64`` raw fixed point or ``float64``), ``indices``
(sample indices, counters, flags: integers in both arithmetics), the a_v delay line and the ring of recent
step durations. The slot constants below are what the kernel indexes with. Its temporaries are the local
variables of the kernel's functions: :data:`FRAMES` gives each one its PIC word (0 for what needs no RAM
of its own: a constant, an alias of a state slot, an operand consumed by the next primitive, which lives in
the maths routines' registers, or the emulator's own bookkeeping) and :data:`CALLS` the call graph, so the
temporaries take the largest sum of frames along a call chain. The RAM the algorithm needs on the
PIC16F877 is :func:`ram_bytes` of these declarations — the implemented state, not a table written beside
it: ``tests/firmware_sim/test_online_state.py`` checks that every local and argument of every kernel
function is declared here (and nothing else), that the call graph is the code's, and that a walk writes
every persistent slot and nothing outside them.

Widths are the PIC words: sample indices are 16-bit (:data:`INDEX_BITS`), filter outputs 24-bit (Q2.16),
accumulators 32-bit. Indices wrap at 65,536 as the PIC's do: the kernel keeps them modulo :data:`INDEX_MODULUS`
and compares them only through :func:`since`, the 16-bit difference read as signed (exact while the two are
less than 2^15 samples apart, which every difference the algorithm takes is). What depends on the run's age
(the gravity warm-up, the filters' first output) tests ``N`` only while ``FLAGS`` lacks ``F_OLD``, set once the
run is 2^15 samples old. The firmware's own
variables (page buffer, UART, header counters, maths registers ...) are declared in
:mod:`gaitlog.firmware_sim.budget`, which adds them up against the 368 bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Variable", "INDEX_BITS", "INDEX_MODULUS", "INDEX_MASK", "INDEX_HALF", "since", "VALUE_SLOTS",
           "INDEX_SLOTS", "N_VALUES", "N_INDICES", "FRAMES", "CALLS", "variables", "persistent_bytes",
           "temporaries_bytes", "ram_bytes", "WORD_OF"]


#: Width of a sample index or sample counter on the PIC (``N``, ``MXPOS``, ``PEND``, ``LAST``, ``RAW`` and the
#: kernel's index temporaries: 2-byte words).
INDEX_BITS = 16
INDEX_MODULUS = 1 << INDEX_BITS
INDEX_MASK = INDEX_MODULUS - 1
INDEX_HALF = INDEX_MODULUS >> 1


def since(a: int, b: int) -> int:
    """``a - b`` as the PIC computes it: the 16-bit difference read as signed, exact while the true difference
    lies in ``[-2^15, 2^15)`` (compiled into the kernel).

    >>> since(5, 65530), since(65530, 5), since(300, 200)
    (11, -11, 100)
    """
    return ((a - b + INDEX_HALF) & INDEX_MASK) - INDEX_HALF


@dataclass(frozen=True)
class Variable:
    """One declared variable: name, number of words, bytes per word, where it lives, what it is for."""

    name: str
    count: int
    word_bytes: int
    kind: str          # "value", "index", "line", "ring"
    note: str

    @property
    def bytes(self) -> int:
        """RAM taken."""
        return self.count * self.word_bytes


# (slot name, count, word bytes, note); the order fixes the slot numbers
_VALUES = (
    ("G1", 3, 4, "gravity, first exponential stage, x y z (Q2.29)"),
    ("G2", 3, 4, "gravity, second stage (Q2.29)"),
    ("MX", 1, 3, ("peak detector: highest 3 Hz value since the last trough (Q2.16); while looking for a "
                  "trough, the highest since it or the last weak peak (the stop rule)")),
    ("MN", 1, 3, "peak detector: lowest 3 Hz value since the last peak (Q2.16)"),
    ("PEND_Y", 1, 3, "3 Hz value of the pending foot-flat"),
    ("RAW_Y", 1, 3, "3 Hz value of the last peak of the step-duration stream"),
    ("AMP", 1, 3, "recent step amplitude: exponential mean of the confirmed peaks' rises (Q2.16)"),
)
_INDEX_BYTES = INDEX_BITS // 8
_INDICES = (
    ("N", 1, _INDEX_BYTES, "samples since the run started (low 16 bits)"),
    ("LINE_POS", 1, 1, "write position in the a_v delay line"),
    ("FLAGS", 1, 1, "bits: looking for a peak, pending valid, last foot-flat valid, raw peak valid, "
              "amplitude valid, pending is a weak stop step, last is one, the run is 2^15 samples old"),
    ("MXPOS", 1, _INDEX_BYTES, "index of MX"),
    ("PEND", 1, _INDEX_BYTES, "index of the pending foot-flat"),
    ("LAST", 1, _INDEX_BYTES, "index of the last final foot-flat"),
    ("RAW", 1, _INDEX_BYTES, "index of the last peak of the step-duration stream"),
    ("N_DUR", 1, 1, "step durations in the ring (saturates at its length)"),
    ("DUR_POS", 1, 1, "write position in the duration ring"),
    ("DIST", 1, 1, "current minimum foot-flat distance, samples"),
)


def _slots(spec: tuple) -> dict[str, int]:
    out, pos = {}, 0
    for name, count, _, _ in spec:
        out[name] = pos
        pos += count
    return out


#: Slot of each value variable in the ``values`` array.
VALUE_SLOTS = _slots(_VALUES)
#: Slot of each index variable in the ``indices`` array.
INDEX_SLOTS = _slots(_INDICES)
N_VALUES = sum(c for _, c, _, _ in _VALUES)
N_INDICES = sum(c for _, c, _, _ in _INDICES)

# the kernel's slot constants (module-level integers: compiled in as constants)
G1, G2, MX, MN, PEND_Y, RAW_Y, AMP = (VALUE_SLOTS[n] for n, *_ in _VALUES)
N, LINE_POS, FLAGS, MXPOS, PEND, LAST, RAW, N_DUR, DUR_POS, DIST = (INDEX_SLOTS[n] for n, *_ in _INDICES)

#: Bits of ``FLAGS``.
F_LOOK_MAX, F_PEND, F_LAST, F_RAW, F_AMP, F_PEND_WEAK, F_LAST_WEAK, F_OLD = 1, 2, 4, 8, 16, 32, 64, 128


#: Arguments and locals of the kernel's functions: name -> (bytes on the PIC, why). Array arguments (the
#: state, configuration and output arrays, the counters) are fixed RAM areas or the EEPROM and are left out.
FRAMES: dict[str, dict[str, tuple[int, str]]] = {
    "process": {"k": (0, "records written: the step store's write index, in the header copy"),
                "row": (0, "the emulator's loop over a block; the firmware runs one sample per interrupt")},
    "_sample": {"cx": (0, "in the page buffer"), "cy": (0, "in the page buffer"), "cz": (0, "in the page buffer"),
                "k": (0, "the step store's write index"), "m": (2, "index of the newest filter output"),
                "y": (3, "its 3 Hz value, Q2.16"), "ready": (0, "a branch: the filters have an output")},
    "_weak_peak": {"y": (0, "alias of the caller's y"), "m": (0, "alias of the caller's m")},
    "_stop_candidate": {},
    "_prominence": {"scaled": (0, "fraction · AMP: the product in the maths registers, consumed by the caller's "
                                  "comparison")},
    "_front": {
        "cx": (0, "in the page buffer"), "cy": (0, "in the page buffer"), "cz": (0, "in the page buffer"),
        "r3": (0, "constant"), "n": (0, "alias of N"),
        "c0": (2, "centred code x, Q10.5"), "c1": (2, "centred code y"), "c2": (2, "centred code z"),
        "fx": (2, "specific force x, Q2.13"), "fy": (2, "specific force y"), "fz": (2, "specific force z"),
        "warm": (1, "gravity shift while the run is young"), "axis": (1, "loop counter"),
        "gx": (2, "gravity x rounded to Q2.13"), "gy": (2, "gravity y"), "gz": (2, "gravity z"),
        "norm2": (4, "|g|^2, Q5.26"), "gn": (2, "|g|, Q2.13"), "av": (2, "a_v, Q2.13"),
        "centre": (1, "delay-line position of the FIR centre"), "young": (0, "bit of FLAGS"),
    },
    "_calibrated": {"row": (0, "unrolled: three copies"), "c0": (0, "alias"), "c1": (0, "alias"),
                    "c2": (0, "alias"), "mf": (0, "constant"), "cf": (0, "constant"), "acc": (4, "row sum, 32-bit")},
    "_fir": {"centre": (0, "alias"), "length": (0, "constant"), "w0": (0, "constant"), "r": (0, "constant"),
             "acc": (4, "FIR sum, Q4.27"), "tap": (1, "loop counter"), "pair": (0, "operand of the next multiply")},
    "_confirmed": {"p": (2, "index of the confirmed peak"), "yp": (3, "its 3 Hz value"), "m": (0, "alias"),
                   "k": (0, "the step store's write index")},
    "_median_twice": {"n": (0, "alias of N_DUR"), "d": (-1, "an insertion-sorted copy of the duration ring")},
    "_finalise": {
        "e": (2, "index of the final foot-flat"), "m": (0, "alias"), "k": (0, "the step store's write index"),
        "zero": (0, "constant"), "flags": (1, "the record's flags"), "s": (2, "window start (previous foot-flat)"),
        "hs": (2, "heel-strike index"), "to": (2, "toe-off index"), "hs3": (2, "M3's heel-strike"),
        "l1": (2, "M1 length, UQ2.14 (the record's)"), "l2": (2, "M2"), "l3": (2, "M3"), "l4": (2, "M4"),
        "l5": (2, "M5"), "c": (0, "the emulator's output loop"), "span": (4, "position range"),
        "c1": (4, "M2 c1, Q.17"), "c2": (4, "M2 c2, Q.17 per sample"), "length": (2, "pendulum length, UQ2.14; then M4's roots of the range, UQ1.15"),
        "bad": (0, "bit of flags (IMPOSSIBLE)"), "span3": (4, "M3 position range"),
    },
    "_heel_strike": {"e": (0, "alias"), "m": (0, "alias"), "young": (0, "bit of FLAGS"),
                     "lo": (2, "search start"), "band": (3, "the impact band at j, Q2.16"),
                     "hi": (2, "search end"), "best": (2, "impact index"), "peak": (3, "impact value, Q2.16"),
                     "j": (2, "loop index")},
    "_toe_off": {"s": (0, "alias"), "m": (0, "alias"), "j": (2, "loop index"), "prev": (3, "d10 at j - 1"),
                 "cur": (3, "d10 at j"), "nxt": (3, "d10 at j + 1")},
    "_range": {"s": (0, "alias"), "e": (0, "alias"), "y_max": (3, "3 Hz maximum"),
               "y_min": (3, "3 Hz minimum"), "j": (2, "loop index"), "y": (3, "y3 at j")},
    "_fir_scratch": {"j": (0, "alias"), "w0": (0, "constant"), "r": (0, "constant")},
    "_band": {"j": (0, "alias"), "d10": (3, "d10 at j, while d5 is evaluated")},
    "_pass1": {"s": (0, "alias"), "e": (0, "alias"), "size": (0, "constant"), "vel": (4, "velocity accumulator"),
               "pos": (4, "position accumulator"), "p_max": (4, "M1 maximum"), "p_min": (4, "M1 minimum"),
               "j": (2, "loop index"), "v_new": (4, "next velocity"), "c1": (0, "returned in the caller's c1"),
               "prev": (0, "the emulator's ring index of j - 1 (the EEPROM's sequential read)"),
               "cur": (0, "the emulator's ring index of j"),
               "c2": (0, "returned in the caller's c2")},
    "_pass2": {"s": (0, "alias"), "e": (0, "alias"), "to": (0, "alias"), "hs3": (0, "alias"), "c1": (0, "alias"),
               "c2": (0, "alias"), "size": (0, "constant"), "vel": (4, "velocity accumulator"),
               "q": (4, "M2 position p2"), "q_max": (4, "M2 maximum"), "q_min": (4, "M2 minimum"),
               "s_max": (4, "M3 maximum"), "s_min": (4, "M3 minimum"), "ramp": (4, "2 c1 (2 tau - 1)"),
               "ramp_step": (4, "4 c1"), "seen": (0, "bit of the caller's flags"), "j": (2, "loop index"),
               "v_new": (4, "next velocity"), "dp": (0, "operand of the next addition"),
               "prev": (0, "the emulator's ring index of j - 1 (the EEPROM's sequential read)"),
               "cur": (0, "the emulator's ring index of j")},
    "_excursion": {"span": (0, "operand"), "f_pos": (0, "constant"), "shift": (0, "constant"), "f_h": (0, "constant"),
                   "w_h": (0, "constant"), "s16": (0, "operand of the next multiply")},
    "_pendulum": {"h": (0, "alias of the excursion"), "f_h": (0, "constant"), "f_arg": (0, "constant"),
                  "w_arg": (0, "constant"), "lh2": (4, "2 l h, 32-bit"),
                  "hh": (0, "operand"), "x": (4, "2 l h - h^2"), "half": (0, "operand")},
    "_read_cost": {"records": (0, "the emulator's I2C accounting"), "record_bytes": (0, "constant")},
    "_scratch_tail": {"n": (0, "alias of N"), "k": (0, "the step store's write index")},
    "flush": {"k": (0, "the step store's write index")},
    "reset": {},
}

#: Which kernel function calls which (the frames of a call chain are live together).
CALLS: dict[str, tuple[str, ...]] = {
    "process": ("_sample",),
    "_sample": ("_front", "_finalise", "_confirmed", "_prominence", "_weak_peak", "_stop_candidate"),
    "_weak_peak": ("_stop_candidate",),
    "_stop_candidate": (),
    "_prominence": (),
    "_front": ("_calibrated", "_fir"),
    "_calibrated": (),
    "_fir": (),
    "_confirmed": ("_median_twice", "_finalise"),
    "_median_twice": (),
    "_finalise": ("_scratch_tail", "_heel_strike", "_toe_off", "_pass1", "_excursion", "_pendulum", "_pass2",
                  "_range"),
    "_heel_strike": ("_band",),
    "_toe_off": ("_fir_scratch",),
    "_range": ("_fir_scratch",),
    "_fir_scratch": ("_read_cost", "_fir"),
    "_band": ("_read_cost", "_fir"),
    "_pass1": ("_read_cost",),
    "_pass2": ("_read_cost",),
    "_excursion": (),
    "_pendulum": (),
    "_read_cost": (),
    "_scratch_tail": (),
    "flush": ("_scratch_tail", "_finalise"),
    "reset": (),
}


def _frame_bytes(name: str, median_steps: int) -> int:
    return sum(median_steps if b < 0 else b for b, _ in FRAMES[name].values())


def temporaries_bytes(*, median_steps: int, entry: str = "process") -> int:
    """RAM of the temporaries: the largest sum of frames along a call chain from ``entry``.

    >>> temporaries_bytes(median_steps=7)
    87
    """
    below = max((temporaries_bytes(median_steps=median_steps, entry=c) for c in CALLS[entry]), default=0)
    return _frame_bytes(entry, median_steps) + below


#: The word each value variable and the delay line are kept in, as the name of a format set's attribute
#: (:class:`gaitlog.firmware_sim.algorithms.format_kernel.KernelFormats`, bits where the values saturate): a
#: narrower word takes ``ceil(bits / 8)`` bytes (the shipped 32, 19 and 16 bits: the 4, 3 and 2 above).
WORD_OF = {"G1": "gravity_word_bits", "G2": "gravity_word_bits", "MX": "lowpass_word_bits",
           "MN": "lowpass_word_bits", "PEND_Y": "lowpass_word_bits", "RAW_Y": "lowpass_word_bits",
           "AMP": "lowpass_word_bits", "LINE": "acc_word_bits"}


def persistent_bytes(*, line_length: int, median_steps: int, formats: object = None) -> int:
    """RAM of the state kept between samples (``formats``: as :func:`variables`)."""
    return sum(v.bytes for v in variables(line_length=line_length, median_steps=median_steps, formats=formats))


def variables(*, line_length: int, median_steps: int, formats: object = None) -> list[Variable]:
    """Every variable with its size, for a delay line of ``line_length`` a_v samples (``2 r3 + 1``) and a
    ring of ``median_steps`` durations; with ``formats`` (a format set: an object with the attributes of
    :data:`WORD_OF`) the value variables and the line in its words' whole bytes."""
    def word_bytes(name: str, shipped: int) -> int:
        return shipped if formats is None or name not in WORD_OF else -(-getattr(formats, WORD_OF[name]) // 8)

    out = [Variable(n, c, word_bytes(n, b), "value", note) for n, c, b, note in _VALUES]
    out += [Variable(n, c, b, "index", note) for n, c, b, note in _INDICES]
    out.append(Variable("LINE", line_length, word_bytes("LINE", 2), "line",
                        "a_v delay line of the centred FIR filters (Q2.13)"))
    out.append(Variable("DURATIONS", median_steps, 1, "ring", "recent peak intervals, samples"))
    return out


def ram_bytes(*, line_length: int, median_steps: int) -> int:
    """RAM of the algorithm on the PIC: its persistent state plus its temporaries.

    >>> ram_bytes(line_length=19, median_steps=7)
    186
    """
    return (persistent_bytes(line_length=line_length, median_steps=median_steps)
            + temporaries_bytes(median_steps=median_steps))
