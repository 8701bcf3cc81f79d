"""The cycle and memory budget of the firmware's assembly part, measured on the chip (gpsim) beside the model.

:func:`chip_budget` runs ``logger.asm`` in gpsim on a walk's codes (:class:`~.gpsim_logger.PicLogger`: the
sampling interrupt and the whole on-line algorithm, steps 1-5 with the step record) and prices the same samples
with the model (:func:`gaitlog.firmware_sim.algorithms.probe.algorithm_operation_counts` at
:data:`gaitlog.firmware_sim.budget.MEAN_CYCLES`; the interrupt's parts of
:func:`gaitlog.firmware_sim.budget.logging_cycles`). Each part gets the measured cycles per sample (mean, 99th
percentile, worst), the model's estimate and the model's error per sample; each step record, its sample's step-5
cycles measured and estimated; the backlog; RAM and program words from gpasm's listing
(:func:`~.gpsim_logger.memory_map`). Without gputils/gpsim (``measured`` False) only the model's estimates are
filled in. The sample pages' I2C write and the UART stay estimates.

:func:`i2c_event_cycles` times the scratch ring's I2C bus events in gpsim (``i2c_bench.asm``): the measured bus
timing that :data:`gaitlog.firmware_sim.fixedpoint.I2C_BYTE_CYCLES` is priced from.
"""

from __future__ import annotations

import re
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ
from gaitlog.firmware_sim.algorithms.probe import algorithm_operation_counts
from gaitlog.firmware_sim.budget import LoggerConfig, estimated_cycles, interrupt_cycles_estimate
from gaitlog.firmware_sim.fixedpoint import DEFAULT_FOSC_HZ, cycles_per_sample_available
from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.firmware_sim.pic.gpsim_bench import copy_sources
from gaitlog.firmware_sim.pic.gpsim_logger import MemoryMap, PicLogger, memory_map, run_starts

__all__ = ["CyclePart", "RecordCycles", "ChipBudget", "chip_budget", "STEPS", "STILL_ESTIMATED", "RAM_ESTIMATE_NOTE",
           "I2C_EVENTS", "i2c_event_cycles"]

#: The parts compared, in order: the interrupt, the algorithm's steps (the harness's stages) and their sums.
STEPS = ("sampling interrupt", "step 1 (calibration)", "steps 2-3 (gravity, a_v)", "steps 1-3",
         "step 4 (3 Hz FIR, scratch)", "step 5 (detector, record)", "steps 1-5", "total in assembly")
#: Why ``gaitlog budget``'s RAM estimate (:func:`gaitlog.firmware_sim.budget.ram_budget`) differs from the measured map.
RAM_ESTIMATE_NOTE = ("budget.ram_budget: the algorithm's temporaries by the kernel's declared frames, not the "
                     "assembly's overlays; the header counters at 13 bytes, where the map keeps 8: write_index is "
                     "samples_written's low half (65,536 slots), the flags follow from the run's mode and that "
                     "count, and step_write_index is steps_written mod the step capacity, computed when a record "
                     "is stored")
#: What the assembly does not do yet: its cycles are in neither figure.
STILL_ESTIMATED = ("the sample pages' I2C write and commit", "STOP's last step record", "UART")


def _config(h: PicLogger) -> LoggerConfig:
    return LoggerConfig("assembly", h.sampling_rate_hz, 3, fosc_hz=h.fosc_hz, source_impedance_ohm=h.source_impedance_ohm)


def _stats(x: np.ndarray) -> dict[str, float]:
    if x.size == 0:
        return {"mean": 0.0, "p99": 0.0, "worst": 0.0}
    return {"mean": float(np.mean(x)), "p99": float(np.percentile(x, 99)), "worst": float(np.max(x))}


@dataclass(frozen=True)
class CyclePart:
    """One part's cycles per sample: gpsim's (None without gpsim) and the model's, per sample."""

    name: str
    measured_cycles: np.ndarray | None
    estimated_cycles: np.ndarray

    @property
    def error_cycles(self) -> np.ndarray:
        """The model's error per sample, estimate - measured."""
        return self.estimated_cycles - self.measured_cycles

    def summary(self) -> dict:
        """Measured and estimated mean/p99/worst; the model's error per sample (mean, worst by magnitude)."""
        out = {"estimated": _stats(self.estimated_cycles)}
        if self.measured_cycles is None:
            return out
        err = self.error_cycles
        rel = 100.0 * err / np.maximum(self.measured_cycles, 1)
        k = int(np.argmax(np.abs(err)))
        out.update(measured=_stats(self.measured_cycles),
                   error={"mean_cycles": float(err.mean()), "mean_percent": float(rel.mean()),
                          "worst_cycles": float(err[k]), "worst_percent": float(rel[k]), "worst_sample": k})
        return out


@dataclass(frozen=True)
class RecordCycles:
    """Each step record's cycles: step 5 on the sample that wrote it (the detector and ``finalise``, the scratch
    ring read back over I2C), gpsim's (None without gpsim) and the model's."""

    samples: np.ndarray
    measured_cycles: np.ndarray | None
    estimated_cycles: np.ndarray

    @property
    def error_percent(self) -> np.ndarray:
        """The model's error on each record, % of gpsim's."""
        return 100.0 * (self.estimated_cycles - self.measured_cycles) / self.measured_cycles

    @property
    def mean_error_percent(self) -> float:
        """The model's mean over the records against gpsim's mean, %."""
        return float(100.0 * (self.estimated_cycles.mean() / self.measured_cycles.mean() - 1.0))

    def summary(self) -> dict:
        out = {"n_records": int(self.samples.size), "estimated": _stats(self.estimated_cycles)}
        if self.measured_cycles is None or self.samples.size == 0:
            return out
        e = self.error_percent
        out.update(measured=_stats(self.measured_cycles),
                   error={"mean_percent": self.mean_error_percent, "median_percent": float(np.median(e)),
                          "min_percent": float(e.min()), "max_percent": float(e.max())},
                   records=[{"sample": int(s), "measured": int(m), "estimated": round(float(x), 1)}
                            for s, m, x in zip(self.samples, self.measured_cycles, self.estimated_cycles)])
        return out

    def lines(self) -> list[str]:
        if self.samples.size == 0:
            return ["  no step record in these samples"]
        if self.measured_cycles is None:
            e = _stats(self.estimated_cycles)
            return [f"  step records ({self.samples.size}), step 5 on the record's sample: estimated mean "
                    f"{e['mean']:,.0f}, worst {e['worst']:,.0f}"]
        s = self.summary()
        m, x, r = s["measured"], s["estimated"], s["error"]
        out = [f"  step records ({self.samples.size}), step 5 on the record's sample: measured mean {m['mean']:,.0f}, "
               f"worst {m['worst']:,.0f} | estimated mean {x['mean']:,.0f}, worst {x['worst']:,.0f} | model's "
               f"error: mean {r['mean_percent']:+.1f} %, per record median {r['median_percent']:+.1f} % "
               f"({r['min_percent']:+.1f} % to {r['max_percent']:+.1f} %)",
               "  each record (sample: measured / estimated, error):"]
        cells = [f"{s:>6}: {m:>9,} / {x:>9,.0f} {p:+5.1f} %" for s, m, x, p in
                 zip(self.samples.tolist(), self.measured_cycles.tolist(), self.estimated_cycles, self.error_percent)]
        out += ["    " + "   ".join(cells[i:i + 3]) for i in range(0, len(cells), 3)]
        return out


@dataclass(frozen=True)
class ChipBudget:
    """:func:`chip_budget`'s result."""

    source: str
    n_samples: int
    sampling_rate_hz: float
    parts: tuple[CyclePart, ...]
    memory: MemoryMap | None
    why_not_measured: str | None
    period_cycles: float = 0.0
    records: RecordCycles | None = None
    backlog_samples_measured: int | None = None

    def backlog_cycles(self, measured: bool | None = None) -> float:
        """The most work the assembly part still owed when a sample came (Lindley's recursion on the measured,
        or estimated, total per sample against the period; 0 when every sample fits its period). ``measured``:
        which figures (default: the measured ones when gpsim ran)."""
        total = self.part("total in assembly")
        use_measured = self.measured if measured is None else measured
        t = total.measured_cycles if use_measured else total.estimated_cycles
        s = np.concatenate([[0.0], np.cumsum(t - self.period_cycles)])
        return float(np.max(s - np.minimum.accumulate(s)))

    @property
    def worst_backlog_cycles(self) -> float:
        """:meth:`backlog_cycles` of the measured figures (of the estimates without gpsim)."""
        return self.backlog_cycles()

    @property
    def measured(self) -> bool:
        """gpsim ran: the cycles, RAM and program words are measured."""
        return self.why_not_measured is None

    def part(self, name: str) -> CyclePart:
        """The part called ``name`` (one of :data:`STEPS`)."""
        return next(p for p in self.parts if p.name == name)

    def _estimated_lines(self) -> list[str]:
        out = [f"the assembly part on {self.source} ({self.n_samples:,} samples): not measured "
               f"({self.why_not_measured}); the model's figures, estimated:"]
        for p in self.parts:
            e = p.summary()["estimated"]
            out.append(f"  {p.name:<26} estimated mean {e['mean']:9,.1f}   p99 {e['p99']:9,.1f}   "
                       f"worst {e['worst']:9,.0f}")
        if self.records is not None:
            out += self.records.lines()
        out.append(f"  worst backlog, estimated: {self.backlog_cycles(False) / self.period_cycles:.2f} samples")
        return out

    def lines(self) -> list[str]:
        """A printed table."""
        if not self.measured:
            return self._estimated_lines()
        out = [f"the assembly part measured in gpsim on {self.source} ({self.n_samples:,} samples at "
               f"{self.sampling_rate_hz:g} Hz), cycles per sample:",
               f"  {'':<26} {'measured mean':>14} {'p99':>9} {'worst':>9} | {'estimated mean':>14} {'worst':>9} | "
               f"model's error per sample: mean, worst"]
        for p in self.parts:
            s = p.summary()
            m, e, r = s["measured"], s["estimated"], s["error"]
            out.append(f"  {p.name:<26} {m['mean']:14,.1f} {m['p99']:9,.1f} {m['worst']:9,.0f} | "
                       f"{e['mean']:14,.1f} {e['worst']:9,.0f} | {r['mean_cycles']:+8,.1f} ({r['mean_percent']:+.1f} %), "
                       f"{r['worst_cycles']:+9,.0f} ({r['worst_percent']:+.1f} %)")
        if self.records is not None:
            out += self.records.lines()
        worst = self.part("total in assembly").measured_cycles.max()
        out.append(f"  worst total {worst:,.0f} of {self.period_cycles:,.0f} cycles per sample "
                   f"({worst / self.period_cycles:.2f} periods); worst backlog, measured: "
                   f"{self.backlog_samples_measured} samples of 32 (PENDING), {self.worst_backlog_cycles:,.0f} cycles "
                   f"({self.worst_backlog_cycles / self.period_cycles:.2f} periods; the model's: "
                   f"{self.backlog_cycles(False) / self.period_cycles:.2f})")
        m = self.memory
        out.append(f"  RAM, measured (gpasm listing): {m.ram_line()}")
        out.append(f"  the model's RAM estimate ({RAM_ESTIMATE_NOTE}) is not this map: the map above is the firmware's")
        out.append(f"  program memory, measured: {m.program_words:,} of 8,192 words ({m.kernel_words} of them kernels)")
        out.append("  still estimated: " + ", ".join(STILL_ESTIMATED))
        return out

    def to_dict(self) -> dict:
        """The JSON form."""
        doc = {"source": self.source, "n_samples": self.n_samples, "sampling_rate_hz": self.sampling_rate_hz,
               "measured": self.measured, "why_not_measured": self.why_not_measured,
               "period_cycles": self.period_cycles, "worst_backlog_cycles": self.worst_backlog_cycles,
               "worst_backlog_cycles_estimated": self.backlog_cycles(False),
               "worst_backlog_samples_measured": self.backlog_samples_measured,
               "cycles_per_sample": {p.name: p.summary() for p in self.parts},
               "step_records": self.records.summary() if self.records is not None else None,
               "still_estimated": list(STILL_ESTIMATED)}
        if self.memory is not None:
            doc.update(ram_bytes_measured=self.memory.ram_bytes, ram_total_bytes_measured=self.memory.ram_total_bytes,
                       ram_groups_measured=self.memory.ram_groups, ram_problems=list(self.memory.ram_problems),
                       program_words_measured=self.memory.program_words, kernel_words=self.memory.kernel_words)
        return doc


def _sums(parts: list) -> list:
    """The stage list [interrupt, 1, 2-3, 4, 5] in :data:`STEPS` order, with its sums (None stays None)."""
    if parts[0] is None:
        return [None] * len(STEPS)
    isr, s1, s23, s4, s5 = parts
    return [isr, s1, s23, s1 + s23, s4, s5, s1 + s23 + s4 + s5, isr + s1 + s23 + s4 + s5]


def chip_budget(codes: np.ndarray, flags: np.ndarray, calibration: CalibrationQ, *, sampling_rate_hz: float = 50.0,
                fosc_hz: float = DEFAULT_FOSC_HZ, source: str = "codes", first_sample_number: int = 0,
                harness: PicLogger | None = None) -> ChipBudget:
    """Measure the assembly part in gpsim on ``codes`` (``(n, 3)``; ``flags``: S starts a run) beside the
    model's estimate of the same samples; without gputils/gpsim, the estimates alone."""
    c = np.asarray(codes, np.int64).reshape(-1, 3)
    f = np.asarray(flags, np.int64).reshape(-1)
    h = harness or PicLogger(sampling_rate_hz=sampling_rate_hz, fosc_hz=fosc_hz)
    ops = algorithm_operation_counts(c, calibration, h.sampling_rate_hz, run_starts(f), gravity_shift=h.gravity_shift,
                                     min_gravity_raw=h.min_gravity_raw)
    est = [np.full(c.shape[0], interrupt_cycles_estimate(_config(h)))] + [
        estimated_cycles(x) for x in (ops.step1, ops.steps23, ops.step4, ops.step5)]
    why = gl.missing_tools()
    meas: list = [None] * 5
    mem, backlog = None, None
    samples, rec_meas = ops.record_samples, None
    if why is None:
        run = h.run(c, f, calibration, first_sample_number=first_sample_number)
        meas = [run.isr_cycles.astype(float)] + [run.stage_cycles[:, i].astype(float) for i in range(4)]
        mem = memory_map(sampling_rate_hz=h.sampling_rate_hz, fosc_hz=h.fosc_hz)
        backlog = int(run.backlog_max)
        samples = np.intersect1d(ops.record_samples, run.calls[:, 0])   # the records both sides wrote
        rec_meas = run.stage_cycles[samples, 3].astype(np.int64)
    parts = tuple(CyclePart(n, m, e) for n, m, e in zip(STEPS, _sums(meas), _sums(est)))
    records = RecordCycles(samples, rec_meas, est[4][samples])
    return ChipBudget(source, int(c.shape[0]), float(h.sampling_rate_hz), parts, mem, why,
                      cycles_per_sample_available(h.sampling_rate_hz, h.fosc_hz), records, backlog)


# ---------------------------------------------------------------------------------------------------------
# the I2C bus, timed

#: The bus events ``i2c_bench.asm`` times, in order (each with the instructions step_record.asm runs for it).
I2C_EVENTS = ("start", "send control", "send address high", "send address low", "restart", "send control (read)",
              "receive", "acknowledge", "receive", "acknowledge", "receive (last)", "not acknowledge", "stop")
I2C_BENCH_ASM = Path(__file__).resolve().parent / "i2c_bench.asm"
_MARK_ADDRESS = 0x20
_MARK_CYCLES = 2                        # MOVLW, MOVWF of each mark
_MARK_WRITE = re.compile(r"^0x([0-9A-Fa-f]+) p16f877[^\n]*\n(?:[^\n]*\n)*?\s+Wrote: 0x([0-9A-Fa-f]+) to", re.M)


def i2c_event_cycles(timeout_s: float = 60.0) -> list[tuple[str, int]]:
    """(event, cycles): each of :data:`I2C_EVENTS`' instruction cycles in gpsim (the MSSP at SSPADD = 10, the 24xx256 of the
    logger's runs on the bus), its instructions included: a random read's opening, two bytes received and
    acknowledged, the last one not acknowledged, the stop. A send includes its ``MOVLW`` and ``CALL i2c_tx``; a
    receive its ``MOVF SSPBUF`` and ``MOVWF`` (the last one's neither). Raises :class:`~.gpsim_logger.PicError`
    without gputils/gpsim or when gpsim fails."""
    why = gl.missing_tools()
    if why:
        raise gl.PicError(why)
    with tempfile.TemporaryDirectory(prefix="gpsim-i2c-") as tmp:
        asm = Path(tmp) / I2C_BENCH_ASM.name
        copy_sources(Path(tmp), I2C_BENCH_ASM)
        proc = subprocess.run(["gpasm", "-p", "p16f877", asm.name], capture_output=True, text=True, timeout=60,
                              cwd=tmp)
        cod = asm.with_suffix(".cod")
        if proc.returncode != 0 or not cod.exists():
            raise gl.PicError(f"gpasm failed on {I2C_BENCH_ASM.name}: {(proc.stdout + proc.stderr).strip()[-300:]}")
        log = gl._gpsim(gl._Build(cod, {}), [_MARK_ADDRESS], "e done", timeout_s).decode(errors="replace")
    stamps = [int(m.group(1), 16) for m in _MARK_WRITE.finditer(log)]
    if len(stamps) < len(I2C_EVENTS) + 1:
        raise gl.PicError(f"the I2C bench logged {len(stamps)} marks, not {len(I2C_EVENTS) + 1}")
    return [(name, stamps[i + 1] - stamps[i] - _MARK_CYCLES) for i, name in enumerate(I2C_EVENTS)]
