"""The PIC firmware's step records on many recordings at once: every IPOL trial, simulated subjects
(:func:`check_records`). Each recording goes through the assembly in gpsim in the records-only lean mode
(:func:`gaitlog.firmware_sim.pic.gpsim_logger.verify_records`), two gpsim processes at a time; ``gaitlog pic
verify`` (:mod:`gaitlog.host.studies.pic_runs`) compares every stage of one recording."""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.pic import gpsim_logger
from gaitlog.firmware_sim.pic.gpsim_logger import PicError, PicLogger, RecordsVerification
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_bytes
from gaitlog.host.studies.pic_runs import AssemblyInput, assembly_input
from gaitlog.host.studies.simulation import simulated_population
from gaitlog.protocol.image import build_image

__all__ = ["CHECK_CORRIDOR_M", "simulated_inputs", "RecordsCheck", "check_records"]


#: The simulated subjects' walk for the records check (:func:`simulated_inputs`): the paper's protocol (its
#: logging run around one excursion) cut to one excursion at preferred speed in a corridor this long.
CHECK_CORRIDOR_M = 20.0


def simulated_inputs(n_subjects: int = 20, *, seed: int = 0, population: str = "people") -> list[AssemblyInput]:
    """The first ``n_subjects`` of ``gaitlog evaluate sim``'s population (its defaults: seed 0, the "people"
    population at the paper's heights, subject ``i`` walking with seed ``1000 seed + i``), each logging one
    excursion of :data:`CHECK_CORRIDOR_M` out and back at preferred speed with the emulated logger (nominal
    calibration, 50 Hz, 10 bits), read back from its memory image as the host reads a dump."""
    subjects, plan = simulated_population(n_subjects, seed=seed, population=population, protocol="paper")
    plan = replace(plan, corridor_length_m=CHECK_CORRIDOR_M, speeds=("preferred",),
                   lap_marks_m=(0.0, CHECK_CORRIDOR_M, 2 * CHECK_CORRIDOR_M))
    out = []
    for i, subject in enumerate(subjects):
        walk_seed = seed * 1000 + i
        logger = Logger(device_id=1 + walk_seed % 60000)
        for motion in Walking(subject=subject, walk_plan=plan, seed=walk_seed).render_runs(
                logger.sensor.internal_rate_hz):
            logger.record(motion, start_time_s=1_700_000_000 + int(motion.t0_s))
        name = f"subject {subject.subject_id}"
        rec = decode_bytes(build_image(logger.header.to_bytes(), logger.memory, step_memory=logger.step_memory),
                           source=name)
        out.append(assembly_input(rec, name, None))
    return out


@dataclass(frozen=True)
class RecordsCheck:
    """:func:`check_records`' result: one :class:`~gaitlog.firmware_sim.pic.gpsim_logger.RecordsVerification`
    per recording, in order, and the wall time of the whole check."""

    results: list[RecordsVerification]
    wall_s: float

    @property
    def identical(self) -> bool:
        return all(r.identical for r in self.results)

    @property
    def n_records(self) -> int:
        return sum(r.records.n_compared for r in self.results)

    @property
    def n_samples(self) -> int:
        return sum(r.n_samples for r in self.results)

    def differences(self) -> list[str]:
        """One line per recording whose records differ or whose main loop fell a page behind."""
        return [f"{r.source}: {r.records.n_identical} of {r.records.n_compared} records identical, first "
                f"difference {r.records.first_difference}, backlog {r.backlog_max}"
                for r in self.results if not r.identical]


def check_records(inputs: list[AssemblyInput], *, workers: int = 2, period_cycles: int | None = None) -> RecordsCheck:
    """Every recording's step records through the assembly in gpsim (the records-only lean mode,
    :func:`~gaitlog.firmware_sim.pic.gpsim_logger.verify_records`) against the model's, ``workers`` gpsim
    processes at a time (one recording each); ``period_cycles``: as
    :meth:`~gaitlog.firmware_sim.pic.gpsim_logger.PicLogger.run_records`.

    Raises
    ------
    HostError
        gputils or gpsim is missing, or gpsim fails on a recording.
    """
    why = gpsim_logger.missing_tools()
    if why:
        raise HostError(f"the records check needs gputils and gpsim: {why}")
    t0 = time.perf_counter()

    def one(run: AssemblyInput) -> RecordsVerification:
        harness = PicLogger(sampling_rate_hz=run.sampling_rate_hz, workers=1)
        try:
            return gpsim_logger.verify_records(run.codes, run.flags, run.calibration_q, source=run.source,
                                               first_sample_number=run.first_sample_number, harness=harness,
                                               period_cycles=period_cycles)
        except (PicError, ValueError) as err:
            raise HostError(f"{run.source}: {err}") from err

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        results = list(pool.map(one, inputs))
    return RecordsCheck(results, time.perf_counter() - t0)
