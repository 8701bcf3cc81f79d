"""The cycle and memory budget of the firmware's assembly part, measured on the chip (gpsim) beside the model.

:func:`chip_budget` runs ``logger.asm`` in gpsim on a walk's codes (:class:`~.gpsim_logger.PicLogger`) and
prices the same samples with the model (:func:`gaitlog.firmware_sim.algorithms.probe.front_operation_counts`
at :data:`gaitlog.firmware_sim.budget.MEAN_CYCLES`; the interrupt's parts of
:func:`gaitlog.firmware_sim.budget.logging_cycles`). Each part gets the measured cycles per sample (mean, 99th
percentile, worst), the model's estimate and the model's error per sample; RAM and program words come from
gpasm's listing (:func:`~.gpsim_logger.memory_map`). Without gputils/gpsim (``measured`` False) only the
model's estimates are filled in. Steps 4 and later of the algorithm, the I2C driver and the UART stay estimates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ
from gaitlog.firmware_sim.algorithms.probe import front_operation_counts
from gaitlog.firmware_sim.budget import LoggerConfig, estimated_cycles, interrupt_cycles_estimate
from gaitlog.firmware_sim.fixedpoint import DEFAULT_FOSC_HZ, cycles_per_sample_available
from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.firmware_sim.pic.gpsim_logger import MemoryMap, PicLogger, memory_map, run_starts

__all__ = ["CyclePart", "ChipBudget", "chip_budget", "STEPS"]

#: The parts compared, in order: the interrupt, the algorithm's steps 1-3 (stage 1; stages 2-3), their sum.
STEPS = ("sampling interrupt", "step 1 (calibration)", "steps 2-3 (gravity, a_v)", "steps 1-3", "total in assembly")


def _config(h: PicLogger) -> LoggerConfig:
    return LoggerConfig("assembly", h.sampling_rate_hz, 3, fosc_hz=h.fosc_hz, source_impedance_ohm=h.source_impedance_ohm)


def _stats(x: np.ndarray) -> dict[str, float]:
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
        rel = 100.0 * err / self.measured_cycles
        k = int(np.argmax(np.abs(err)))
        out.update(measured=_stats(self.measured_cycles),
                   error={"mean_cycles": float(err.mean()), "mean_percent": float(rel.mean()),
                          "worst_cycles": float(err[k]), "worst_percent": float(rel[k]), "worst_sample": k})
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

    @property
    def worst_backlog_cycles(self) -> float:
        """The most work the assembly part still owed when a sample came (Lindley's recursion on the measured,
        else estimated, total per sample against the period; 0 when every sample fits its period)."""
        total = self.part("total in assembly")
        t = total.measured_cycles if self.measured else total.estimated_cycles
        s = np.concatenate([[0.0], np.cumsum(t - self.period_cycles)])
        return float(np.max(s - np.minimum.accumulate(s)))

    @property
    def measured(self) -> bool:
        """gpsim ran: the cycles, RAM and program words are measured."""
        return self.why_not_measured is None

    def part(self, name: str) -> CyclePart:
        """The part called ``name`` (one of :data:`STEPS`)."""
        return next(p for p in self.parts if p.name == name)

    def lines(self) -> list[str]:
        """A printed table."""
        if not self.measured:
            out = [f"the assembly part on {self.source} ({self.n_samples:,} samples): not measured "
                   f"({self.why_not_measured}); the model's figures, estimated:"]
            for p in self.parts:
                e = p.summary()["estimated"]
                out.append(f"  {p.name:<26} estimated mean {e['mean']:8,.1f}   p99 {e['p99']:8,.1f}   "
                           f"worst {e['worst']:8,.0f}")
            return out
        out = [f"the assembly part measured in gpsim on {self.source} ({self.n_samples:,} samples at "
               f"{self.sampling_rate_hz:g} Hz), cycles per sample:",
               f"  {'':<26} {'measured mean':>14} {'p99':>8} {'worst':>7} | {'estimated mean':>14} {'worst':>7} | "
               f"model's error per sample: mean, worst"]
        for p in self.parts:
            s = p.summary()
            m, e, r = s["measured"], s["estimated"], s["error"]
            out.append(f"  {p.name:<26} {m['mean']:14,.1f} {m['p99']:8,.1f} {m['worst']:7,.0f} | "
                       f"{e['mean']:14,.1f} {e['worst']:7,.0f} | {r['mean_cycles']:+8,.1f} ({r['mean_percent']:+.1f} %), "
                       f"{r['worst_cycles']:+7,.0f} ({r['worst_percent']:+.1f} %)")
        worst = self.part("total in assembly").measured_cycles.max()
        out.append(f"  worst total {worst:,.0f} of {self.period_cycles:,.0f} cycles per sample "
                   f"({100 * worst / self.period_cycles:.1f} %), worst backlog {self.worst_backlog_cycles:,.0f} cycles")
        m = self.memory
        out.append(f"  RAM, measured (gpasm listing): {m.ram_total_bytes} of 368 bytes ("
                   + ", ".join(f"{k} {v}" for k, v in m.ram_bytes.items()) + ")")
        out.append(f"  program memory, measured: {m.program_words:,} of 8,192 words ({m.kernel_words} of them kernels)")
        out.append("  still estimated: steps 4 and later of the algorithm, the I2C page write and commit, the UART")
        return out

    def to_dict(self) -> dict:
        """The JSON form."""
        doc = {"source": self.source, "n_samples": self.n_samples, "sampling_rate_hz": self.sampling_rate_hz,
               "measured": self.measured, "why_not_measured": self.why_not_measured,
               "period_cycles": self.period_cycles, "worst_backlog_cycles": self.worst_backlog_cycles,
               "cycles_per_sample": {p.name: p.summary() for p in self.parts},
               "still_estimated": ["steps 4 and later of the algorithm", "I2C page write and commit", "UART"]}
        if self.memory is not None:
            doc.update(ram_bytes_measured=self.memory.ram_bytes, ram_total_bytes_measured=self.memory.ram_total_bytes,
                       program_words_measured=self.memory.program_words, kernel_words=self.memory.kernel_words)
        return doc


def chip_budget(codes: np.ndarray, flags: np.ndarray, calibration: CalibrationQ, *, sampling_rate_hz: float = 50.0,
                fosc_hz: float = DEFAULT_FOSC_HZ, source: str = "codes", first_sample_number: int = 0,
                harness: PicLogger | None = None) -> ChipBudget:
    """Measure the assembly part in gpsim on ``codes`` (``(n, 3)``; ``flags``: S starts a run) beside the
    model's estimate of the same samples; without gputils/gpsim, the estimates alone."""
    c = np.asarray(codes, np.int64).reshape(-1, 3)
    f = np.asarray(flags, np.int64).reshape(-1)
    h = harness or PicLogger(sampling_rate_hz=sampling_rate_hz, fosc_hz=fosc_hz)
    s1, s23 = front_operation_counts(c, calibration, h.gravity_shift, h.min_gravity_raw, run_starts(f))
    est = [np.full(c.shape[0], interrupt_cycles_estimate(_config(h))), estimated_cycles(s1), estimated_cycles(s23)]
    why = gl.missing_tools()
    meas: list[np.ndarray | None] = [None, None, None]
    mem = None
    if why is None:
        run = h.run(c, f, calibration, first_sample_number=first_sample_number)
        meas = [run.isr_cycles.astype(float), run.stage_cycles[:, 0].astype(float),
                run.stage_cycles[:, 1].astype(float)]
        mem = memory_map(sampling_rate_hz=h.sampling_rate_hz, fosc_hz=h.fosc_hz)
    est += [est[1] + est[2], est[0] + est[1] + est[2]]
    if why is None:
        meas += [meas[1] + meas[2], meas[0] + meas[1] + meas[2]]
    else:
        meas += [None, None]
    parts = tuple(CyclePart(n, m, e) for n, m, e in zip(STEPS, meas, est))
    return ChipBudget(source, int(c.shape[0]), float(h.sampling_rate_hz), parts, mem, why,
                      cycles_per_sample_available(h.sampling_rate_hz, h.fosc_hz))
