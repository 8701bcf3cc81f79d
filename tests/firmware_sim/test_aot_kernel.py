"""The compiled layer: numba loaded only when a compiled function runs, the small-array Python path of the
PIC arithmetic equal to its compiled loops, the on-line kernel compiled ahead of time equal to numba's JIT bit
for bit, its build on first use (one builder, the others wait), its fallback, and the cache's pruning."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim import compiled, fixedpoint
from gaitlog.firmware_sim.algorithms import aot_kernel, kernel
from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm
from gaitlog.firmware_sim.fixedpoint import ArithmeticContext, QFormat
from gaitlog.protocol.header import CalibrationSlot
from gaitlog.protocol.steps import StepConfig

ROOT = Path(__file__).resolve().parents[2]
STEP_CONFIG = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)


def _child(script: str, **env: str) -> dict:
    """Run ``script`` in a fresh interpreter (this checkout first on the path); its last stdout line as JSON."""
    e = {k: v for k, v in os.environ.items() if k not in ("NUMBA_DISABLE_JIT", "GAITLOG_NO_AOT")}
    e.update(env, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", script], env=e, capture_output=True, text=True, timeout=900,
                         check=False)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def _aot_or_skip() -> None:
    if not aot_kernel.enabled():
        pytest.skip("the ahead-of-time kernel is off (GAITLOG_NO_AOT or NUMBA_DISABLE_JIT)")
    if aot_kernel.entry_points("fixed")[1] != "aot":
        failed = aot_kernel.aot_dir().with_name(aot_kernel.aot_dir().name + ".failed")
        reason = failed.read_text().strip() if failed.exists() else "unknown"
        pytest.skip(f"the ahead-of-time kernel could not be built here: {reason}")


# ---------------------------------------------------------------------------------------------------------
# the PIC arithmetic's two paths


def _both_paths(fn):
    """``fn(ctx)`` through the Python text and through the compiled loops: results and contexts."""
    saved = fixedpoint.PYTHON_MAX_ELEMENTS
    try:
        runs = []
        for limit in (1 << 40, -1):
            fixedpoint.PYTHON_MAX_ELEMENTS = limit
            ctx = ArithmeticContext()
            runs.append((fn(ctx), ctx))
    finally:
        fixedpoint.PYTHON_MAX_ELEMENTS = saved
    return runs


def test_python_text_and_compiled_loops_give_the_same_bits_and_counts() -> None:
    rng = np.random.default_rng(11)
    edges16 = np.array([-32768, -32767, -16385, -16384, -1, 0, 1, 16383, 16384, 32766, 32767], np.int64)
    a16 = np.concatenate([edges16, rng.integers(-32768, 32768, 3000)])
    b16 = rng.permutation(a16)
    e32 = np.array([-(1 << 31), -(1 << 31) + 1, -1, 0, 1, (1 << 31) - 1], np.int64)
    a32 = np.concatenate([e32, rng.integers(-(1 << 31), 1 << 31, 3000)])
    d16 = np.concatenate([np.zeros(6, np.int64), rng.integers(-32768, 32768, 3000)])
    u32 = np.concatenate([np.array([0, 1, 2, 3, (1 << 32) - 1], np.int64), rng.integers(0, 1 << 32, 3000)])
    real = np.concatenate([np.array([0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 1e300, -1e300, 2.0 ** 62, 5e-324]),
                           rng.normal(0.0, 3e4, 3000)])
    q32, q16 = QFormat(15, 16, word_bits=32), QFormat(7, 8)
    cases = {
        "saturate": lambda c: fixedpoint.saturate(a32, 16, ctx=c),
        "wrap": lambda c: fixedpoint.wrap(a32, 8, signed=False, ctx=c),
        "shift_right": lambda c: fixedpoint.shift_right(a32, 7, ctx=c),
        "shift_right_floor": lambda c: fixedpoint.shift_right(a32, 7, rounding="floor", ctx=c),
        "shift_left": lambda c: fixedpoint.shift_left(a16, 3, 16, overflow="wrap", ctx=c),
        "requantize_down": lambda c: fixedpoint.requantize(a32, q32, q16, ctx=c),
        "requantize_up": lambda c: fixedpoint.requantize(a16, q16, q32, overflow="wrap", ctx=c),
        "add": lambda c: fixedpoint.add(a16, b16, 16, ctx=c),
        "sub_wrap": lambda c: fixedpoint.sub(a16, b16, 16, overflow="wrap", ctx=c),
        "cumsum": lambda c: fixedpoint.cumsum(a16, 16, ctx=c),
        "mul": lambda c: fixedpoint.mul(a16, b16, ctx=c),
        "mul_q": lambda c: fixedpoint.mul_q(a16, b16, 15, QFormat(0, 15), ctx=c),
        "mul_q_unsigned_out": lambda c: fixedpoint.mul_q(a16, b16, 14, QFormat(1, 15, signed=False), ctx=c),
        "div": lambda c: fixedpoint.div(a32, d16[: a32.size], 16, ctx=c),
        "div_round": lambda c: fixedpoint.div_round(a32, d16[: a32.size], ctx=c),
        "isqrt": lambda c: fixedpoint.isqrt(u32, rounding="nearest", ctx=c),
        "from_float": lambda c: q32.from_float(real, ctx=c),
        "from_float_floor_wrap": lambda c: q16.from_float(real, rounding="floor", overflow="wrap", ctx=c),
    }
    for name, fn in cases.items():
        (py, py_ctx), (jit, jit_ctx) = _both_paths(fn)
        for p, j in zip(py if isinstance(py, tuple) else (py,), jit if isinstance(jit, tuple) else (jit,)):
            assert p.dtype == j.dtype == np.int64 and np.array_equal(p, j), name
        assert py_ctx == jit_ctx, name


def test_from_float_saturates_huge_values_towards_their_sign() -> None:
    # compiled, the floor of a float beyond int64 was undefined: 1e300 came out as the word's minimum
    q = QFormat(15, 16, word_bits=32)
    for (out, _ctx) in _both_paths(lambda c: q.from_float(np.tile([1e300, -1e300, 1e19], 100), ctx=c)):
        assert out[:3].tolist() == [q.max_raw, q.min_raw, q.max_raw]


# ---------------------------------------------------------------------------------------------------------
# numba only when a compiled function runs


def test_configuring_the_algorithm_imports_no_numba() -> None:
    got = _child(
        "import json, sys\n"
        "from gaitlog.firmware_sim.algorithms.online import OnlineConfig\n"
        "from gaitlog.protocol.header import CalibrationSlot\n"
        "from gaitlog.protocol.steps import StepConfig\n"
        "cal = CalibrationSlot([510.0, 515.5, 508.25], [[0.0039, 1e-5, 0], [0, 0.00391, -2e-5], "
        "[0, 0, 0.0038]])\n"
        "sc = StepConfig(step_format=1, leg_length_m=0.93, foot_length_m=0.21)\n"
        "for a in ('fixed', 'float'):\n"
        "    OnlineConfig.build(sampling_rate_hz=50.0, step_config=sc, calibration=cal, arithmetic=a)\n"
        "    OnlineConfig.build(sampling_rate_hz=100.0, step_config=sc, adc_bits=12, arithmetic=a)\n"
        "print(json.dumps('numba' in sys.modules))\n")
    assert got is False


def test_lazy_functions_compile_together_on_first_call() -> None:
    assert hasattr(kernel.process, "py_func") and hasattr(kernel.reset, "py_func")
    got = _child(
        "import json, sys\n"
        "from gaitlog.firmware_sim.algorithms import kernel\n"
        "from gaitlog.firmware_sim.compiled import LazyDispatcher\n"
        "before = isinstance(kernel._sample, LazyDispatcher), 'numba' in sys.modules\n"
        "lazy = kernel.reset\n"
        "import numpy as np\n"
        "n = len(kernel.CI)\n"
        "lazy(np.zeros(n, np.int64), np.zeros(64, np.int64), np.zeros(64, np.int64), np.zeros(8, np.int64), "
        "np.zeros(4, np.int64))\n"
        "print(json.dumps([*before, type(kernel._sample).__name__, 'numba' in sys.modules]))\n",
        GAITLOG_NO_AOT="1")
    assert got == [True, False, "CPUDispatcher", True]


# ---------------------------------------------------------------------------------------------------------
# the kernel compiled ahead of time


def _run_both(codes: np.ndarray, arithmetic: str, calibration: object | None) -> list[OnlineStepAlgorithm]:
    algs = []
    for jit in (False, True):
        alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=STEP_CONFIG, calibration=calibration,
                                  arithmetic=arithmetic)
        if jit:
            alg._process, alg._flush, alg._reset = kernel.process, kernel.flush, kernel.reset
        alg.steps = alg.run(codes)
        algs.append(alg)
    return algs


@pytest.mark.parametrize("arithmetic", ["fixed", "float"])
def test_aot_kernel_equals_the_jit_bit_for_bit(simulated_walk: tuple, arithmetic: str) -> None:
    _aot_or_skip()
    codes, _ = simulated_walk
    rng = np.random.default_rng(5)
    rough = np.clip(codes[:20000] + rng.integers(-150, 151, (20000, 3)), 0, 1023)   # saturating, odd steps
    cal = CalibrationSlot([511.0, 514.5, 509.25], [[0.0039, 2e-5, 0], [0, 0.00392, -3e-5],
                                                              [1e-5, 0, 0.0038]])
    for c, calibration in ((codes, None), (codes, cal), (rough, cal)):
        aot, jit = _run_both(c, arithmetic, calibration)
        assert aot.compiled_by == "aot"
        assert aot.steps.n_steps > 10
        for f in ("end", "duration", "toe_off", "heel_strike", "flags", "lengths", "extras"):
            assert np.array_equal(getattr(aot.steps, f), getattr(jit.steps, f)), f
        for f in ("_st_i", "_st_v", "_line", "_durs", "_scr", "_cnt", "_cyc"):
            assert np.array_equal(getattr(aot, f), getattr(jit, f)), f


@pytest.mark.parametrize("compiled_by", ["aot", "jit"])
def test_the_kernel_releases_the_gil_while_it_runs(simulated_walk: tuple, compiled_by: str,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Python runs in this thread while another is inside the kernel's call: this thread's loop runs in the middle
    half of the call (with the GIL held through the call it runs only at its ends, at a switch of the GIL just
    before the call or just after: measured 0 times in the middle half)."""
    if compiled_by == "aot":
        _aot_or_skip()
    else:
        monkeypatch.setitem(aot_kernel._ENTRY_POINTS, "fixed", (tuple(
            aot_kernel.EntryPoint(n, "fixed", getattr(kernel, n)) for n in aot_kernel.ENTRY_POINTS), "jit"))
    codes = np.ascontiguousarray(np.concatenate([simulated_walk[0]] * 3), dtype=np.int64)
    alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=STEP_CONFIG)
    assert alg.compiled_by == compiled_by
    alg.run(codes[:64])                                  # compiled (the JIT) here, not in the call timed below
    out_i, out_v = alg._outputs(codes.shape[0])
    c = alg.config
    args = (codes, c.cfg_i, c.cfg_v, alg._st_i, alg._st_v, alg._line, alg._durs, alg._scr, out_i, out_v, 0,
            alg._cnt, alg._cyc)
    span: list[float] = []

    def work() -> None:
        span.append(time.perf_counter())
        alg._process(*args)
        span.append(time.perf_counter())

    worker = threading.Thread(target=work)
    seen: list[float] = []
    worker.start()
    while worker.is_alive():
        seen.append(time.perf_counter())
    worker.join()
    d = span[1] - span[0]
    assert d > 0.02                                      # a long call: 3 walks, ~50 ms
    assert any(span[0] + d / 4 < t < span[1] - d / 4 for t in seen)


def test_estimate_loads_the_aot_kernel_without_numba(tmp_path: Path) -> None:
    _aot_or_skip()
    codes = np.full((3000, 3), 512, np.int64)
    codes[:, 2] = 768 + (25 * np.sin(np.arange(3000) * 2 * np.pi / 25)).astype(np.int64)   # 1 g, 2 steps/s
    np.save(tmp_path / "codes.npy", codes)
    got = _child(
        "import json, sys, numpy as np\n"
        "from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm\n"
        "from gaitlog.protocol.steps import StepConfig\n"
        "sc = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)\n"
        f"codes = np.load({str(tmp_path / 'codes.npy')!r})\n"
        "out = []\n"
        "for a in ('fixed', 'float'):\n"
        "    alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=sc, arithmetic=a)\n"
        "    out.append([alg.compiled_by, alg.run(codes).n_steps])\n"
        "print(json.dumps([out, 'numba' in sys.modules]))\n")
    assert got[1] is False
    assert [c for c, _ in got[0]] == ["aot", "aot"] and all(n > 50 for _, n in got[0])


def test_an_algorithm_pickles_and_runs_on_in_its_receiver(simulated_walk: tuple) -> None:
    codes, _ = simulated_walk
    alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, step_config=STEP_CONFIG)
    first = alg.feed(codes[:30000])
    copy = pickle.loads(pickle.dumps(alg))
    a, b = alg.feed(codes[30000:]), copy.feed(codes[30000:])
    assert first.n_steps > 10 and a.n_steps > 10
    assert np.array_equal(a.end, b.end) and np.array_equal(a.lengths, b.lengths)


def test_no_aot_and_a_failed_build_use_the_jit(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    folder = tmp_path / "aot-0000"
    tmp_path.joinpath("aot-0000.failed").write_text("CompileError: no compiler\n")
    monkeypatch.setattr(aot_kernel, "aot_dir", lambda: folder)
    monkeypatch.setattr(aot_kernel, "_ENTRY_POINTS", {})
    fns, by = aot_kernel.entry_points("fixed")
    assert by == "jit" and [f.fn for f in fns] == [kernel.process, kernel.flush, kernel.reset]
    assert not folder.exists()
    monkeypatch.setattr(aot_kernel, "_ENTRY_POINTS", {})
    monkeypatch.setenv("GAITLOG_NO_AOT", "1")
    assert aot_kernel.entry_points("float")[1] == "jit"


@pytest.mark.slow
def test_first_use_builds_once_while_another_process_waits(tmp_path: Path) -> None:
    """Two processes start on an empty cache: one builds (under the lock), the other waits and loads it."""
    if not aot_kernel.enabled():
        pytest.skip("the ahead-of-time kernel is off (GAITLOG_NO_AOT or NUMBA_DISABLE_JIT)")
    script = ("import json, time\n"
              "from gaitlog.firmware_sim.algorithms import aot_kernel\n"
              "aot_kernel.BUILD_WAIT_S = 800.0\n"    # a loaded machine (a parallel run) builds slower than 180 s
              "t = time.monotonic()\n"
              "print(json.dumps([aot_kernel.entry_points('fixed')[1], time.monotonic() - t]))\n")
    e = {k: v for k, v in os.environ.items() if k not in ("NUMBA_DISABLE_JIT", "GAITLOG_NO_AOT")}
    e.update(PYTHONPATH=str(ROOT), GAITLOG_CACHE_DIR=str(tmp_path))
    procs = [subprocess.Popen([sys.executable, "-c", script], env=e, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)]
    time.sleep(1.0)
    procs.append(subprocess.Popen([sys.executable, "-c", script], env=e, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True))
    results = []
    for p in procs:
        out, err = p.communicate(timeout=900)
        assert p.returncode == 0, err[-3000:]
        results.append(json.loads(out.strip().splitlines()[-1]))
    failed = list(tmp_path.glob("aot-*.failed"))
    if failed:
        pytest.skip(f"the ahead-of-time kernel could not be built here: {failed[0].read_text().strip()}")
    assert [r[0] for r in results] == ["aot", "aot"]
    names = sorted(p.name for p in tmp_path.iterdir())
    assert len([n for n in names if n.startswith("aot-")]) == 1, names          # no lock, no build folder left
    assert len(list(tmp_path.glob("aot-*/" + aot_kernel.MODULE_NAME + ".*"))) == 1


def test_prune_removes_only_long_unused_folders_of_other_versions(tmp_path: Path) -> None:
    keep = tmp_path / "numba-aaaa"
    old = [tmp_path / "numba-bbbb", tmp_path / "aot-bbbb", tmp_path / "aot-cccc.failed"]
    recent = [tmp_path / "aot-dddd", tmp_path / "numba-eeee"]
    other = tmp_path / "notes"
    for p in (keep, *old[:2], *recent, other):
        p.mkdir()
        (p / "x").write_text("x")
    old[2].write_text("error\n")
    past = time.time() - (compiled.PRUNE_AFTER_DAYS + 1) * 86400
    for p in (keep, *old, other):
        os.utime(p, (past, past))
    removed = compiled.prune_cache(keep)
    assert sorted(removed) == sorted(old)
    assert all(p.exists() for p in (keep, *recent, other)) and not any(p.exists() for p in old)


def test_a_finalise_trace_under_the_aot_kernel_leaves_the_jit_usable() -> None:
    """probe.finalise_calls swaps two of the kernel's module globals for a run. Under the ahead-of-time kernel
    numba is not loaded yet; had the swap saved a lazy dispatcher, numba would skip replacing that global when it
    loads during the trace, and restoring it would leave ``_finalise`` lazy, so the JIT's ``flush`` could no longer
    be compiled (a test order under pytest-xdist met this). In a fresh interpreter: the trace, then the JIT."""
    _aot_or_skip()
    got = _child(
        "import json\n"
        "import numpy as np\n"
        "from gaitlog.firmware_sim.algorithms import kernel\n"
        "from gaitlog.firmware_sim.algorithms.online import OnlineStepAlgorithm\n"
        "from gaitlog.firmware_sim.algorithms.probe import finalise_calls\n"
        "from gaitlog.protocol.steps import StepConfig\n"
        "sc = StepConfig(step_format=1, leg_length_m=0.9, foot_length_m=0.2)\n"
        "alg = OnlineStepAlgorithm(sampling_rate_hz=50.0, arithmetic='fixed', step_config=sc)\n"
        "t = np.arange(1500) / 50.0\n"
        "codes = np.stack([np.full(t.size, 512), np.full(t.size, 512),\n"
        "                  (640 + 60 * np.sin(2 * np.pi * 1.8 * t)).astype(np.int64)], axis=1)\n"
        "aot = alg.compiled_by\n"
        "finalise_calls(alg, codes)\n"
        "jit = OnlineStepAlgorithm(sampling_rate_hz=50.0, arithmetic='fixed', step_config=sc)\n"
        "jit._process, jit._flush, jit._reset = kernel.process, kernel.flush, kernel.reset\n"
        "jit.run(codes)\n"
        "print(json.dumps([aot, type(kernel._finalise).__name__]))\n")
    assert got == ["aot", "CPUDispatcher"]
