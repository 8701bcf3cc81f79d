"""Ranges of the fixed-point variables over recordings, IPOL trials and simulated walks (``gaitlog ranges``).

Each source is run through the logger's on-line algorithm as the logger sets it up from its header (rate, ADC
width, calibration, step configuration; :func:`gaitlog.firmware_sim.firmware.step_algorithm_for`) and observed by
:class:`gaitlog.firmware_sim.ranges.RangeCollector`:

* a logger recording (anything ``gaitlog decode`` reads): its runs, cut at every missing sample;
* an IPOL trial (``_lb.txt``, its ``.json``, or a folder of trials): replayed through the emulated logger
  (:func:`gaitlog.host.studies.ipol_evaluation.replay_trial`);
* ``n_simulated`` walkers (``random_subjects(n, seed)``, walker ``i`` walking with seed ``seed + i``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from gaitlog.firmware_sim.adc import Adc
from gaitlog.firmware_sim.algorithms.format_kernel import KernelFormats
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.ranges import RangeCollector, RangeReport
from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.firmware import step_algorithm_for
from gaitlog.firmware_sim.world.subject import random_subjects
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_file
from gaitlog.host.files.replay import run_starts
from gaitlog.host.studies.ipol_evaluation import replay_trial
from gaitlog.protocol.steps import StepConfig

__all__ = ["collect_ranges", "ipol_trial_paths", "recording_segments", "words_label"]

#: The step configuration of a recording whose header turns the algorithm off (the ranges need one).
DEFAULT_LEG_M, DEFAULT_FOOT_M = 0.9, 0.2


def recording_segments(valid: np.ndarray, flags: np.ndarray) -> list[tuple[int, int]]:
    """``[a, b)`` stretches of present samples, cut at every run start (SESSION_START) and missing sample.

    >>> recording_segments(np.array([1, 1, 0, 1, 1, 1], bool), np.array([1, 0, 0, 0, 1, 0]))
    [(0, 2), (3, 4), (4, 6)]
    """
    ok = np.asarray(valid, bool)
    cut = np.zeros(ok.size, bool)
    cut[run_starts(ok, flags)] = True
    if ok.size:
        cut[0] = True
    starts = np.flatnonzero(ok & (cut | ~np.r_[False, ok[:-1]]))
    bounds = np.flatnonzero(~ok | cut)
    stops = np.append(bounds, ok.size)[np.searchsorted(bounds, starts, side="right")]
    return [(int(a), int(b)) for a, b in zip(starts, stops)]


def ipol_trial_paths(path: Path) -> list[Path]:
    """The IPOL trials ``path`` names (``_lb.txt`` files): itself, its ``.json``'s sibling, or a folder's (its
    ``GaitData`` folder's), sorted; empty when it is none of these."""
    if path.is_dir():
        inner = path / "GaitData" if (path / "GaitData").is_dir() else path
        return sorted(inner.glob("*_lb.txt"))
    if path.name.endswith("_lb.txt"):
        return [path]
    sibling = path.with_name(path.stem + "_lb.txt")
    return [sibling] if path.suffix == ".json" and sibling.is_file() else []


def _add_recording(collector: RangeCollector, path: Path) -> None:
    rec = decode_file(path)
    if rec.header is None:
        raise HostError(f"{path}: no logger header: ranges needs a logger recording, an IPOL trial or --simulate")
    alg = step_algorithm_for(rec.header)
    if alg is None:
        alg = OnlineStepAlgorithm(sampling_rate_hz=rec.header.sampling_rate_hz, calibration=rec.header.calibration,
                                  adc_bits=rec.header.adc_bits, step_config=StepConfig(
                                      step_format=1, leg_length_m=DEFAULT_LEG_M, foot_length_m=DEFAULT_FOOT_M))
    segments = recording_segments(rec.valid, rec.flags)
    if not segments:
        raise HostError(f"{path}: no valid samples to run")
    collector.add(alg, rec.codes, segments=segments, name=str(path))


def _add_trial(collector: RangeCollector, lb_path: Path) -> None:
    rt = replay_trial(lb_path)
    segments = recording_segments(np.ones(rt.codes.shape[0], bool), rt.flags)
    collector.add(step_algorithm_for(rt.header), rt.codes, segments=segments, name=str(lb_path))


def _add_walks(collector: RangeCollector, n: int, seed: int) -> None:
    for i, subject in enumerate(random_subjects(n, seed=seed)):
        logger = Logger(adc=Adc(), step_config=StepConfig(step_format=1, leg_length_m=subject.leg_length_m,
                                                          foot_length_m=subject.foot_length_m))
        res = logger.record(Walking(subject=subject, seed=seed + i))
        segments = recording_segments(np.ones(res.codes.shape[0], bool), np.asarray(res.flags))
        collector.add(step_algorithm_for(logger.header), res.codes, segments=segments,
                      name=f"simulated walker {i} (seed {seed + i})")


def words_label(text: str) -> str:
    """The canonical label of a format set of words only (``wexc12-wgrav24``, ``lpint1``, ``shipped``): the
    words ranges can be counted at (the run is the shipped one's). ValueError naming what is wrong.

    >>> words_label("wexc12-wgrav24"), words_label("shipped")
    ('wgrav24-wexc12', 'shipped')
    """
    words = KernelFormats.parse(text)
    if any(getattr(words, n) != getattr(KernelFormats(), n) for n in KernelFormats.field_names()):
        raise ValueError(f"{text!r}: words only (wNAME+N, lpintN), not fraction bits: the ranges are the shipped "
                         "run's")
    return words.label()


def collect_ranges(paths: Sequence[str | Path], *, n_simulated: int = 0, seed: int = 0,
                   margin_bits: int = 1, words: str = "shipped") -> RangeReport:
    """Ranges of every fixed-point variable over ``paths`` (recordings, IPOL trials or folders of them) and
    ``n_simulated`` walks (module notes), their saturations and headroom counted at the words of ``words`` (a
    :class:`~gaitlog.firmware_sim.algorithms.format_kernel.KernelFormats` label of words only;
    :class:`~gaitlog.firmware_sim.ranges.RangeCollector`).

    Raises
    ------
    HostError
        A path is unreadable or holds no codes to run (the message names it).
    """
    collector = RangeCollector(None if words == "shipped" else KernelFormats.parse(words))
    for p in map(Path, paths):
        if not p.exists():
            raise HostError(f"{p}: no such file or folder")
        trials = ipol_trial_paths(p)
        if p.is_dir() and not trials:
            raise HostError(f"{p}: a folder without IPOL trials (*_lb.txt)")
        for lb in trials:
            _add_trial(collector, lb)
        if not trials:
            _add_recording(collector, p)
    if n_simulated:
        _add_walks(collector, n_simulated, seed)
    return collector.report(margin_bits=margin_bits)
