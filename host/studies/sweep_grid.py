"""A parameter grid over the simulated logger (``gaitlog sweep``): ADC bits x sampling rate x sensor noise x
simulated subjects x seeds, as independent tasks, each deterministic from its seed.

**Tasks.** One task is one subject of one seed (``random_subjects(n_subjects, seed=seed)[i]``, walking with
seed ``seed * 1000 + i``, as :class:`host.studies.sweep.AdcRateSweep`) sampled at one rate with one noise
density and quantised at one ADC width. Its work is :func:`host.studies.sweep.run_config` (the comparison of
:func:`host.studies.compare.compare_walk`: ideal, offline, on-line float and on-line fixed-point chains, one K
per calibration mode fitted on the offline chain): the same code as ``gaitlog compare --sweep``, so a grid of
the same configurations gives the same numbers. A task depends on nothing but its own fields, so it gives the
same rows in any process, in any order, on any machine: 1 worker, N workers, a remote cluster or a resumed run
agree exactly (the tests check it).

The expensive part, rendering the walk and the sensor's analog response, depends on the subject and seed only;
a process keeps the last :data:`WALK_MEMO_SIZE` rendered walks (:func:`analog_walk`), so the tasks of one
subject run by one worker render its walk once. The memo changes no result, only the time.

**Rows.** :func:`run_task` returns plain JSON-able rows: ``sections`` (one per configuration x subject x
evaluated 20 m section x calibration mode x estimator: the section ratio estimated / real of every chain) and
``splits`` (one per configuration x subject x share x estimator: the per-step error split ADC = offline -
ideal, algorithm = online-float - offline, arithmetic = online-fixed - online-float, mm), and ``task``, the
per-task scalars (step-timing error, fixed-point saturation).

**Q formats.** The fixed-point chain's formats (:mod:`firmware_sim.algorithms.formats`) are compile-time
constants of the numba kernel, not parameters: the grid does not sweep them; the arithmetic share measures the
firmware's own formats.

**Spec files.** :meth:`SweepGrid.from_spec` reads a JSON or TOML mapping with the keys of :data:`SPEC_KEYS`
(lists or single values); anything else is an error naming the key.
"""

from __future__ import annotations

import hashlib
import json
import math
import threading
import tomllib
from collections import OrderedDict
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from firmware_sim.algorithms.steps import ESTIMATORS
from firmware_sim.sensor import SensorModel
from firmware_sim.world.subject import random_subjects
from firmware_sim.world.walk_plan import WalkPlan
from host.errors import HostError
from host.gait.sections import MODES
from host.studies.compare import CHAINS, SHARES, column_key, pair_label
from host.studies.simulation import AnalogWalk
from host.studies.sweep import ADC_BITS, RATES_HZ, median_iqr, run_config
from protocol.adc_bits import MAX_SIMULATED_ADC_BITS, check_adc_bits

#: The sensor's own white-noise density (ADXL202E typical), g/√Hz.
SENSOR_NOISE_G_RTHZ: float = next(f.default for f in fields(SensorModel) if f.name == "noise_density_g_rthz")
#: Walking protocols: the paper's (10 min, 12 laps of 20 m at four speeds) and a short one for quick looks and
#: tests (four 40 m corridors with short rests).
PROTOCOLS: dict[str, WalkPlan | None] = {
    "paper": None,
    "short": WalkPlan(corridor_length_m=40.0, rest_s=8.0, lap_marks_m=(0.0, 10.0, 30.0, 50.0, 70.0, 80.0)),
}
#: Largest spec file read, bytes.
MAX_SPEC_BYTES = 1 << 20
#: Rendered walks kept per process (:func:`analog_walk`).
WALK_MEMO_SIZE = 2
#: Keys of a spec file and their meaning.
SPEC_KEYS = {
    "adc_bits": "ADC widths, bits",
    "sampling_rate_hz": "logger sampling rates, Hz",
    "noise_density_g_rthz": "sensor white-noise densities, g/√Hz",
    "subjects": "simulated subjects per seed",
    "seeds": "seeds of the subject draws",
    "estimators": f"estimators kept in the rows ({', '.join(ESTIMATORS)})",
    "protocol": f"walking protocol ({', '.join(PROTOCOLS)})",
}
#: Section-ratio columns of a ``sections`` row (the chains and the exact-timing offline chain).
RATIO_KINDS = tuple(column_key(c) for c in CHAINS) + ("exact_timing",)
#: Configuration columns, first in every row.
CONFIG_COLUMNS = ("adc_bits", "sampling_rate_hz", "noise_density_g_rthz", "protocol", "seed")
SECTION_COLUMNS = CONFIG_COLUMNS + ("subject", "excursion", "speed_label", "section", "real_m", "mode", "estimator") \
    + tuple(f"ratio_{k}" for k in RATIO_KINDS)
SPLIT_COLUMNS = CONFIG_COLUMNS + ("subject", "share", "pair", "estimator", "n", "median_abs_mm", "p95_abs_mm",
                                  "max_abs_mm", "bias_mm", "max_rel", "n_different_events")
SUMMARY_COLUMNS = (("adc_bits", "sampling_rate_hz", "noise_density_g_rthz", "mode", "estimator", "n_subjects",
                    "n_sections")
                   + tuple(f"{q}_{k}" for k in RATIO_KINDS[:-1] for q in ("median", "iqr"))
                   + ("subject_median_offline_lo", "subject_median_offline_hi", "adc_ratio_abs_max",
                      "adc_step_mm", "arith_step_mm"))
#: The quantisation question's tolerances: per-step |offline - ideal| median and section-ratio difference.
STEP_TOLERANCE_MM = 1.0
RATIO_TOLERANCE = 0.01


@dataclass(frozen=True)
class SweepTask:
    """One subject x one configuration (module notes); everything the task's result depends on."""

    seed: int
    subject_index: int
    n_subjects: int
    adc_bits: int
    sampling_rate_hz: float
    noise_density_g_rthz: float
    protocol: str
    estimators: tuple[str, ...]
    calibration_sections: int = 2

    @property
    def group(self) -> tuple:
        """The walk this task samples: tasks of one group share its rendering (:func:`analog_walk`)."""
        return (self.seed, self.subject_index, self.n_subjects, self.protocol)

    @property
    def key(self) -> str:
        """A file-name-safe name, unique for the task's fields (readable part + hash of all fields)."""
        text = json.dumps(asdict(self), sort_keys=True)
        digest = hashlib.sha256(text.encode()).hexdigest()[:12]
        return (f"seed{self.seed}-s{self.subject_index}-{self.adc_bits}b-{self.sampling_rate_hz:g}Hz-"
                f"n{self.noise_density_g_rthz:g}-{digest}")


@dataclass(frozen=True)
class SweepGrid:
    """The grid (module notes); :meth:`tasks` lists its tasks in a fixed order."""

    adc_bits: tuple[int, ...] = ADC_BITS
    sampling_rate_hz: tuple[float, ...] = RATES_HZ
    noise_density_g_rthz: tuple[float, ...] = (SENSOR_NOISE_G_RTHZ,)
    subjects: int = 4
    seeds: tuple[int, ...] = (0,)
    estimators: tuple[str, ...] = ESTIMATORS
    protocol: str = "paper"
    calibration_sections: int = field(default=2, repr=False)

    def __post_init__(self) -> None:
        for b in self.adc_bits:
            check_adc_bits(b, max_bits=MAX_SIMULATED_ADC_BITS, what="ADC bits", error=HostError)
        for name in ("adc_bits", "sampling_rate_hz", "noise_density_g_rthz", "seeds", "estimators"):
            if not getattr(self, name):
                raise HostError(f"sweep grid: {name} is empty")
        for r in self.sampling_rate_hz:
            if not (math.isfinite(r) and 10.0 <= r <= 1000.0):
                raise HostError(f"sweep grid: sampling rate {r:g} Hz outside 10-1000 Hz")
        for n in self.noise_density_g_rthz:
            if not (math.isfinite(n) and 0.0 <= n <= 0.01):
                raise HostError(f"sweep grid: noise density {n:g} g/√Hz outside 0-0.01")
        if not 1 <= self.subjects <= 1000:
            raise HostError(f"sweep grid: subjects must be 1..1000, got {self.subjects}")
        unknown = [e for e in self.estimators if e not in ESTIMATORS]
        if unknown:
            raise HostError(f"sweep grid: unknown estimator(s) {', '.join(unknown)}; known: {', '.join(ESTIMATORS)}")
        if self.protocol not in PROTOCOLS:
            raise HostError(f"sweep grid: unknown protocol {self.protocol!r}; known: {', '.join(PROTOCOLS)}")

    @classmethod
    def from_spec(cls, spec: dict, *, source: str = "spec") -> SweepGrid:
        """A grid from a mapping with the keys of :data:`SPEC_KEYS` (scalars or lists; missing keys: defaults)."""
        unknown = sorted(set(spec) - set(SPEC_KEYS))
        if unknown:
            raise HostError(f"{source}: unknown key(s) {', '.join(unknown)}; known: {', '.join(SPEC_KEYS)}")
        kinds = {"adc_bits": int, "sampling_rate_hz": float, "noise_density_g_rthz": float, "seeds": int,
                 "estimators": str}
        kw: dict[str, Any] = {}
        for key, value in spec.items():
            try:
                if key in kinds:
                    values = value if isinstance(value, list) else [value]
                    if kinds[key] is not str and any(isinstance(v, (bool, str)) for v in values):
                        raise ValueError(key)
                    kw[key] = tuple(kinds[key](v) for v in values)
                elif key == "subjects":
                    if isinstance(value, bool) or not isinstance(value, int):
                        raise ValueError(key)
                    kw[key] = value
                else:
                    kw[key] = str(value)
            except (TypeError, ValueError):
                raise HostError(f"{source}: {key} = {value!r} is not {SPEC_KEYS[key]}") from None
        try:
            return cls(**kw)
        except HostError as err:
            raise HostError(f"{source}: {err}") from None

    @classmethod
    def load(cls, path: str | Path) -> SweepGrid:
        """A grid from a ``.json`` or ``.toml`` spec file."""
        p = Path(path)
        try:
            if p.stat().st_size > MAX_SPEC_BYTES:
                raise HostError(f"{p}: {p.stat().st_size} bytes is too large for a sweep spec")
            text = p.read_text(encoding="utf-8")
        except OSError as err:
            raise HostError(f"{p}: cannot read: {err.strerror or err}") from None
        except UnicodeDecodeError:
            raise HostError(f"{p}: not a text file (a JSON or TOML spec is UTF-8 text)") from None
        try:
            spec = tomllib.loads(text) if p.suffix.lower() == ".toml" else json.loads(text)
        except (tomllib.TOMLDecodeError, json.JSONDecodeError, RecursionError) as err:
            raise HostError(f"{p}: not a valid {'TOML' if p.suffix.lower() == '.toml' else 'JSON'} spec: {err}") from None
        if not isinstance(spec, dict):
            raise HostError(f"{p}: a spec is a mapping of {', '.join(SPEC_KEYS)}")
        return cls.from_spec(spec, source=str(p))

    def to_spec(self) -> dict:
        """The spec mapping of this grid (:meth:`from_spec` of it gives it back)."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items() if k in SPEC_KEYS}

    def tasks(self) -> list[SweepTask]:
        """Every task, seed by seed, subject by subject (the walk's order), then rate, noise and width."""
        return [SweepTask(seed, i, self.subjects, b, float(r), float(n), self.protocol, tuple(self.estimators),
                          self.calibration_sections)
                for seed in self.seeds for i in range(self.subjects) for r in self.sampling_rate_hz
                for n in self.noise_density_g_rthz for b in self.adc_bits]


_WALKS: OrderedDict[tuple, AnalogWalk] = OrderedDict()
_WALKS_LOCK = threading.Lock()          # a threaded worker runs several tasks in one process


def analog_walk(seed: int, subject_index: int, n_subjects: int, protocol: str) -> tuple[Any, AnalogWalk]:
    """The subject and its rendered walk (module notes: a per-process memo of :data:`WALK_MEMO_SIZE` walks)."""
    key = (seed, subject_index, n_subjects, protocol)          # SweepTask.group
    with _WALKS_LOCK:
        walk = _WALKS.get(key)
        if walk is not None:
            _WALKS.move_to_end(key)
            return walk.subject, walk
    subject = random_subjects(n_subjects, seed=seed)[subject_index]
    walk = AnalogWalk(subject=subject, seed=seed * 1000 + subject_index, walk_plan=PROTOCOLS[protocol]).run()
    with _WALKS_LOCK:
        _WALKS[key] = walk
        while len(_WALKS) > WALK_MEMO_SIZE:
            _WALKS.popitem(last=False)
    return subject, walk


def _plain(v: Any) -> Any:
    """A JSON-able Python scalar of a numpy one."""
    if isinstance(v, np.generic):
        return v.item()
    return v


def run_task(task: SweepTask) -> dict:
    """The rows of one task (module notes): ``{"sections": [...], "splits": [...], "task": {...}}``."""
    subject, walk = analog_walk(task.seed, task.subject_index, task.n_subjects, task.protocol)
    sw = walk.sample(task.sampling_rate_hz, noise_density_g_rthz=task.noise_density_g_rthz)
    result, _ = run_config(sw, subject, task.adc_bits, calibration_sections=task.calibration_sections)
    config = dict(adc_bits=task.adc_bits, sampling_rate_hz=task.sampling_rate_hz,
                  noise_density_g_rthz=task.noise_density_g_rthz, protocol=task.protocol, seed=task.seed)
    keep = set(task.estimators)
    sections = [config | {k: _plain(s[k]) for k in SECTION_COLUMNS if k in s and k not in config}
                for s in result.segments if s["estimator"] in keep]
    splits = [config | {"subject": subject.subject_id} | {k: _plain(d[k]) for k in SPLIT_COLUMNS if k in d}
              for d in result.step_diffs if d["estimator"] in keep]
    scalars = config | dict(subject=subject.subject_id, timing_rms_ms=_plain(result.timing["rms_ms"]),
                            saturated=int(result.saturated), wrapped=int(result.wrapped),
                            saturation=result.saturation)
    return {"sections": sections, "splits": splits, "task": scalars}


def summarise(sections: list[dict], splits: list[dict]) -> list[dict]:
    """One row per (bits, rate, noise, mode, estimator), pooled over seeds and subjects.

    ``median_<chain>`` / ``iqr_<chain>``: pooled 20 m section ratios; ``subject_median_offline_lo/hi``: the
    range over subjects of each subject's median offline ratio (the interval over subjects);
    ``adc_ratio_abs_max``: the largest per-section |offline - ideal| ratio; ``adc_step_mm`` /
    ``arith_step_mm``: median over subjects of the per-step median |offline - ideal| and |online-fixed -
    online-float| (multi-speed lengths).
    """
    labels = {s: pair_label(a, b) for s, (a, b) in SHARES.items()}
    groups: dict[tuple, list[dict]] = {}
    for s in sections:
        groups.setdefault((s["adc_bits"], s["sampling_rate_hz"], s["noise_density_g_rthz"], s["mode"],
                           s["estimator"]), []).append(s)
    split_groups: dict[tuple, list[dict]] = {}
    for d in splits:
        split_groups.setdefault((d["adc_bits"], d["sampling_rate_hz"], d["noise_density_g_rthz"], d["pair"],
                                 d["estimator"]), []).append(d)
    out = []
    for key in sorted(groups, key=lambda k: (k[1], k[2], k[0], MODES.index(k[3]), ESTIMATORS.index(k[4]))):
        bits, rate, noise, mode, est = key
        seg = groups[key]
        row: dict[str, Any] = dict(adc_bits=bits, sampling_rate_hz=rate, noise_density_g_rthz=noise, mode=mode,
                                   estimator=est, n_subjects=len({(s["seed"], s["subject"]) for s in seg}),
                                   n_sections=len(seg))
        ratio = {k: np.array([s[f"ratio_{k}"] for s in seg], float) for k in RATIO_KINDS}
        for k in RATIO_KINDS[:-1]:
            row[f"median_{k}"], row[f"iqr_{k}"] = median_iqr(ratio[k])
        per_subject = [median_iqr(np.array([s["ratio_offline"] for s in seg if (s["seed"], s["subject"]) == subj], float))[0]
                       for subj in sorted({(s["seed"], s["subject"]) for s in seg})]
        per_subject = [v for v in per_subject if math.isfinite(v)]
        row["subject_median_offline_lo"] = float(min(per_subject)) if per_subject else math.nan
        row["subject_median_offline_hi"] = float(max(per_subject)) if per_subject else math.nan
        d = ratio["offline"] - ratio["ideal"]
        row["adc_ratio_abs_max"] = float(np.nanmax(np.abs(d))) if np.isfinite(d).any() else math.nan
        for share, col in (("adc", "adc_step_mm"), ("arithmetic", "arith_step_mm")):
            v = [x["median_abs_mm"] for x in split_groups.get((bits, rate, noise, labels[share], est), [])]
            v = [x for x in v if math.isfinite(x)]
            row[col] = float(np.median(v)) if v else math.nan
        out.append(row)
    return [{k: r[k] for k in SUMMARY_COLUMNS} for r in out]


def smallest_adc_bits(summary: list[dict], *, mode: str = "multi-speed") -> list[dict]:
    """Per (rate, noise, estimator): the smallest swept ADC width from which on every wider one the ADC share
    stays within :data:`STEP_TOLERANCE_MM` per step (median) and :data:`RATIO_TOLERANCE` per 20 m section
    (largest |offline - ideal| ratio); ``smallest_adc_bits`` is None when no swept width does."""
    out = []
    keys = sorted({(r["sampling_rate_hz"], r["noise_density_g_rthz"], r["estimator"]) for r in summary
                   if r["mode"] == mode}, key=lambda k: (k[0], k[1], ESTIMATORS.index(k[2])))
    for rate, noise, est in keys:
        rows = sorted((r for r in summary if r["mode"] == mode and r["estimator"] == est
                       and r["sampling_rate_hz"] == rate and r["noise_density_g_rthz"] == noise),
                      key=lambda r: r["adc_bits"])
        ok = [r["adc_step_mm"] <= STEP_TOLERANCE_MM and r["adc_ratio_abs_max"] <= RATIO_TOLERANCE for r in rows]
        best = None
        for i in range(len(rows) - 1, -1, -1):
            if not ok[i]:
                break
            best = rows[i]["adc_bits"]
        out.append(dict(sampling_rate_hz=rate, noise_density_g_rthz=noise, estimator=est, smallest_adc_bits=best,
                        swept_bits="/".join(str(r["adc_bits"]) for r in rows)))
    return out


def format_summary(summary: list[dict], *, mode: str = "multi-speed") -> str:
    """Printed summary of one calibration mode."""
    lines = [f"{mode} calibration (one K per configuration, fitted on its offline chain); section ratio "
             "estimated / real, pooled median and IQR; subj. range: subjects' median offline ratio; ADC mm / arith "
             "mm: per-step median |offline - ideal| / |online-fixed - online-float|",
             f"{'bits':>4}{'Hz':>6}{'noise ug':>9} {'est':<4}{'subj':>5}{'n':>6}{'ideal':>8}{'offline':>8}{'IQR':>7}"
             f"{'on-fx':>8}{'subj. range':>14}{'ADC max':>9}{'ADC mm':>8}{'arith mm':>9}"]
    for r in summary:
        if r["mode"] != mode:
            continue
        lines.append(f"{r['adc_bits']:>4}{r['sampling_rate_hz']:>6g}{1e6 * r['noise_density_g_rthz']:>9.0f} "
                     f"{r['estimator']:<4}{r['n_subjects']:>5}{r['n_sections']:>6}{r['median_ideal']:>8.3f}"
                     f"{r['median_offline']:>8.3f}{r['iqr_offline']:>7.3f}{r['median_online_fixed']:>8.3f}"
                     f"{r['subject_median_offline_lo']:>7.3f}-{r['subject_median_offline_hi']:<6.3f}"
                     f"{r['adc_ratio_abs_max']:>9.4f}{r['adc_step_mm']:>8.3f}{r['arith_step_mm']:>9.3f}")
    return "\n".join(lines)


def format_smallest_bits(rows: list[dict]) -> str:
    """Printed answer: the smallest ADC width within the tolerances, per rate, noise and estimator."""
    lines = [f"smallest swept ADC width keeping the ADC share within {STEP_TOLERANCE_MM:g} mm per step and "
             f"{100 * RATIO_TOLERANCE:g} % per 20 m section (multi-speed K); Q formats are the firmware's, not swept"]
    for r in rows:
        b = r["smallest_adc_bits"]
        lines.append(f"  {r['sampling_rate_hz']:g} Hz, noise {1e6 * r['noise_density_g_rthz']:.0f} ug/rtHz, "
                     f"{r['estimator']}: {b if b is not None else 'none'} bits (swept {r['swept_bits']})")
    return "\n".join(lines)
