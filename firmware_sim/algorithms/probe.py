"""Probes into the fixed-point kernel: a stage's intermediate values, for the PIC assembly to be compared with.

The on-line kernel (:mod:`gaitlog.firmware_sim.algorithms.kernel`) keeps only its state and its step records;
the values in between (the calibrated axes of step 1, ...) are gone by the end of a sample. The PIC assembly
(``firmware_sim/pic/logger.asm``, run by :mod:`gaitlog.firmware_sim.pic.gpsim_logger`) writes them to RAM, so
a comparison needs them from the model too. A probe computes one stage with the kernel's own helpers and Q
formats, over a whole array of samples; it does not change the kernel, and a test checks each probe against
the kernel's state after the stage (``tests/firmware_sim/test_pic_logger.py``).

Probes
------
:func:`calibrated_axes`
    Step 1, calibration: ``c = requant(code, 0, code_frac) - offset`` (16 bits, saturating), then per row
    the kernel's ``_calibrated`` (three 16 x 16 products summed with saturation in 32 bits, rounded half up
    to Q2.13 g and saturated to 16 bits).
:func:`gravity_states`
    Step 2, gravity: the two exponential stages ``G1``, ``G2`` (Q2.29) after each sample of one run, from
    the calibrated axes, with the warm-up shift of ``kernel._front``.
:func:`vertical_acceleration`
    Step 3: ``a_v = (f·g - |g|^2) / |g|`` (Q2.13 g; 0 when ``|g|`` is at most ``G_MIN``).
:func:`detector_trace`
    Steps 4-5: the kernel itself (:class:`~gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm`) fed
    one sample at a time, its state read after each: y3 (the kernel's ``_fir`` on its delay line, run
    uncompiled), the detector's slots (:data:`DETECTOR_FIELDS`) and each call of ``_finalise``
    (:data:`CALL_FIELDS`).
:func:`finalise_calls`
    Step 6: the inputs of every ``_finalise`` call of a run (the foot-flats, the state's ``LAST`` and ``FLAGS``,
    the sticky saturation flag), each call's counted cycles, the run's a_v and the records the calls wrote
    (``tests/firmware_sim/test_pic_step_record.py`` checks them against the kernel's own run).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gaitlog.firmware_sim.algorithms import arithmetic as ar
from gaitlog.firmware_sim.algorithms import kernel
from gaitlog.firmware_sim.algorithms.calibration import CalibrationQ
from gaitlog.firmware_sim.algorithms.formats import F_ACC, F_ACC2, F_GRAV, W16, W32, centred_q
from gaitlog.firmware_sim.algorithms.online import OnlineConfig, OnlineStepAlgorithm
from gaitlog.firmware_sim.algorithms.state import (
    AMP,
    DIST,
    DUR_POS,
    F_LAST,
    F_OLD,
    F_PEND_WEAK,
    FLAGS,
    INDEX_MASK,
    LAST,
    LINE_POS,
    MN,
    MX,
    MXPOS,
    N_DUR,
    PEND,
    PEND_Y,
    RAW,
    RAW_Y,
    N,
)
from gaitlog.firmware_sim.compiled import load_numba, njit
from gaitlog.firmware_sim.fixedpoint import C_CYCLES, C_STICKY, N_COUNTERS, OP_DEE, OP_I2C, OPS, new_counters, s_cost
from gaitlog.protocol.steps import STEP_RECORD_DTYPE, StepConfig, pack_step_records

__all__ = ["calibrated_axes", "gravity_states", "vertical_acceleration", "front_operation_counts", "online_config",
           "DETECTOR_FIELDS", "CALL_FIELDS", "DetectorTrace", "detector_trace", "step_records", "FinaliseTrace",
           "finalise_calls", "OperationCounts", "algorithm_operation_counts", "scratch_writes"]


@njit(cache=True)
def _calibrated_axes(codes, cfg_i, cfg_v, out, cnt, trace):  # pragma: no cover - compiled
    cf = cfg_i[kernel.CI_CODE_FRAC]
    mf = cfg_i[kernel.CI_MANT_FRAC]
    for i in range(codes.shape[0]):
        # kernel._front, step 1, line for line
        c0 = ar.sub(ar.requant(codes[i, 0], 0, cf, W16, cnt), cfg_v[kernel.CV_OFF + 0], W16, cnt)
        c1 = ar.sub(ar.requant(codes[i, 1], 0, cf, W16, cnt), cfg_v[kernel.CV_OFF + 1], W16, cnt)
        c2 = ar.sub(ar.requant(codes[i, 2], 0, cf, W16, cnt), cfg_v[kernel.CV_OFF + 2], W16, cnt)
        for row in range(3):
            out[i, row] = kernel._calibrated(cfg_v, row, c0, c1, c2, mf, cf, cnt)
        s_cost(cnt, OP_DEE, 25)                  # offsets, mantissas, exponent from the data EEPROM
        trace[i, :] = cnt


def calibrated_axes(codes: np.ndarray, calibration: CalibrationQ) -> np.ndarray:
    """Step 1 of the fixed-point kernel on every sample: ``(n, 3)`` int64 calibrated axes, raw Q2.13 g.

    Parameters
    ----------
    codes
        ``(n, 3)`` ADC codes (counts).
    calibration
        The calibration as the PIC keeps it (:class:`~gaitlog.firmware_sim.algorithms.calibration.CalibrationQ`).

    Examples
    --------
    >>> from gaitlog.firmware_sim.algorithms.calibration import nominal_calibration_q
    >>> calibrated_axes(np.array([[512, 768, 256]]), nominal_calibration_q()).tolist()   # 0, +1, -1 g
    [[0, 8192, -8192]]
    """
    c = np.ascontiguousarray(codes, dtype=np.int64).reshape(-1, 3)
    return _calibrated_traced(c, calibration)[0]


def _calibrated_traced(c: np.ndarray, calibration: CalibrationQ) -> tuple[np.ndarray, np.ndarray]:
    cfg_i = np.zeros(kernel.N_CI, np.int64)
    cfg_i[kernel.CI_CODE_FRAC] = centred_q(calibration.adc_bits).frac_bits
    cfg_i[kernel.CI_MANT_FRAC] = calibration.matrix_frac_bits
    cfg_v = np.zeros(kernel.CV_M + 9, np.int64)
    cfg_v[kernel.CV_OFF:kernel.CV_OFF + 3] = calibration.offset_raw
    cfg_v[kernel.CV_M:kernel.CV_M + 9] = np.asarray(calibration.mantissa_raw, np.int64).reshape(9)
    out = np.zeros((c.shape[0], 3), np.int64)
    trace = np.zeros((c.shape[0], N_COUNTERS), np.int64)
    _calibrated_axes(c, cfg_i, cfg_v, out, new_counters(), trace)
    return out, _per_sample(trace)


@njit(cache=True)
def _gravity(f, g_shift, out, cnt, trace):  # pragma: no cover - compiled
    g1 = np.zeros(3, np.int64)
    g2 = np.zeros(3, np.int64)
    for n in range(f.shape[0]):
        # kernel._front, step 2, line for line (n: the samples of the run before this one)
        warm = 0
        while (2 << warm) <= n + 1 and warm < g_shift:
            warm += 1
        for axis in range(3):
            g1[axis] = ar.add(g1[axis], ar.scale2(ar.sub(ar.requant(f[n, axis], F_ACC, F_GRAV, W32, cnt), g1[axis],
                                                         W32, cnt), -warm, W32, cnt), W32, cnt)
            g2[axis] = ar.add(g2[axis], ar.scale2(ar.sub(g1[axis], g2[axis], W32, cnt), -warm, W32, cnt), W32, cnt)
            out[n, axis] = g1[axis]
            out[n, 3 + axis] = g2[axis]
        trace[n, :] = cnt


def gravity_states(calibrated: np.ndarray, gravity_shift: int) -> np.ndarray:
    """Step 2 of the fixed-point kernel over one run (from START): ``(n, 6)`` int64 ``G1``, ``G2`` after each
    sample, raw Q2.29 g.

    Parameters
    ----------
    calibrated
        ``(n, 3)`` calibrated axes, raw Q2.13 (:func:`calibrated_axes`).
    gravity_shift
        The kernel's ``G_SHIFT`` (``OnlineConfig.cfg_i[kernel.CI_G_SHIFT]``).

    Examples
    --------
    >>> gravity_states(np.array([[8192, 0, 0], [0, 0, 0]]), 6)[:, [0, 3]].tolist()   # G1x, G2x: 1 g, then the mean
    [[536870912, 536870912], [268435456, 402653184]]
    """
    f = np.ascontiguousarray(calibrated, dtype=np.int64).reshape(-1, 3)
    return _gravity_traced(f, gravity_shift)[0]


def _gravity_traced(f: np.ndarray, gravity_shift: int) -> tuple[np.ndarray, np.ndarray]:
    out = np.zeros((f.shape[0], 6), np.int64)
    trace = np.zeros((f.shape[0], N_COUNTERS), np.int64)
    _gravity(f, int(gravity_shift), out, new_counters(), trace)
    return out, _per_sample(trace)


@njit(cache=True)
def _vertical(f, g2, g_min, out, cnt, trace):  # pragma: no cover - compiled
    for n in range(f.shape[0]):
        fx, fy, fz = f[n, 0], f[n, 1], f[n, 2]
        # kernel._front, step 3, line for line
        gx = ar.requant(g2[n, 0], F_GRAV, F_ACC, W16, cnt)
        gy = ar.requant(g2[n, 1], F_GRAV, F_ACC, W16, cnt)
        gz = ar.requant(g2[n, 2], F_GRAV, F_ACC, W16, cnt)
        norm2 = ar.add(ar.add(ar.mul(gx, F_ACC, gx, F_ACC, F_ACC2, W32, cnt),
                              ar.mul(gy, F_ACC, gy, F_ACC, F_ACC2, W32, cnt), W32, cnt),
                       ar.mul(gz, F_ACC, gz, F_ACC, F_ACC2, W32, cnt), W32, cnt)
        gn = ar.sqrt(norm2, F_ACC2, F_ACC, True, cnt)
        av = fx * 0
        if gn > g_min:
            av = ar.div(ar.sub(ar.add(ar.add(ar.mul(fx, F_ACC, gx, F_ACC, F_ACC2, W32, cnt),
                                             ar.mul(fy, F_ACC, gy, F_ACC, F_ACC2, W32, cnt), W32, cnt),
                                      ar.mul(fz, F_ACC, gz, F_ACC, F_ACC2, W32, cnt), W32, cnt), norm2, W32, cnt),
                        F_ACC2, gn, F_ACC, F_ACC, W16, cnt)
        out[n] = av
        trace[n, :] = cnt


def vertical_acceleration(calibrated: np.ndarray, gravity2: np.ndarray, min_gravity_raw: int) -> np.ndarray:
    """Step 3 of the fixed-point kernel on every sample: ``(n,)`` int64 a_v, raw Q2.13 g.

    Parameters
    ----------
    calibrated
        ``(n, 3)`` calibrated axes, raw Q2.13 (:func:`calibrated_axes`).
    gravity2
        ``(n, 3)`` the second gravity stage after each sample, raw Q2.29 (:func:`gravity_states`' last columns).
    min_gravity_raw
        The kernel's ``G_MIN`` (raw Q2.13).

    Raises
    ------
    ValueError
        As the kernel: ``|g|`` beyond a signed 16-bit divisor (a calibration far outside the sensor's range).

    Examples
    --------
    >>> vertical_acceleration(np.array([[0, 0, 16384], [0, 0, 0]]), np.array([[0, 0, 1 << 29]] * 2), 1638).tolist()
    [8192, -8192]
    """
    f = np.ascontiguousarray(calibrated, dtype=np.int64).reshape(-1, 3)
    g = np.ascontiguousarray(gravity2, dtype=np.int64).reshape(-1, 3)
    return _vertical_traced(f, g, min_gravity_raw)[0]


def _vertical_traced(f: np.ndarray, g: np.ndarray, min_gravity_raw: int) -> tuple[np.ndarray, np.ndarray]:
    out = np.zeros(f.shape[0], np.int64)
    trace = np.zeros((f.shape[0], N_COUNTERS), np.int64)
    _vertical(f, g, int(min_gravity_raw), out, new_counters(), trace)
    return out, _per_sample(trace)


def _per_sample(trace: np.ndarray) -> np.ndarray:
    """Each sample's calls per primitive (``(n, len(OPS))``) from the counters after each sample."""
    calls = trace[:, :len(OPS)]
    return np.diff(calls, axis=0, prepend=np.zeros((1, len(OPS)), np.int64))


def front_operation_counts(codes: np.ndarray, calibration: CalibrationQ, gravity_shift: int, min_gravity_raw: int,
                           run_starts: list[int] | tuple[int, ...] = (0,)) -> tuple[np.ndarray, np.ndarray]:
    """The model's primitive calls per sample in steps 1-3, as the kernel counts them: ``(stage 1, stages 2-3)``,
    each ``(n, len(OPS))`` int64 (columns in :data:`~gaitlog.firmware_sim.fixedpoint.OPS` order). Step 2 restarts
    at each of ``run_starts`` (the runs' first samples, 0 first). The cycle budget prices them.

    Examples
    --------
    >>> from gaitlog.firmware_sim.algorithms.calibration import nominal_calibration_q
    >>> from gaitlog.firmware_sim.fixedpoint import OPS
    >>> s1, s23 = front_operation_counts(np.array([[512, 768, 256]] * 2), nominal_calibration_q(), 6, 1638)
    >>> int(s1[0, OPS.index("mul16x16s")]), int(s23[1, OPS.index("isqrt32")])    # 3 x 3 products, one root
    (9, 1)
    """
    c = np.ascontiguousarray(codes, dtype=np.int64).reshape(-1, 3)
    f, stage1 = _calibrated_traced(c, calibration)
    bounds = list(run_starts) + [c.shape[0]]
    parts = [_gravity_traced(f[a:b], gravity_shift) for a, b in zip(bounds, bounds[1:]) if b > a]
    g = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 6), np.int64)
    stage2 = np.concatenate([p[1] for p in parts]) if parts else np.zeros((0, len(OPS)), np.int64)
    return stage1, stage2 + _vertical_traced(f, np.ascontiguousarray(g[:, 3:]), min_gravity_raw)[1]


# ---------------------------------------------------------------------------------------------------------
# steps 4-5

#: The detector's state compared after each sample (the kernel's slots; the durations ring ``d0 ..`` follows).
DETECTOR_FIELDS = ("mn", "mx", "mxpos", "pend", "pend_y", "last", "raw", "raw_y", "amp", "dist", "n_dur", "dur_pos",
                   "flags", "n", "line_pos")
_DETECTOR_SLOTS = (("v", MN), ("v", MX), ("i", MXPOS), ("i", PEND), ("v", PEND_Y), ("i", LAST), ("i", RAW),
                   ("v", RAW_Y), ("v", AMP), ("i", DIST), ("i", N_DUR), ("i", DUR_POS), ("i", FLAGS), ("i", N),
                   ("i", LINE_POS))
#: A call of ``_finalise``: the sample (from the run's first), the foot-flat ``e``, the previous one ``s`` (the
#: ``LAST`` slot as it stands), the newest output ``m``, and the flags the step reads (``F_LAST``,
#: ``F_PEND_WEAK``, ``F_OLD``).
CALL_FIELDS = ("sample", "e", "s", "m", "flags")
#: Leg and foot of the step configuration the trace runs with (steps 4-5 do not read it; ``_finalise`` does).
_TRACE_LEG_M, _TRACE_FOOT_M = 0.9, 0.26


def online_config(sampling_rate_hz: float):
    """The on-line algorithm's fixed-point configuration at ``sampling_rate_hz`` with the default parameters
    (:class:`~gaitlog.firmware_sim.algorithms.online.OnlineConfig`; the nominal calibration)."""
    return OnlineConfig.build(sampling_rate_hz=sampling_rate_hz, step_config=StepConfig(
        step_format=1, leg_length_m=_TRACE_LEG_M, foot_length_m=_TRACE_FOOT_M))


@dataclass(frozen=True)
class DetectorTrace:
    """:func:`detector_trace`'s result.

    Attributes
    ----------
    y3, ready
        ``(n,)`` int64: the 3 Hz FIR output (raw Q2.16; 0 where there is none) and bool: whether the sample has one.
    state
        ``(n, len(DETECTOR_FIELDS) + median_steps)`` int64: the detector's slots after each sample, then the
        durations ring.
    calls
        ``(k, len(CALL_FIELDS))`` int64: each call of ``_finalise``, while the samples were fed and at each run's
        STOP (``flush``; its sample is the run's end: its last sample's index + 1).
    """

    y3: np.ndarray
    ready: np.ndarray
    state: np.ndarray
    calls: np.ndarray
    #: ``(k, 20)`` uint8: the step records the calls made, packed as the device stores them (CRC included),
    #: their end sample counted from their run's START
    records: np.ndarray = field(default_factory=lambda: np.zeros((0, 20), np.uint8))


def _trace_algorithm(calibration: CalibrationQ, sampling_rate_hz: float, scratch_ring: int) -> OnlineStepAlgorithm:
    """The fixed-point kernel as the PIC runs it: the PIC's calibration as is, the trace's step configuration and
    (``scratch_ring`` > 0) a scratch ring of that many samples."""
    algo = OnlineStepAlgorithm(sampling_rate_hz=sampling_rate_hz, step_config=StepConfig(
        step_format=1, leg_length_m=_TRACE_LEG_M, foot_length_m=_TRACE_FOOT_M))
    cfg_i, cfg_v = algo.config.cfg_i, algo.config.cfg_v
    cfg_v[kernel.CV_OFF:kernel.CV_OFF + 3] = calibration.offset_raw            # the PIC's calibration, as is
    cfg_v[kernel.CV_M:kernel.CV_M + 9] = np.asarray(calibration.mantissa_raw, np.int64).reshape(9)
    cfg_i[kernel.CI_MANT_FRAC] = calibration.matrix_frac_bits
    if scratch_ring:
        cfg_i[kernel.CI_SCRATCH] = scratch_ring
        algo._scr = np.zeros(scratch_ring, algo._scr.dtype)
    return algo


def step_records(codes: np.ndarray, calibration: CalibrationQ, sampling_rate_hz: float = 50.0,
                 run_starts: list[int] | tuple[int, ...] = (0,), scratch_ring: int = 0) -> np.ndarray:
    """The step records :func:`detector_trace` gives (``(k, 20)`` uint8, each end sample counted from its run's
    START), from the compiled kernel fed each run whole, then its STOP (``flush``: the pending foot-flat's
    record, as the PIC's ``step_flush`` writes it): what the PIC's records are checked against when only
    the records are compared (no per-sample state to read, so no sample-at-a-time loop)."""
    c = np.ascontiguousarray(codes, dtype=np.int64).reshape(-1, 3)
    algo = _trace_algorithm(calibration, sampling_rate_hz, scratch_ring)
    bounds = sorted(set(run_starts) | {0}) + [c.shape[0]]
    out = [np.zeros((0, 20), np.uint8)]
    for a, b in zip(bounds, bounds[1:]):
        algo.reset()
        for steps in (algo.feed(c[a:b]), algo.flush()):        # the run's samples, then its STOP
            if len(steps.end):
                out.append(np.frombuffer(pack_step_records(steps.to_records(0)), np.uint8).reshape(-1, 20))
    return np.concatenate(out)


def scratch_writes(codes: np.ndarray, calibration: CalibrationQ, sampling_rate_hz: float = 50.0,
                   scratch_ring: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """One run (START, ``codes``, STOP) of the compiled kernel: the write cycles of each scratch-ring page, counted
    from the run's first (:attr:`~gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm.scratch_page_writes`:
    the flushes and the tail writes), and each tail write's sample count (``N``; the run's length at STOP)."""
    algo = _trace_algorithm(calibration, sampling_rate_hz, scratch_ring)
    algo.reset()
    algo.feed(np.ascontiguousarray(codes, dtype=np.int64).reshape(-1, 3))
    algo.flush()
    return algo.scratch_page_writes, algo.scratch_tail_samples


def detector_trace(codes: np.ndarray, calibration: CalibrationQ, sampling_rate_hz: float = 50.0,
                   run_starts: list[int] | tuple[int, ...] = (0,), start_n: int = 0,
                   scratch_ring: int = 0) -> DetectorTrace:
    """Steps 4-5 of the fixed-point kernel on every sample: the kernel fed one sample at a time (runs restart
    at ``run_starts``), its y3, detector state and ``_finalise`` calls after each. ``start_n``: the kernel's
    ``N`` after each START (0; else a run that old, as the PIC test build's ``START_N``). ``scratch_ring``:
    the scratch ring's samples (a power of two; 0: the emulator's), as the PIC's EEPROM ring holds them.
    The records' end sample counts from ``N`` = 0 at START, as the PIC counts it (``start_n`` included).

    Examples
    --------
    >>> from gaitlog.firmware_sim.algorithms.calibration import nominal_calibration_q
    >>> t = detector_trace(np.full((20, 3), 512) + [0, 0, 256], nominal_calibration_q())     # still: 1 g on z
    >>> t.ready.tolist().index(True), int(t.y3[-1]), t.calls.shape   # r3 = 9 at 50 Hz: the 19th sample
    (18, 0, (0, 5))
    """
    c = np.ascontiguousarray(codes, dtype=np.int64).reshape(-1, 3)
    algo = _trace_algorithm(calibration, sampling_rate_hz, scratch_ring)
    cfg_i, cfg_v = algo.config.cfg_i, algo.config.cfg_v
    r3 = int(cfg_i[kernel.CI_R3])
    fir = kernel._fir.py_func
    records = []
    cnt = new_counters()
    n = c.shape[0]
    y3 = np.zeros(n, np.int64)
    ready = np.zeros(n, bool)
    state = np.zeros((n, len(DETECTOR_FIELDS) + int(cfg_i[kernel.CI_N_MED])), np.int64)
    calls = []
    starts = set(run_starts) | {0}
    for i in range(n):
        if i in starts:
            if i:
                _stop(algo, i, r3, calls, records)
            algo.reset()
            algo._st_i[N] = start_n
        prev = algo._st_i.copy()
        steps = algo.feed(c[i:i + 1])
        st_i, st_v = algo._st_i, algo._st_v
        ready[i] = bool(st_i[FLAGS] & F_OLD) or prev[N] >= 2 * r3
        if ready[i]:
            centre = (int(st_i[LINE_POS]) - 1 - r3) % (2 * r3 + 1)
            y3[i] = fir(algo._line, centre, 2 * r3 + 1, cfg_v, kernel.CV_W3, r3, cnt)
        state[i, :len(_DETECTOR_SLOTS)] = [st_v[k] if kind == "v" else st_i[k] for kind, k in _DETECTOR_SLOTS]
        state[i, len(_DETECTOR_SLOTS):] = algo._durs
        if len(steps.end):
            records.append(np.frombuffer(pack_step_records(steps.to_records(start_n)), np.uint8).reshape(-1, 20))
        for end in steps.end.tolist():
            e = int(prev[PEND])
            if ((end + start_n) & INDEX_MASK) != e:          # the driver counts from START
                raise AssertionError(f"sample {i}: the kernel's record ends at {end}, its pending foot-flat was {e}")
            calls.append([i, e, int(prev[LAST]), int((st_i[N] - 1 - r3) & INDEX_MASK),
                          int(prev[FLAGS] & (F_LAST | F_PEND_WEAK) | st_i[FLAGS] & F_OLD)])
    if n:
        _stop(algo, n, r3, calls, records)
    return DetectorTrace(y3, ready, state, np.asarray(calls, np.int64).reshape(-1, len(CALL_FIELDS)),
                         np.concatenate(records) if records else np.zeros((0, 20), np.uint8))


def _stop(algo, end: int, r3: int, calls: list, records: list) -> None:
    """STOP after a run whose last sample is ``end - 1``: ``flush``, its call (if it finalised the pending
    foot-flat) and record appended, as :func:`detector_trace` lists them."""
    prev = algo._st_i.copy()
    steps = algo.flush()
    if len(steps.end):
        records.append(np.frombuffer(pack_step_records(steps.to_records(0)), np.uint8).reshape(-1, 20))
        calls.append([end, int(prev[PEND]), int(prev[LAST]), int((prev[N] - 1 - r3) & INDEX_MASK),
                      int(prev[FLAGS] & (F_LAST | F_PEND_WEAK | F_OLD))])


# ---------------------------------------------------------------------------------------------------------
# step 6: the inputs of every _finalise call, traced while the kernel runs


@dataclass(frozen=True)
class FinaliseTrace:
    """Every call of the kernel's ``_finalise`` over one run, with what it was given and what it cost.

    Attributes
    ----------
    e, m, last, flags
        ``(k,)`` int64: the final foot-flat, the newest filter output, the state's ``LAST`` and ``FLAGS`` on entry
        (16-bit indices, as the kernel keeps them).
    sticky
        ``(k,)`` int64: the sticky saturation flag on entry (a saturation since the previous step).
    m_abs
        ``(k,)`` int64: the absolute sample number of ``m`` (``first_sample_number`` + its index in the run).
    cycles
        ``(k,)`` int64: the cycles the kernel counted inside the call (its cost model, I2C and data-EEPROM
        reads included).
    ops
        ``(k, len(OPS))`` int64: the primitives the kernel counted inside the call
        (:data:`~gaitlog.firmware_sim.fixedpoint.OPS` order).
    a_v
        ``(n,)`` int64: each sample's vertical acceleration (raw Q2.13), as the delay line and the scratch ring
        received it.
    records
        ``(k,)`` :data:`gaitlog.protocol.steps.STEP_RECORD_DTYPE`: the records (CRC set) the calls wrote.
    extras
        ``(k, 4)``: what the records do not store: the excursions h (M1, M2), h1 (M3) and M4's range (raw).
    """

    e: np.ndarray
    m: np.ndarray
    last: np.ndarray
    flags: np.ndarray
    sticky: np.ndarray
    m_abs: np.ndarray
    cycles: np.ndarray
    ops: np.ndarray
    a_v: np.ndarray
    records: np.ndarray
    extras: np.ndarray

    def subset(self, calls: np.ndarray) -> FinaliseTrace:
        """The calls at ``calls`` (indices or a mask), with the whole run's a_v."""
        c = np.asarray(calls)
        return FinaliseTrace(self.e[c], self.m[c], self.last[c], self.flags[c], self.sticky[c], self.m_abs[c],
                             self.cycles[c], self.ops[c], self.a_v, self.records[c], self.extras[c])


def finalise_calls(algorithm, codes: np.ndarray, *, first_sample_number: int = 0) -> FinaliseTrace:
    """Run a fixed-point :class:`~gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm` over one run of
    ``codes`` (``(n, 3)``; START before, STOP after, as its ``run`` does for one run) and trace each
    ``_finalise`` call.

    The per-sample driver (``kernel._sample``, ``_confirmed``, ``flush``) runs as Python (their ``py_func``)
    with ``_finalise`` wrapped; everything else, ``_finalise`` itself included, is the compiled kernel. The
    kernel is not edited: its module globals are swapped for the run and restored. A test checks that the
    records equal :meth:`~gaitlog.firmware_sim.algorithms.online.OnlineStepAlgorithm.run`'s.
    """
    if algorithm.arithmetic != "fixed":
        raise ValueError("the trace is of the fixed-point kernel (the PIC's)")
    c = np.ascontiguousarray(codes, dtype=np.int64).reshape(-1, 3)
    load_numba()       # the kernel's module globals become numba's dispatchers before two are swapped below: an
    algorithm.reset()  # ahead-of-time kernel loads no numba, and a swap over a lazy one would restore it unloaded
    cfg_i, cfg_v = algorithm.config.cfg_i, algorithm.config.cfg_v
    st_i, st_v, line, durs, scr, cnt = (algorithm._st_i, algorithm._st_v, algorithm._line, algorithm._durs,
                                        algorithm._scr, algorithm._cnt)
    r3 = int(cfg_i[kernel.CI_R3])
    out_i, out_v = algorithm._outputs(c.shape[0])
    rows: list[tuple[int, ...]] = []
    ops: list[np.ndarray] = []
    where = {"row": 0}
    real = kernel._finalise

    def traced(e, m, cfg_i, cfg_v, st_i, st_v, scr, out_i, out_v, k, cnt):
        before = int(cnt[C_CYCLES])
        ops_before = cnt[:len(OPS)].copy()
        entry = (int(e), int(m), int(st_i[LAST]), int(st_i[FLAGS]), int(cnt[C_STICKY]),
                 int(first_sample_number) + where["row"] - r3)
        k = real(e, m, cfg_i, cfg_v, st_i, st_v, scr, out_i, out_v, k, cnt)
        rows.append(entry + (int(cnt[C_CYCLES]) - before,))
        ops.append(cnt[:len(OPS)] - ops_before)
        return k

    saved = {name: getattr(kernel, name) for name in ("_finalise", "_confirmed")}
    a_v = np.zeros(c.shape[0], np.int64)
    k = 0
    try:
        kernel._finalise = traced
        kernel._confirmed = getattr(saved["_confirmed"], "py_func", saved["_confirmed"])
        sample = kernel._sample.py_func
        for row in range(c.shape[0]):
            where["row"] = row
            cnt[C_CYCLES] = 0
            k = sample(c[row, 0], c[row, 1], c[row, 2], cfg_i, cfg_v, st_i, st_v, line, durs, scr, out_i, out_v,
                       k, cnt)
            a_v[row] = line[(int(st_i[LINE_POS]) - 1) % line.size]
        where["row"] = c.shape[0] - 1
        k = kernel.flush.py_func(cfg_i, cfg_v, st_i, st_v, scr, out_i, out_v, k, cnt)
    finally:
        for name, fn in saved.items():
            setattr(kernel, name, fn)
    algorithm._fed = c.shape[0]
    steps = algorithm._steps(out_i, out_v, k, 0)
    recs = steps.to_records(first_sample_number)
    recs = np.frombuffer(pack_step_records(recs), dtype=STEP_RECORD_DTYPE).copy() if recs.size else recs
    t = np.asarray(rows, np.int64).reshape(-1, 7)
    return FinaliseTrace(*(t[:, i].copy() for i in range(7)), ops=np.asarray(ops, np.int64).reshape(-1, len(OPS)),
                         a_v=a_v, records=recs, extras=np.asarray(steps.extras, np.int64).reshape(-1, 4))


# ---------------------------------------------------------------------------------------------------------
# the whole algorithm's primitive calls per sample (the cycle budget prices them)


@dataclass(frozen=True)
class OperationCounts:
    """:func:`algorithm_operation_counts`' result: each sample's primitive calls per step of the algorithm, each
    ``(n, len(OPS))`` int64 (columns in :data:`~gaitlog.firmware_sim.fixedpoint.OPS` order), and the samples
    whose step 5 wrote a step record."""

    step1: np.ndarray
    steps23: np.ndarray
    step4: np.ndarray
    step5: np.ndarray
    record_samples: np.ndarray


def algorithm_operation_counts(codes: np.ndarray, calibration: CalibrationQ, sampling_rate_hz: float = 50.0,
                               run_starts: list[int] | tuple[int, ...] = (0,), *, gravity_shift: int,
                               min_gravity_raw: int, scratch_ring: int = 0) -> OperationCounts:
    """The model's primitive calls per sample in each step, as the kernel counts them: steps 1-3 from
    :func:`front_operation_counts`; steps 4-5 from the kernel fed one sample at a time (as
    :func:`detector_trace`), less steps 1-3. Step 4 is the 3 Hz FIR (one evaluation and the prominence's
    data-EEPROM bytes on each sample with an output) and the scratch ring's page write (every ``CI_FLUSH``
    samples); step 5, the rest (the detector, ``_finalise`` and its step record)."""
    c = np.ascontiguousarray(codes, dtype=np.int64).reshape(-1, 3)
    s1, s23 = front_operation_counts(c, calibration, gravity_shift, min_gravity_raw, run_starts)
    algo = OnlineStepAlgorithm(sampling_rate_hz=sampling_rate_hz, step_config=StepConfig(
        step_format=1, leg_length_m=_TRACE_LEG_M, foot_length_m=_TRACE_FOOT_M))
    cfg_i, cfg_v = algo.config.cfg_i, algo.config.cfg_v
    cfg_v[kernel.CV_OFF:kernel.CV_OFF + 3] = calibration.offset_raw
    cfg_v[kernel.CV_M:kernel.CV_M + 9] = np.asarray(calibration.mantissa_raw, np.int64).reshape(9)
    cfg_i[kernel.CI_MANT_FRAC] = calibration.matrix_frac_bits
    if scratch_ring:
        cfg_i[kernel.CI_SCRATCH] = scratch_ring
        algo._scr = np.zeros(scratch_ring, algo._scr.dtype)
    n = c.shape[0]
    whole = np.zeros((n, len(OPS)), np.int64)
    ready = np.zeros(n, bool)
    flush = np.zeros(n, bool)
    records = []
    starts = set(run_starts) | {0}
    r3, every = int(cfg_i[kernel.CI_R3]), int(cfg_i[kernel.CI_FLUSH])
    for i in range(n):
        if i in starts:
            algo.reset()
        before, n_before, flags_before = algo._cnt[:len(OPS)].copy(), int(algo._st_i[N]), int(algo._st_i[FLAGS])
        if len(algo.feed(c[i:i + 1]).end):
            records.append(i)
        whole[i] = algo._cnt[:len(OPS)] - before
        ready[i] = bool(flags_before & F_OLD) or n_before >= 2 * r3
        flush[i] = (n_before + 1) % every == 0
    fir_ops = new_counters()
    kernel._fir.py_func(np.zeros(2 * r3 + 1, algo._line.dtype), 0, 2 * r3 + 1, cfg_v, kernel.CV_W3, r3, fir_ops)
    one_fir = fir_ops[:len(OPS)].copy()
    one_fir[OP_DEE] += 3                                                # the prominence, read with the output
    write = np.zeros(len(OPS), np.int64)
    write[OP_I2C] = kernel.SCRATCH_SAMPLE_BYTES * every + kernel.I2C_WRITE_OVERHEAD
    s4 = ready[:, None] * one_fir + flush[:, None] * write
    s5 = whole - s1 - s23 - s4
    if np.any(s5 < 0):
        raise AssertionError("the kernel counted fewer calls than steps 1-4 make")
    return OperationCounts(s1, s23, s4, s5, np.asarray(records, np.int64))
