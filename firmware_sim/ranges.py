"""Range collection and a data-type proposal for every fixed-point variable of the on-line step algorithm.

What the industrial fixed-point tools do in two passes (collect ranges, then propose data types), for the
firmware's own formats (:mod:`gaitlog.firmware_sim.algorithms.formats`, the shipped ones): run the fixed-point
algorithm over recordings, observe the values each variable takes, and report per variable its format, the
observed minimum and maximum (raw counts and real units), the headroom in bits, how often it sat at its word's
limit, and the smallest format that holds the observed range with a margin.

The kernel (:mod:`gaitlog.firmware_sim.algorithms.kernel`) is not changed: its results stay byte for byte the
same. What is observed, and how, is said per row (:data:`HOW`):

``state``
    The kernel's persistent state (:mod:`gaitlog.firmware_sim.algorithms.state`) read after every sample:
    every value a state variable takes (and a_v, the newest entry of the delay line).
``probe``
    Step 1 of the kernel recomputed on every sample by :func:`gaitlog.firmware_sim.algorithms.probe.calibrated_axes`
    (the kernel's own helper, checked against the kernel by the PIC tests); M2's c1 and c2 from the kernel's
    own ``_pass1`` run on the observed a_v of each step; or computed exactly (int64, no saturation) from
    observed values with the kernel's expression: the centred codes, gravity rounded to Q2.13, ``|g|^2`` and
    ``f·g - |g|^2``.
``record``
    The step records' lengths, excursions and M4's range (every value written).
``derived``
    Temporaries of a step's passes recomputed in int64 from the observed a_v, the records' windows and
    excursions with the kernel's formulas: M1's velocity and position accumulators, M2's corrected position
    p2, ``2 l h - h^2``, M4's square root, M5's ``K1 fs / N + K2`` before the record's unsigned word
    (:func:`m5_before_storing`). Not read from the kernel: a value beyond the word is counted where the kernel
    would saturate.
``constant``
    Configuration the kernel keeps (FIR weights, calibration, leg, K ...): the values configured.
``none``
    Not observed: temporaries the kernel does not expose (the FIR accumulator's partial sums). Their rows
    have no range.

A row's ``saturations`` counts the observed values at the word's limit (at either limit when signed, at the
top when unsigned: 0 is a common unsigned value), or beyond it for derived values (below 0 too, for an
unsigned word); the kernel's own counters
(saturations, wraps, divisions by zero of every primitive, not per variable) are in
:attr:`RangeReport.kernel_saturations` and beside it.

Examples
--------
A logger lying still, z up (nominal calibration): the calibrated axes are 0 and 1 g, gravity is 1 g from the
first sample on, a_v is 0:

>>> from gaitlog.protocol.steps import StepConfig
>>> alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=StepConfig(step_format=1, leg_length_m=0.9,
...                                                                         foot_length_m=0.2))
>>> c = RangeCollector(); c.add(alg, np.tile([512, 512, 768], (200, 1)), name="still")
>>> r = c.report(margin_bits=0)
>>> f, g = r.row("f (x, y, z)"), r.row("G2 (x, y, z)")
>>> (f.min_real, f.max_real), (g.min_real, g.max_real), r.row("a_v").max_raw, g.proposed
((0.0, 1.0), (0.0, 1.0), 0, 'Q1.29')
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from gaitlog.firmware_sim.algorithms import arithmetic as ar
from gaitlog.firmware_sim.algorithms import formats as fm
from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ
from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm, OnlineSteps
from gaitlog.firmware_sim.algorithms.probe import calibrated_axes
from gaitlog.firmware_sim.algorithms.state import AMP, G1, G2, MN, MX, PEND_Y, RAW_Y
from gaitlog.firmware_sim.fixedpoint import QFormat, new_counters
from gaitlog.protocol.steps import StepFlag

__all__ = ["HOW", "TRACKED", "Tracked", "VariableRange", "RangeReport", "RangeCollector", "m5_before_storing",
           "smallest_format"]

#: How a row's values are observed (module notes), in the table's order of trust.
HOW = ("state", "probe", "record", "derived", "constant", "none")


@dataclass(frozen=True)
class Tracked:
    """One variable: its name, the name of its format in ``formats`` (``CENTRED_Q``: ``centred_q(adc_bits)``),
    how it is observed (:data:`HOW`), its unit."""

    name: str
    format_name: str
    how: str
    unit: str


#: Every variable tracked, grouped by format, in the order of ``formats.__all__``; each format has a row.
TRACKED = (
    Tracked("centred codes c (x, y, z)", "CENTRED_Q", "probe", "counts"),
    Tracked("offsets (x, y, z)", "CENTRED_Q", "constant", "counts"),
    Tracked("f (x, y, z)", "ACC_Q", "probe", "g"),
    Tracked("g rounded (x, y, z)", "ACC_Q", "probe", "g"),
    Tracked("a_v", "ACC_Q", "state", "g"),
    Tracked("G1 (x, y, z)", "GRAVITY_Q", "state", "g"),
    Tracked("G2 (x, y, z)", "GRAVITY_Q", "state", "g"),
    Tracked("|g|^2", "ACC2_Q", "probe", "g^2"),
    Tracked("f.g - |g|^2", "ACC2_Q", "probe", "g^2"),
    Tracked("FIR weights", "KERNEL_Q", "constant", "1"),
    Tracked("FIR accumulator", "FIR_SUM_Q", "none", "g"),
    Tracked("MX", "LOWPASS_Q", "state", "g"),
    Tracked("MN", "LOWPASS_Q", "state", "g"),
    Tracked("PEND_Y", "LOWPASS_Q", "state", "g"),
    Tracked("RAW_Y", "LOWPASS_Q", "state", "g"),
    Tracked("AMP", "LOWPASS_Q", "state", "g"),
    Tracked("M4 range", "LOWPASS_Q", "record", "g"),
    Tracked("V (M1 pass)", "VELOCITY_Q", "derived", "2 g Ts"),
    Tracked("P (M1 pass)", "POSITION_Q", "derived", "4 g Ts^2"),
    Tracked("c1, c2 (M2 pass)", "POSITION2_Q", "probe", "4 g Ts^2"),
    Tracked("p2 (M2 pass)", "POSITION2_Q", "derived", "4 g Ts^2"),
    Tracked("h (M1)", "EXCURSION_Q", "record", "m"),
    Tracked("h (M2), h1 (M3)", "EXCURSION2_Q", "record", "m"),
    Tracked("leg, foot (stored)", "LENGTH_Q", "constant", "m"),
    Tracked("2 l, foot", "TWO_LENGTH_Q", "constant", "m"),
    Tracked("2 l h - h^2 (M1)", "PENDULUM_ARG_Q", "derived", "m^2"),
    Tracked("2 l h - h^2 (M2, M3)", "PENDULUM_ARG2_Q", "derived", "m^2"),
    *(Tracked(f"length M{i}", "STEP_Q", "record", "m") for i in range(1, 6)),
    Tracked("K1 fs / N + K2 (M5)", "STEP_Q", "derived", "m"),
    Tracked("K1, K2 (as used)", "K_Q", "constant", "1"),
    Tracked("K4 g0^p", "K4_Q", "constant", "1"),
    Tracked("sqrt(range) (M4)", "ROOT4_Q", "derived", "g^1/2"),
    Tracked("K1 fs, K2 (M5)", "M5_Q", "constant", "m"),
    Tracked("calibration mantissas", "MANTISSA_Q", "constant", "1"),
)
_BY_NAME = {t.name: t for t in TRACKED}


def _format(name: str, adc_bits: int) -> QFormat:
    return fm.centred_q(adc_bits) if name == "CENTRED_Q" else getattr(fm, name)


def _limits(q: QFormat) -> tuple[int, int]:
    """The raw limits the kernel saturates at: the format's value bits (Q2.16 saturates at 19 bits in 24)."""
    return q.min_raw, q.max_raw


def smallest_format(lo_raw: int, hi_raw: int, q: QFormat, margin_bits: int) -> tuple[int, int]:
    """The smallest format with ``q``'s fraction bits and signedness that holds ``[lo_raw, hi_raw]`` (raw counts
    of ``q``) magnified by ``2^margin_bits``: ``(integer bits, total bits)`` (integer bits may be negative, as
    ``EXCURSION2_Q``'s -2). A negative ``lo_raw`` of an unsigned ``q`` (a derived value below its word) needs a
    sign: the format proposed is then signed.

    >>> smallest_format(0, 1 << 29, fm.GRAVITY_Q, 0), smallest_format(0, 1 << 29, fm.GRAVITY_Q, 1)
    ((1, 31), (2, 32))
    >>> smallest_format(0, 6000, fm.STEP_Q, 1), smallest_format(-1, 0, fm.ACC_Q, 0)
    ((0, 14), (-13, 1))
    >>> smallest_format(-2000, 20000, fm.STEP_Q, 0)      # -0.12 .. 1.22 m: a sign and Q1.14
    (1, 16)
    """
    hi, lo = int(hi_raw) << margin_bits, int(lo_raw) << margin_bits
    signed = q.signed or lo < 0
    if signed:
        total = 1 + max(max(hi, 0).bit_length(), (-min(lo, 0) - 1).bit_length() if lo < 0 else 0)
    else:
        total = max(max(hi, 0).bit_length(), 1)
    return total - q.frac_bits - int(signed), total


def m5_before_storing(cfg_v: np.ndarray, durations_samples: np.ndarray) -> np.ndarray:
    """M5 of steps of ``durations_samples`` samples (records without a window, duration 0, left out) in
    ``STEP_Q``'s raw counts: the kernel's ``K1 fs / N + K2`` with its own primitives, but requantised into a
    32-bit word instead of the record's unsigned 16 bits, so a negative length (a calibrated ``K2 < 0`` and
    ``N > K1 fs / -K2``, which the kernel stores as 0 and counts as a saturation) stays negative.

    >>> from gaitlog.protocol.steps import StepConfig
    >>> alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=StepConfig(step_format=1, leg_length_m=0.9,
    ...                                                                         foot_length_m=0.2))
    >>> (m5_before_storing(alg.config.cfg_v, np.array([0, 25, 50])) * fm.STEP_Q.lsb).tolist()   # K = 1: 1 / T
    [2.0, 1.0]
    """
    cnt = new_counters()
    k1fs, k2 = int(cfg_v[kernel.CV_K1FS]), int(cfg_v[kernel.CV_K2M5])
    return np.array([ar.requant(ar.add(ar.div(k1fs, fm.F_M5, int(n), 0, fm.F_M5, fm.W32, cnt), k2, fm.W32, cnt),
                                fm.F_M5, fm.F_STEP, fm.W32, cnt)
                     for n in np.asarray(durations_samples, np.int64) if n > 0], np.int64)


@dataclass(frozen=True)
class VariableRange:
    """One row of the report: a variable, its format and what was observed (None: nothing observed).

    ``headroom_bits`` is ``log2`` of the format's limit over the observed magnitude, on the tighter side;
    ``proposed`` the smallest format with the same fraction bits holding the range with the report's margin,
    ``proposed_bits`` its width (``format_bits`` is the shipped one's value bits, ``word_bits`` its RAM word).
    """

    variable: str
    format_name: str
    format: str
    how: str
    unit: str
    frac_bits: int
    signed: bool
    format_bits: int
    word_bits: int
    n_values: int
    min_raw: int | None
    max_raw: int | None
    min_real: float | None
    max_real: float | None
    headroom_bits: float | None
    saturations: int
    proposed: str | None
    proposed_bits: int | None


def _headroom_bits(q: QFormat, lo: int, hi: int) -> float | None:
    sides = [q.max_raw / hi] if hi > 0 else []
    if lo < 0 and q.signed:
        sides.append(-q.min_raw / -lo)
    return round(math.log2(min(sides)), 2) if sides else None


def _q_name(int_bits: int, frac_bits: int, signed: bool) -> str:
    return f"{'' if signed else 'U'}Q{int_bits}.{frac_bits}"


@dataclass(frozen=True)
class RangeReport:
    """Ranges of every tracked variable over the sources, and the kernel's counters.

    Attributes
    ----------
    rows
        One :class:`VariableRange` per :data:`TRACKED` variable, in that order.
    margin_bits
        The margin of the proposals: the observed range times ``2^margin_bits`` must fit.
    sources
        Names of the recordings and walks fed.
    n_samples, n_steps
        Samples fed and step records written.
    kernel_saturations, kernel_wraps, kernel_divisions_by_zero
        The kernel's own counters (every primitive; the sticky flag's source), summed over the sources.
    saturated_records
        Records with the SATURATED flag.
    """

    rows: tuple[VariableRange, ...]
    margin_bits: int
    sources: tuple[str, ...]
    n_samples: int
    n_steps: int
    kernel_saturations: int
    kernel_wraps: int
    kernel_divisions_by_zero: int
    saturated_records: int

    def row(self, variable: str) -> VariableRange:
        """The row of ``variable`` (a :data:`TRACKED` name)."""
        for r in self.rows:
            if r.variable == variable:
                return r
        raise KeyError(variable)

    def tightest(self) -> VariableRange | None:
        """The observed row with the least headroom (None when nothing was observed)."""
        seen = [r for r in self.rows if r.headroom_bits is not None]
        return min(seen, key=lambda r: r.headroom_bits) if seen else None

    def saturated(self) -> list[VariableRange]:
        """Rows with values at (or, derived, beyond) their word's limit."""
        return [r for r in self.rows if r.saturations]

    def headline(self) -> str:
        """One line: saturations and the tightest headroom."""
        sat = self.saturated()
        t = self.tightest()
        said = ("no variable at its limit" if not sat else
                "at the limit: " + ", ".join(f"{r.variable} ({r.format_name}) {r.saturations}x" for r in sat))
        tight = f"; tightest headroom {t.headroom_bits:g} bits: {t.variable} ({t.format_name})" if t else ""
        return (f"{len(self.sources)} source(s), {self.n_samples} samples, {self.n_steps} steps; kernel counted "
                f"{self.kernel_saturations} saturation(s), {self.kernel_wraps} wrap(s), "
                f"{self.kernel_divisions_by_zero} division(s) by zero; {said}{tight}")

    def to_dict(self) -> dict:
        """JSON-ready: the rows (the table's columns, with units) and the totals."""
        out = {k: v for k, v in asdict(self).items() if k != "rows"}
        out["sources"] = list(self.sources)
        out["headline"] = self.headline()
        out["rows"] = [asdict(r) for r in self.rows]
        return out

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON (a row with nothing observed, or only zeros, has null headroom)."""
        return json.dumps(self.to_dict(), indent=2)

    def format_table(self) -> str:
        """The table: one line per variable, then the headline and the key to the ``seen`` column."""
        head = (f"{'format':<16} {'variable':<26} {'seen':<8} {'Q':<12} {'min raw':>12} {'max raw':>12} "
                f"{'min':>11} {'max':>11} {'unit':<8} {'headroom':>8} {'sat':>5} {'proposed':<10} {'bits':>4}")
        lines = [head, "-" * len(head)]
        for r in self.rows:
            cell = (lambda v, f: "-" if v is None else format(v, f))
            lines.append(f"{r.format_name:<16} {r.variable:<26} {r.how:<8} {r.format:<12} "
                         f"{cell(r.min_raw, 'd'):>12} {cell(r.max_raw, 'd'):>12} {cell(r.min_real, '.5g'):>11} "
                         f"{cell(r.max_real, '.5g'):>11} {r.unit:<8} {cell(r.headroom_bits, '.2f'):>8} "
                         f"{r.saturations:>5} {r.proposed or '-':<10} {cell(r.proposed_bits, 'd'):>4}")
        lines += ["", self.headline(),
                  f"proposed: the smallest format with the same fraction bits holding the range x 2^{self.margin_bits}"
                  " (--margin-bits); headroom: log2(limit / observed), tighter side",
                  "seen: state = read after every sample; probe = the kernel's step recomputed on every sample; "
                  "record = step records; derived = recomputed from a_v and the records; constant = configured; "
                  "none = not observed; lengths, K and M5's constants are the raw values (K = 1) where the "
                  "logger's K is not calibrated"]
        return "\n".join(lines)


class RangeCollector:
    """Feeds recordings to the fixed-point algorithm and keeps each tracked variable's extremes.

    Use :meth:`add` per recording (or walk), then :meth:`report`. ``words`` (a format set that differs from the
    shipped one in words only: :class:`~gaitlog.firmware_sim.algorithms.format_kernel.KernelFormats`) reports each
    row against its format in those words: the shipped run's values beyond a narrower word are counted as
    ``saturations`` (what that word would clip where the value is stored), the headroom is the narrower word's.
    """

    def __init__(self, words: KernelFormats | None = None) -> None:
        if words is not None and any(getattr(words, n) != getattr(KernelFormats(), n)
                                     for n in KernelFormats.field_names()):
            raise ValueError(f"ranges take other words only, not other fraction bits (the run is the shipped "
                             f"one's), got {words.label()}")
        self._words = words
        self._lo: dict[str, int] = {}
        self._hi: dict[str, int] = {}
        self._n: dict[str, int] = {}
        self._sat: dict[str, int] = {}
        self._adc_bits = 10
        self._sources: list[str] = []
        self._samples = 0
        self._steps = 0
        self._counts = np.zeros(3, np.int64)
        self._saturated_records = 0

    def _see(self, name: str, values: np.ndarray) -> None:
        v = np.asarray(values, np.int64).reshape(-1)
        if v.size == 0:
            return
        q = self._format(_BY_NAME[name].format_name)
        lo_lim, hi_lim = _limits(q)
        lo, hi = int(v.min()), int(v.max())
        self._lo[name] = min(lo, self._lo.get(name, lo))
        self._hi[name] = max(hi, self._hi.get(name, hi))
        self._n[name] = self._n.get(name, 0) + int(v.size)
        if self._words is not None:             # what the narrower word clips
            at = (v > hi_lim) | (v < lo_lim)
        else:                                   # what sat at the shipped word's limit
            at = v >= hi_lim
            at |= (v <= lo_lim) if q.signed else (v < 0)
        self._sat[name] = self._sat.get(name, 0) + int(np.count_nonzero(at))

    def add(self, algorithm: OnlineStepAlgorithm, codes: np.ndarray, *, segments: Sequence[tuple[int, int]] = (),
            name: str = "") -> None:
        """Run ``algorithm`` (fixed point, shipped formats) over ``codes`` and observe every tracked variable.

        Parameters
        ----------
        codes
            ``(n, 3)`` ADC codes.
        segments
            ``[a, b)`` row ranges fed as runs (each from START to STOP); default the whole array as one run.
        name
            The source's name in the report.
        """
        if algorithm.arithmetic != "fixed" or not algorithm.config.formats.shipped:
            raise ValueError("ranges are collected for the fixed-point algorithm with the shipped formats")
        c = np.asarray(codes, np.int64).reshape(-1, 3)
        self._adc_bits = algorithm.config.adc_bits
        before = np.array([algorithm.saturations, algorithm.wraps, algorithm.divisions_by_zero], np.int64)
        for a, b in (segments or [(0, c.shape[0])]):
            if b > a:
                self._run(algorithm, c[a:b])
        self._counts += np.array([algorithm.saturations, algorithm.wraps, algorithm.divisions_by_zero]) - before
        self._constants(algorithm)
        self._sources.append(name or f"source {len(self._sources) + 1}")

    def _run(self, alg: OnlineStepAlgorithm, codes: np.ndarray) -> None:
        """One run, sample by sample: the state after each; then the records' and derived values."""
        n = codes.shape[0]
        values = np.zeros((n, alg.state_values().size), np.int64)
        av = np.zeros(n, np.int64)
        parts = []
        alg.reset()
        for i in range(n):
            parts.append(alg.feed(codes[i:i + 1]))
            values[i] = alg.state_values()
            av[i] = alg.newest_vertical_acceleration()
        parts.append(alg.flush())
        steps = OnlineSteps.concatenate(parts)
        self._samples += n
        self._steps += steps.n_steps
        self._saturated_records += int(np.count_nonzero(steps.flags & int(StepFlag.SATURATED)))
        self._front(alg, codes, values[:, G2:G2 + 3])
        self._see("a_v", av)
        self._see("G1 (x, y, z)", values[:, G1:G1 + 3])
        self._see("G2 (x, y, z)", values[:, G2:G2 + 3])
        for slot, name in ((MX, "MX"), (MN, "MN"), (PEND_Y, "PEND_Y"), (RAW_Y, "RAW_Y"), (AMP, "AMP")):
            self._see(name, values[:, slot])
        self._records(alg, steps, av)

    def _front(self, alg: OnlineStepAlgorithm, codes: np.ndarray, g2: np.ndarray) -> None:
        """Steps 1-3 (calibration, gravity rounded, a_v's numerator) on every sample."""
        cfg = alg.config
        cf = int(cfg.cfg_i[kernel.CI_CODE_FRAC])
        off = cfg.cfg_v[kernel.CV_OFF:kernel.CV_OFF + 3]
        self._see("centred codes c (x, y, z)", np.clip(codes << cf, -32768, 32767) - off)
        cal = CalibrationQ(off.copy(), cfg.cfg_v[kernel.CV_M:kernel.CV_M + 9].reshape(3, 3).copy(),
                           int(cfg.cfg_i[kernel.CI_MANT_FRAC]), cfg.adc_bits)
        f = calibrated_axes(codes, cal)
        shift = fm.F_GRAV - fm.F_ACC
        g = np.clip((g2 + (1 << (shift - 1))) >> shift, -32768, 32767)   # requant half up, 16-bit
        self._see("f (x, y, z)", f)
        self._see("g rounded (x, y, z)", g)
        norm2 = (g * g).sum(axis=1)
        self._see("|g|^2", norm2)
        self._see("f.g - |g|^2", (f * g).sum(axis=1) - norm2)

    def _records(self, alg: OnlineStepAlgorithm, steps: OnlineSteps, av: np.ndarray) -> None:
        """The records' values and the step passes' temporaries derived from them."""
        lengths, extras = np.asarray(steps.lengths, np.int64), np.asarray(steps.extras, np.int64)
        for i in range(5):
            self._see(f"length M{i + 1}", lengths[:, i])
        self._see("h (M1)", extras[:, 0])
        self._see("h (M2), h1 (M3)", extras[:, 1:3])
        self._see("M4 range", extras[:, 3])
        rng = np.maximum(extras[:, 3], 0)
        self._see("sqrt(range) (M4)", np.rint(np.sqrt(rng.astype(np.float64) * 2.0 ** (2 * fm.F_ROOT - fm.F_LP))))
        self._see("K1 fs / N + K2 (M5)", m5_before_storing(alg.config.cfg_v, steps.duration))
        two_leg = int(alg.config.cfg_v[kernel.CV_TWO_LEG])
        for name, h, f_h in (("2 l h - h^2 (M1)", extras[:, 0], fm.F_EXC),
                             ("2 l h - h^2 (M2, M3)", extras[:, 1:3], fm.F_EXC2)):
            s = f_h - fm.F_TWO_LEN
            x = two_leg * h - ((h * h + (1 << (s - 1))) >> s)
            self._see(name, x[x >= 0])                     # x < 0: IMPOSSIBLE, a sign test before the root
        windows = [(int(e - d), int(e)) for e, d in zip(steps.end, steps.duration) if d > 0 and e - d >= 0]
        cfg_i = alg.config.cfg_i.copy()
        cfg_i[kernel.CI_SCRATCH] = max(av.size, 1)          # the run's a_v as the scratch ring, never wrapped
        for s, e in windows:
            self._passes(av, s, e, cfg_i)

    def _passes(self, av: np.ndarray, s: int, e: int, cfg_i: np.ndarray) -> None:
        """A step's two passes: M1's V and P, and M2's p2, derived (int64, the kernel's increments); c1 and c2
        from the kernel's own ``_pass1`` on the observed a_v."""
        vel = np.cumsum(av[s + 1:e + 1] + av[s:e])
        two = vel + np.r_[0, vel[:-1]]
        self._see("V (M1 pass)", vel)
        self._see("P (M1 pass)", np.cumsum(two))
        _, c1, c2 = kernel._pass1(s, e, cfg_i, av, new_counters())
        self._see("c1, c2 (M2 pass)", [c1, c2])
        ramp = 2 * c1 + 4 * c1 * np.arange(vel.size)       # 2 c1 (2 tau - 1)
        self._see("p2 (M2 pass)", np.cumsum((two << (fm.F_POS2 - fm.F_POS)) - c2 + ramp))

    def _constants(self, alg: OnlineStepAlgorithm) -> None:
        v = alg.config.cfg_v
        raw = alg.config.step_config.raw
        self._see("offsets (x, y, z)", v[kernel.CV_OFF:kernel.CV_OFF + 3])
        self._see("calibration mantissas", v[kernel.CV_M:kernel.CV_M + 9])
        self._see("FIR weights", v[kernel.CV_W3:])
        self._see("leg, foot (stored)", [raw["leg_length_q15"], raw["foot_length_q15"]])
        self._see("2 l, foot", v[[kernel.CV_TWO_LEG, kernel.CV_FOOT]])
        self._see("K1, K2 (as used)", v[[kernel.CV_K1, kernel.CV_K2]])     # 1 when K is not calibrated
        self._see("K4 g0^p", v[[kernel.CV_K4]])
        self._see("K1 fs, K2 (M5)", v[[kernel.CV_K1FS, kernel.CV_K2M5]])

    def _format(self, format_name: str) -> QFormat:
        """A row's format: the shipped one, or in :attr:`words`' word."""
        q = _format(format_name, self._adc_bits)
        if self._words is None:
            return q
        return self._words.code_q(self._adc_bits) if format_name == "CENTRED_Q" else self._words.of(q)

    def _row(self, t: Tracked, margin_bits: int) -> VariableRange:
        q = self._format(t.format_name)
        common = dict(variable=t.name, format_name=t.format_name, format=str(q), how=t.how, unit=t.unit,
                      frac_bits=q.frac_bits, signed=q.signed, format_bits=q.total_bits, word_bits=q.word_bits,
                      n_values=self._n.get(t.name, 0), saturations=self._sat.get(t.name, 0))
        if t.name not in self._lo:
            return VariableRange(**common, min_raw=None, max_raw=None, min_real=None, max_real=None,
                                 headroom_bits=None, proposed=None, proposed_bits=None)
        lo, hi = self._lo[t.name], self._hi[t.name]
        m, total = smallest_format(lo, hi, q, margin_bits)
        return VariableRange(**common, min_raw=lo, max_raw=hi, min_real=lo * q.lsb, max_real=hi * q.lsb,
                             headroom_bits=_headroom_bits(q, lo, hi),
                             proposed=_q_name(m, q.frac_bits, q.signed or lo < 0),
                             proposed_bits=total)

    def report(self, *, margin_bits: int = 1) -> RangeReport:
        """The ranges so far, with proposals holding ``2^margin_bits`` times the observed range."""
        if not 0 <= margin_bits <= 16:
            raise ValueError(f"margin_bits must be 0 .. 16, got {margin_bits}")
        return RangeReport(tuple(self._row(t, margin_bits) for t in TRACKED), int(margin_bits),
                           tuple(self._sources), self._samples, self._steps, int(self._counts[0]),
                           int(self._counts[1]), int(self._counts[2]), self._saturated_records)
