"""Report: would a higher-order interpolant of the short gaps make M1 robust to missing samples?

The chain fills runs of missing samples up to 0.1 s linearly (:class:`gaitlog.host.gait.gaps.GapFiller`). M1
(Alvarez's pendulum, no drift correction) misses the missing-sample targets of
``tests/host/gait/test_missing_samples.py``; this measures, against the linear fill (the shipped one, the baseline,
in the same run), four cubic interpolants of the same gaps: the 4-point cubic through the two measured samples
nearest each side (Lagrange), and over every measured sample the natural cubic spline, PCHIP and Akima (scipy).

Truth is the trial with nothing missing. On every dev trial with no lost packet inside its boundaries, and on
simulated walkers, 10 % of the samples are deleted (single samples, or bursts of 1-3: the test's
``delete_samples``, imported), the gaps are filled with each interpolant before the chain (the chain's own
filler then has nothing to do), and the trial distance is compared with the clean trial's (K fitted on the clean
trial and kept). Printed per interpolant: each estimator's median signed and median |change| (%), M1's median
|change| with a 95 % trial-bootstrap interval, M1's change with the clean trial's events (the interpolation
error alone), the share of foot-flats that moved, and the per-sample RMS interpolation error. Then: M1 with the
linear fill's error scaled by alpha (how small the error must become); M1-M3 with nothing deleted and one
foot-flat in ten, then every one, moved by a sample; each axis's power above 5 and 10 Hz; and the best linear
predictor of a single sample from its neighbours, fitted in-sample per trial and axis (a bound: no interpolant
from neighbours does better). ``docs/topics/accuracy.md`` ("Missing samples") holds this output. About a minute.

    python benchmarks/gap_interpolants.py [../shared/data/ipol-lowerback-dev]
"""

from __future__ import annotations

import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
from scipy.interpolate import Akima1DInterpolator, CubicSpline, PchipInterpolator

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "host" / "gait"))

from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS  # noqa: E402
from gaitlog.host.cli import main as cli_main  # noqa: E402
from gaitlog.host.gait.gaps import GapFiller  # noqa: E402
from gaitlog.host.gait.pipeline import StepPipeline, apply_calibration, step_table  # noqa: E402
from gaitlog.host.studies.ipol_evaluation import replay_trial, section_distance, trial_steps  # noqa: E402
from gaitlog.units import STANDARD_GRAVITY_M_S2  # noqa: E402
from test_missing_samples import delete_samples, trial_distances_m  # noqa: E402

DEFAULT_FOLDER = ROOT.parent / "shared" / "data" / "ipol-lowerback-dev"
REPEATS = 8
FRACTION = 0.10


def lagrange4(col: np.ndarray, ok: np.ndarray, fill: np.ndarray) -> np.ndarray:
    """The cubic through the two measured samples nearest each side of every filled sample (linear at an end)."""
    vi = np.flatnonzero(ok)
    f = np.flatnonzero(fill)
    j = np.searchsorted(vi, f)
    js = np.stack([j - 2, j - 1, j, j + 1], 1)
    at_end = (js[:, 0] < 0) | (js[:, 3] >= vi.size)
    xs = vi[np.clip(js, 0, vi.size - 1)].astype(float)
    ys = col[vi[np.clip(js, 0, vi.size - 1)]]
    out = np.zeros(f.size)
    for a in range(4):
        w = np.ones(f.size)
        for b in range(4):
            if b != a:
                w *= np.divide(f - xs[:, b], xs[:, a] - xs[:, b], out=np.zeros(f.size), where=~at_end)
        out += w * ys[:, a]
    return np.where(at_end, np.interp(f, vi, col[vi]), out)


def _global(kind):
    def fill(col, ok, where):
        vi = np.flatnonzero(ok)
        return kind(vi, col[vi])(np.flatnonzero(where))
    return fill


INTERPOLANTS = {
    "linear (shipped)": None,
    "4-point cubic": lagrange4,
    "natural spline": _global(lambda x, y: CubicSpline(x, y, bc_type="natural")),
    "PCHIP": _global(PchipInterpolator),
    "Akima": _global(Akima1DInterpolator),
}


def filled(acc, valid, rate, method, truth=None, alpha=1.0):
    """``acc`` with its short gaps filled by ``method`` (the chain's rule of which gaps), and where it is valid."""
    g = GapFiller().fill(acc, valid, sampling_rate_hz=rate)
    x, where = g.acc_.copy(), g.valid_ & ~valid
    if method is not None and where.any():
        for k in range(3):
            x[where, k] = method(acc[:, k], valid, where)
    if truth is not None:
        x[where] = truth[where] + alpha * (x[where] - truth[where])
    return x, g.valid_


def _run(rt, acc, valid):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return StepPipeline(leg_length_m=rt.leg_length_m, foot_length_m=rt.foot_length_m).run(
            acc, sampling_rate_hz=rt.sampling_rate_hz, valid=valid, t0_s=rt.t0_s)


def _distances(rt, p, ev, k):
    """Every estimator's trial distance from the chain ``p``'s signal with the events ``ev``."""
    av = p.axes_.acc_v_m_s2
    ok, lp = p.axes_.valid & np.isfinite(av), p.events_.first_harmonic_m_s2_
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table, _ = step_table(ev.foot_flat_, ev.heel_strike_, ev.toe_off_, ev.bout_,
                              lambda lo, hi: (av[lo:hi], ok[lo:hi], lp[lo:hi]), sampling_rate_hz=rt.sampling_rate_hz,
                              t0_s=rt.t0_s, leg_length_m=rt.leg_length_m, foot_length_m=rt.foot_length_m, k_fit=None)
    table.length_m = apply_calibration(table, k)
    sec, counts = trial_steps(rt, table, uturn="include")
    return np.array([section_distance(sec, counts, e) for e in ESTIMATORS])


def measure(trials, method, max_burst, *, alpha=1.0, seed=5):
    """Per deletion: the change of every estimator (%), M1's change with the clean events (%), foot-flats moved,
    the interpolation errors; and the trial of each deletion."""
    rng = np.random.default_rng(seed)
    change, m1_clean_events, moved, err, trial = [], [], [], [], []
    for i, rt in enumerate(trials):
        clean_run = _run(rt, rt.acc_g, rt.valid)
        ff_clean = clean_run.events_.foot_flat_
        _, k = trial_distances_m(rt, rt.acc_g, rt.valid, max_fill_s=0.1)
        clean = _distances(rt, clean_run, clean_run.events_, k)
        for _ in range(REPEATS):
            v = delete_samples(rt.valid, fraction=FRACTION, max_burst=max_burst, rng=rng)
            acc = rt.acc_g.copy()
            acc[~v] = np.nan
            x, ok = filled(acc, v, rt.sampling_rate_hz, method, truth=rt.acc_g if alpha != 1.0 else None, alpha=alpha)
            p = _run(rt, x, ok)
            change.append(100 * (_distances(rt, p, p.events_, k) / clean - 1))
            m1_clean_events.append(100 * (_distances(rt, p, clean_run.events_, k)[0] / clean[0] - 1))
            moved.append(np.mean(~np.isin(p.events_.foot_flat_, ff_clean)))
            e = (x - rt.acc_g)[ok & ~v & np.isfinite(rt.acc_g).all(1)]
            err.append(e * STANDARD_GRAVITY_M_S2)
            trial.append(i)
    return np.array(change), np.array(m1_clean_events), float(np.mean(moved)), np.concatenate(err), np.array(trial)


def _trial_bootstrap(values, trial, *, n=1000, seed=0):
    rng = np.random.default_rng(seed)
    ids = np.unique(trial)
    groups = [values[trial == t] for t in ids]
    stats = [np.median(np.abs(np.concatenate([groups[j] for j in rng.integers(0, ids.size, ids.size)])))
             for _ in range(n)]
    return np.percentile(stats, [2.5, 97.5])


def best_predictor_rms(trials, neighbours):
    """RMS error of linear interpolation and of the least-squares predictor of a sample from ``neighbours`` samples
    each side, fitted on the same trial and axis (in-sample: a bound no interpolant from neighbours beats)."""
    lin, best = [], []
    for rt in trials:
        x = rt.acc_g[np.isfinite(rt.acc_g).all(1)] * STANDARD_GRAVITY_M_S2
        i = np.arange(neighbours, x.shape[0] - neighbours)
        for k in range(3):
            c = x[:, k]
            a = np.stack([c[i + d] for d in range(-neighbours, neighbours + 1) if d], 1)
            coef, *_ = np.linalg.lstsq(a, c[i], rcond=None)
            best.append(c[i] - a @ coef)
            lin.append(c[i] - 0.5 * (c[i - 1] + c[i + 1]))
    rms = [float(np.sqrt(np.mean(np.concatenate(e) ** 2))) for e in (lin, best)]
    return rms[0], rms[1]


def foot_flat_shift(trials, share, *, seed=2):
    """Nothing deleted: ``share`` of the foot-flats moved by one sample either way; M1-M3's median signed and
    median |change| of the trial distance (K = 1), %."""
    rng = np.random.default_rng(seed)
    out = []
    for rt in trials:
        p = _run(rt, rt.acc_g, rt.valid)
        clean = _distances(rt, p, p.events_, None)[:3]
        for _ in range(REPEATS):
            ff = p.events_.foot_flat_.copy()
            moved = rng.random(ff.size) < share
            ff[moved] += rng.choice([-1, 1], int(moved.sum()))
            out.append(100 * (_distances(rt, p, _Events(p.events_, ff), None)[:3] / clean - 1))
    out = np.array(out)
    return np.median(out, axis=0), np.median(np.abs(out), axis=0)


class _Events:
    """The events of ``ev`` with other foot-flats."""

    def __init__(self, ev, foot_flat):
        self.foot_flat_, self.heel_strike_ = foot_flat, ev.heel_strike_
        self.toe_off_, self.bout_ = ev.toe_off_, ev.bout_


def spectrum_shares(trials):
    """Per axis, the median share of the power above 5 Hz and above 10 Hz."""
    shares = []
    for rt in trials:
        x = rt.acc_g[np.isfinite(rt.acc_g).all(1)]
        power = np.abs(np.fft.rfft(x - x.mean(0), axis=0)) ** 2
        hz = np.fft.rfftfreq(x.shape[0], 1 / rt.sampling_rate_hz)
        shares.append([power[hz > f].sum(0) / power.sum(0) for f in (5.0, 10.0)])
    return np.median(np.array(shares), axis=0)


def main(argv: list[str]) -> int:
    folder = Path(argv[0]) if argv else DEFAULT_FOLDER
    if not (folder / "GaitData").is_dir():
        print(f"gap_interpolants: {folder}: no GaitData folder", file=sys.stderr)
        return 2
    ipol = [rt for rt in (replay_trial(p) for p in sorted((folder / "GaitData").glob("*_lb.txt")))
            if rt.gaps().missing_fraction_ == 0]
    with tempfile.TemporaryDirectory() as tmp:
        assert cli_main(["simulate", "--ipol-out", str(Path(tmp) / "w"), "--subjects", "6", "--seed", "11", "-q"]) == 0
        sim = [replay_trial(p) for p in sorted((Path(tmp) / "w").glob("*_lb.txt"))]
    sources = ((f"IPOL ({len(ipol)} clean trials)", ipol), (f"simulated ({len(sim)} walks)", sim))
    print(f"10 % of the samples deleted, {REPEATS} deletions a trial; median signed / median |change| of the trial "
          "distance, %")
    print("| source | deletion | interpolant | M1 | M2 | M3 | M4 | M5 | M1 median abs, 95 % CI | M1, clean events "
          "| foot-flats moved | RMS error, m/s2 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for label, trials in sources:
        for burst in (1, 3):
            for name, method in INTERPOLANTS.items():
                ch, m1e, moved, err, trial = measure(trials, method, burst)
                cells = [f"{np.median(ch[:, j]):+.2f} / {np.median(np.abs(ch[:, j])):.2f}" for j in range(5)]
                lo, hi = _trial_bootstrap(ch[:, 0], trial)
                print(f"| {label} | {'single' if burst == 1 else 'bursts 1-3'} | {name} | {' | '.join(cells)} | "
                      f"[{lo:.2f}, {hi:.2f}] | {np.median(m1e):+.2f} / {np.median(np.abs(m1e)):.2f} | "
                      f"{100 * moved:.1f} % | {np.sqrt(np.mean(err ** 2)):.2f} |")
    print("\nM1 with the linear fill's error scaled by alpha (IPOL clean trials): median signed / |change|, %")
    for alpha in (1.0, 0.75, 0.5, 0.25):
        cells = []
        for burst in (1, 3):
            ch, _, moved, _, _ = measure(ipol, None, burst, alpha=alpha)
            cells.append(f"{'single' if burst == 1 else 'bursts'} {np.median(ch[:, 0]):+.2f} / "
                         f"{np.median(np.abs(ch[:, 0])):.2f} (foot-flats moved {100 * moved:.1f} %)")
        print(f"alpha {alpha:.2f}: " + "; ".join(cells))
    print("\nNothing deleted, foot-flats moved by one sample (IPOL clean trials, K = 1): M1, M2, M3 signed / "
          "|change|, %")
    for share in (0.10, 1.0):
        signed, typical = foot_flat_shift(ipol, share)
        print(f"{100 * share:.0f} % of the foot-flats: "
              + ", ".join(f"{a:+.2f} / {b:.2f}" for a, b in zip(signed, typical)))
    above5, above10 = spectrum_shares(ipol)
    print(f"Power above 5 Hz per axis {np.round(above5, 2)}, above 10 Hz {np.round(above10, 3)} (median of the trials)")
    print("\nOne missing sample, RMS error over the IPOL clean trials' axes (linear / best in-sample predictor):")
    for n in (2, 4, 8):
        lin, best = best_predictor_rms(ipol, n)
        print(f"+-{n} neighbours: {lin:.3f} / {best:.3f} m/s2 (ratio {best / lin:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
