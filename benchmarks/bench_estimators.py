"""Speed of the float step chain: events + M1-M5 on 65,536 samples, and the CLI start-up.

Targets (issue 4): the whole chain (tilt correction, events, M1-M5) on 65,536 samples at 50 Hz <= 0.1 s;
``python -c "import gaitlog.host.cli"`` and ``gaitlog --help`` <= 0.3 s. Baseline in the same run: the same
chain with a per-step Python loop for the integrals and the M4 range (``scipy.integrate.cumulative_trapezoid``
per step, as a straightforward implementation would do).

Input: real lower-back walking (the IPOL recordings replayed at 50 Hz, 10 bits, lost packets missing)
when ``../shared/data`` is present, else a synthetic walk. Timings are the best of several runs (the
machine is shared); the load average is printed alongside. Exit status 1 when a target is missed.

Run: ``python benchmarks/bench_estimators.py``
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from _timing import best_of
from gaitlog.units import STANDARD_GRAVITY_M_S2


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

N = 65_536
SAMPLING_RATE_HZ = 50.0


def real_or_synthetic() -> tuple[np.ndarray, np.ndarray, str]:
    data = Path(os.environ.get("GAITLOG_DATA_DIR", ROOT.parent / "shared" / "data")) / "ipol-lowerback-dev"
    if data.is_dir():
        from gaitlog.host.files.ipol import list_trials
        from gaitlog.host.studies.ipol_evaluation import replay_trial

        accs, valids, n = [], [], 0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for p in list_trials(data):
                rt = replay_trial(p)
                accs.append(rt.acc_g)
                valids.append(rt.valid)
                n += rt.acc_g.shape[0]
                if n >= N:
                    break
        reps = int(np.ceil(N / n))
        acc = np.concatenate(accs * reps)[:N]
        valid = np.concatenate(valids * reps)[:N]
        return acc, valid, "IPOL lower back replayed at 50 Hz / 10 bits"
    rng = np.random.default_rng(0)
    t = np.arange(N) / SAMPLING_RATE_HZ
    w = 2 * np.pi / 0.55
    a = 0.02 * w * w * np.cos(w * t) + rng.normal(0, 0.1, N)
    acc = np.c_[0.5 * (1 + a / STANDARD_GRAVITY_M_S2), np.zeros(N), 0.866 * (1 + a / STANDARD_GRAVITY_M_S2)]
    return acc, np.ones(N, bool), "synthetic walk"


def loop_baseline(acc: np.ndarray, valid: np.ndarray, leg: float, foot: float) -> None:
    """Same axes and events, then a per-step Python loop for M1-M4 (the naive way)."""
    from scipy.integrate import cumulative_trapezoid

    from gaitlog.host.gait.axes import body_axes
    from gaitlog.host.gait.events import GaitEventDetector

    ax = body_axes(acc, sampling_rate_hz=SAMPLING_RATE_HZ, valid=valid)
    ev = GaitEventDetector().detect(ax.acc_v_m_s2, sampling_rate_hz=SAMPLING_RATE_HZ, valid=ax.valid)
    av, lp = ax.acc_v_m_s2, ev.first_harmonic_m_s2_
    out = []
    for s, e, to, hs in zip(ev.step_start_, ev.step_end_, ev.step_toe_off_, ev.step_heel_strike_):
        idx = np.arange(s, e + 1)
        idx = idx[ax.valid[idx]]
        t = idx / SAMPLING_RATE_HZ - s / SAMPLING_RATE_HZ
        a = av[idx]
        v = cumulative_trapezoid(a, t, initial=0)
        p1 = cumulative_trapezoid(v, t, initial=0)
        v2 = v - v[-1] / t[-1] * t
        p2 = cumulative_trapezoid(v2, t, initial=0)
        p2 = p2 - p2[-1] / t[-1] * t
        h1, h2 = np.ptp(p1), np.ptp(p2)
        ss = (idx >= to) & (idx <= hs)
        h3 = np.ptp(p2[ss]) if ss.sum() > 1 else np.nan
        r = np.nanmax(lp[s:e + 1]) - np.nanmin(lp[s:e + 1])
        out.append((2 * np.sqrt(2 * leg * h1 - h1 ** 2), 2 * np.sqrt(2 * leg * h2 - h2 ** 2),
                    2 * np.sqrt(2 * leg * h3 - h3 ** 2) + foot, r ** 0.25, SAMPLING_RATE_HZ / (e - s)))


def cli_startup() -> tuple[float, float]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))

    def run(cmd: list[str]) -> float:
        ts = []
        for _ in range(5):
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True, env=env, cwd=ROOT)
            ts.append(time.perf_counter() - t0)
        return min(ts)

    base = run([sys.executable, "-c", "pass"])
    imp = run([sys.executable, "-c", "import gaitlog.host.cli"])
    gaitlog = [sys.executable, "-m", "gaitlog", "--help"]
    hlp = run(gaitlog)
    return imp - base, hlp - base, base


def main() -> int:
    from gaitlog.host.gait.pipeline import StepPipeline

    acc, valid, what = real_or_synthetic()
    leg, foot = 0.9, 0.19
    pipe = StepPipeline(leg_length_m=leg, foot_length_m=foot)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t_vec = best_of(lambda: pipe.run(acc, sampling_rate_hz=SAMPLING_RATE_HZ, valid=valid), warmup=True)
        t_loop = best_of(lambda: loop_baseline(acc, valid, leg, foot), repeat=3, warmup=True)
    n_steps = pipe.steps_.n_steps
    t_imp, t_help, t_py = cli_startup()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"input: {N} samples, {what}; {n_steps} steps; load average {load:.1f} on {os.cpu_count()} CPUs")
    rows = [
        ("events + M1-M5 (vectorised)", t_vec, 0.1, t_loop),
        ("import gaitlog.host.cli (minus bare python)", t_imp, 0.3, None),
        ("gaitlog --help (minus bare python)", t_help, 0.3, None),
    ]
    ok = True
    for name, t, target, base in rows:
        verdict = "ok" if t <= target else "MISSED"
        ok &= t <= target
        extra = f"  baseline per-step loop {base:.3f} s -> {base / t:.1f}x faster" if base else ""
        print(f"{name:<40} {t:.3f} s  target <= {target} s  {verdict}{extra}")
    print(f"(bare python start-up {t_py:.3f} s, subtracted)")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
