"""Missing samples without bias (:mod:`gaitlog.host.gait.gaps`): samples deleted from clean trials, at random
and in bursts, move each estimator's trial distance by little and without a direction.

Truth is the same trial with nothing missing: K is fitted on the clean trial (20 m, U-turn included) and kept,
so the distance of the damaged copy moves only through what the chain does with the gaps. 10 % of the samples
are deleted, one at a time or in bursts of 1-3 samples (20-60 ms at 50 Hz: the IPOL files lose 1-3 packets at
a time, 99th percentile 70 ms). The figures are medians over trials and deletions (signed: the bias; absolute:
the typical trial). Measured (``docs/topics/accuracy.md``): before the gaps were interpolated, M2's distance fell
by 1.8 % (single samples) and 4.5 % (bursts of 1-5) on IPOL trials; now its median change is within
+-0.4 %.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from gaitlog.firmware_sim.algorithms.steps import ESTIMATORS
from gaitlog.host.gait.gaps import MAX_INTERPOLATED_GAP_S, GapFiller, missing_runs
from gaitlog.host.gait.k_calibration import calibrate
from gaitlog.host.gait.pipeline import StepPipeline, apply_calibration, step_table
from gaitlog.host.studies.ipol_evaluation import _counted, replay_trial, section_distance, trial_steps

pytestmark = pytest.mark.slow  # ~40 s: a few hundred runs of the offline chain

MISSING_FRACTION = 0.10
CLEAN_IPOL_TRIALS = ("2-2", "3-2", "4-4", "9-2")     # no lost packet inside the trial boundaries
#: every dev trial with no lost packet inside its boundaries (the foot-flat test: cheap, one chain run a trial)
ALL_CLEAN_IPOL_TRIALS = ("1-1", "1-2", "1-3", "1-4", "1-5", "2-1", "2-2", "2-4", "3-1", "3-2", "4-2", "4-3", "4-4",
                         "4-5", "4-6", "5-1", "5-2", "5-3", "5-4", "6-3", "6-4", "6-6", "7-4", "7-5", "7-6", "8-2",
                         "9-1", "9-2")
REPEATS = 5
#: the bias (median signed change) allowed, %
MAX_BIAS_PCT = 0.5
#: why M1 misses the targets
M1_REASON = ("M1 has no drift correction: its excursion is the double integral from the foot-flat with v = 0 there, "
             "so a one-sample move of the foot-flat (7-10 % of them move at 10 % missing, whatever the interpolant) "
             "or an interpolated sample changes a step by percents (median |change| of a trial 0.79 % on IPOL; "
             "-0.85 % median with bursts on the simulated walks); cubic interpolants do not bring it under 0.5 %")


def delete_samples(valid: np.ndarray, *, fraction: float, max_burst: int, rng: np.random.Generator) -> np.ndarray:
    """``valid`` with ``fraction`` of its samples deleted in bursts of 1..``max_burst`` samples."""
    v = valid.copy()
    target, deleted = int(fraction * v.size), 0
    while deleted < target:
        n = int(rng.integers(1, max_burst + 1))
        a = int(rng.integers(1, v.size - n - 1))
        deleted += int(np.count_nonzero(v[a:a + n]))
        v[a:a + n] = False
    return v


def trial_distances_m(rt, acc, valid, *, max_fill_s: float, k=None):
    """Each estimator's distance over the trial (U-turn included) and the K used (fitted when None)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = StepPipeline(leg_length_m=rt.leg_length_m, foot_length_m=rt.foot_length_m,
                             max_fill_s=max_fill_s).run(acc, sampling_rate_hz=rt.sampling_rate_hz, valid=valid,
                                                        t0_s=rt.t0_s).steps_
    if k is None:
        sec, counts = trial_steps(rt, table, uturn="include")
        k = calibrate([(_counted(sec, counts), 20.0)], leg_length_m=rt.leg_length_m,
                      foot_length_m=rt.foot_length_m)
    table.length_m = apply_calibration(table, k)
    sec, counts = trial_steps(rt, table, uturn="include")
    return np.array([section_distance(sec, counts, e) for e in ESTIMATORS]), k


def changes_pct(trials, *, max_burst: int, max_fill_s: float = MAX_INTERPOLATED_GAP_S, seed: int = 5) -> np.ndarray:
    """``(runs, estimators)`` relative change of the trial distance, %."""
    rng = np.random.default_rng(seed)
    out = []
    for rt in trials:
        clean, k = trial_distances_m(rt, rt.acc_g, rt.valid, max_fill_s=max_fill_s)
        for _ in range(REPEATS):
            v = delete_samples(rt.valid, fraction=MISSING_FRACTION, max_burst=max_burst, rng=rng)
            acc = rt.acc_g.copy()
            acc[~v] = np.nan
            damaged, _ = trial_distances_m(rt, acc, v, max_fill_s=max_fill_s, k=k)
            out.append(100 * (damaged / clean - 1))
    return np.array(out)


_CHANGES: dict = {}


def cached_changes(request, source: str, max_burst: int) -> np.ndarray:
    """:func:`changes_pct` once per source and burst length (every estimator's test reads the same runs)."""
    if (source, max_burst) not in _CHANGES:
        _CHANGES[(source, max_burst)] = changes_pct(request.getfixturevalue(source), max_burst=max_burst)
    return _CHANGES[(source, max_burst)]


@pytest.fixture(scope="module")
def ipol_trials(shared_data):
    folder = shared_data / "ipol-lowerback-dev" / "GaitData"
    if not folder.is_dir():
        pytest.skip("ipol-lowerback-dev not present")
    trials = [replay_trial(folder / f"{name}_lb.txt") for name in CLEAN_IPOL_TRIALS]
    for rt in trials:
        assert rt.gaps().missing_fraction_ == 0, rt.path.name
    return trials


@pytest.fixture(scope="module")
def simulated_trials(tmp_path_factory):
    from gaitlog.host.cli import main

    out = tmp_path_factory.mktemp("sim") / "walks"
    assert main(["simulate", "--ipol-out", str(out), "--subjects", "3", "--seed", "3", "-q"]) == 0
    return [replay_trial(p) for p in sorted(out.glob("*_lb.txt"))]


def test_gap_filler_interpolates_short_gaps_only() -> None:
    """A straight line is restored exactly in a short gap; a long gap and the ends stay missing."""
    x = np.arange(40, dtype=float)[:, None] * np.array([1.0, -2.0, 0.5])
    valid = np.ones(40, bool)
    valid[[0, 5, 6, 7]] = False      # an end, then 3 samples (60 ms at 50 Hz)
    valid[20:26] = False             # 6 samples: 120 ms > 0.1 s
    x[~valid] = np.nan
    g = GapFiller().fill(x, valid, sampling_rate_hz=50.0)
    np.testing.assert_allclose(g.acc_[5:8], np.arange(5, 8)[:, None] * np.array([1.0, -2.0, 0.5]))
    assert g.valid_[5:8].all() and not g.valid_[0] and not g.valid_[20:26].any()
    assert np.isnan(g.acc_[20:26]).all()
    assert (g.n_filled_, g.n_left_missing_) == (3, 7)
    assert g.missing_fraction_ == pytest.approx(10 / 40) and g.longest_gap_s_ == pytest.approx(0.12)
    s, e = missing_runs(g.valid_)
    assert (s.tolist(), e.tolist()) == ([0, 20], [1, 26])


def test_pipeline_reports_the_gaps(ipol_trials) -> None:
    rt = ipol_trials[0]
    v = delete_samples(rt.valid, fraction=0.1, max_burst=3, rng=np.random.default_rng(0))
    acc = rt.acc_g.copy()
    acc[~v] = np.nan
    p = StepPipeline(leg_length_m=rt.leg_length_m, foot_length_m=rt.foot_length_m).run(
        acc, sampling_rate_hz=rt.sampling_rate_hz, valid=v)
    assert p.gaps_.missing_fraction_ == pytest.approx(0.1, abs=0.005)
    assert p.gaps_.n_left_missing_ == 0 and p.gaps_.longest_gap_s_ <= MAX_INTERPOLATED_GAP_S + 1e-9   # bursts may touch


@pytest.mark.parametrize("max_burst", [1, 3])
@pytest.mark.parametrize("source", ["ipol_trials", "simulated_trials"])
@pytest.mark.parametrize("name", ESTIMATORS)
def test_distance_has_no_bias_at_10pct_missing(request, source, max_burst, name) -> None:
    """Median signed change of the trial distance within +-0.5 %; M1 on the simulated walks misses it with bursts
    (strict xfail; with single samples it holds since on-line algorithm version 4's defaults, no stop rule)."""
    if name == "M1" and source == "simulated_trials" and max_burst > 1:
        request.applymarker(pytest.mark.xfail(strict=True, reason=M1_REASON))
    ch = cached_changes(request, source, max_burst)
    j = ESTIMATORS.index(name)
    assert abs(np.median(ch[:, j])) < MAX_BIAS_PCT, np.round(ch[:, j], 2)


@pytest.mark.parametrize("name", ESTIMATORS)
def test_typical_trial_moves_less_than_half_a_percent(request, name) -> None:
    """Single samples deleted at random (10 %): the median |change| of a trial's distance < 0.5 % (measured on
    IPOL: M1 0.79 %, M2 0.15 %, M3 0.38 %, M4 0.12 %, M5 0.03 %); M1 misses it (strict xfail; no cubic
    interpolant of the gaps brings it under 0.5 %: ``benchmarks/gap_interpolants.py``)."""
    if name == "M1":
        request.applymarker(pytest.mark.xfail(strict=True, reason=M1_REASON))
    ch = cached_changes(request, "ipol_trials", 1)
    assert np.median(np.abs(ch[:, ESTIMATORS.index(name)])) < 0.5


def test_m1_moves_with_its_foot_flats(shared_data) -> None:
    """Why M1 misses the targets, with nothing deleted: 10 % of the foot-flats of the clean trials moved by one
    sample (the rate at which they move when 10 % of the samples are deleted and interpolated, linear or cubic)
    move M1's trial distance by more than 0.5 % (median |change|; measured 0.80 %), M2's and M3's by less than
    0.2 % (measured 0.07 % and 0.06 %): M1's velocity is reset to 0 at the foot-flat and never corrected, so the
    sample it starts from sets a drift; M2 removes it."""
    folder = shared_data / "ipol-lowerback-dev" / "GaitData"
    if not folder.is_dir():
        pytest.skip("ipol-lowerback-dev not present")
    rng = np.random.default_rng(2)
    out = []
    for name in ALL_CLEAN_IPOL_TRIALS:
        rt = replay_trial(folder / f"{name}_lb.txt")
        assert rt.gaps().missing_fraction_ == 0, name
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            p = StepPipeline(leg_length_m=rt.leg_length_m, foot_length_m=rt.foot_length_m).run(
                rt.acc_g, sampling_rate_hz=rt.sampling_rate_hz, valid=rt.valid, t0_s=rt.t0_s)
        ev, av = p.events_, p.axes_.acc_v_m_s2
        ok, lp = p.axes_.valid & np.isfinite(av), ev.first_harmonic_m_s2_

        def distances(ff, rt=rt, ev=ev, av=av, ok=ok, lp=lp):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                table, _ = step_table(ff, ev.heel_strike_, ev.toe_off_, ev.bout_,
                                      lambda lo, hi: (av[lo:hi], ok[lo:hi], lp[lo:hi]),
                                      sampling_rate_hz=rt.sampling_rate_hz, t0_s=rt.t0_s,
                                      leg_length_m=rt.leg_length_m, foot_length_m=rt.foot_length_m, k_fit=None)
            sec, counts = trial_steps(rt, table, uturn="include")
            return np.array([section_distance(sec, counts, e, raw=True) for e in ("M1", "M2", "M3")])

        clean = distances(ev.foot_flat_)
        for _ in range(4):
            ff = ev.foot_flat_.copy()
            moved = rng.random(ff.size) < 0.10
            ff[moved] += rng.choice([-1, 1], int(moved.sum()))
            out.append(100 * (distances(ff) / clean - 1))
    typical = np.median(np.abs(np.array(out)), axis=0)
    assert typical[0] > 0.5 and np.all(typical[1:] < 0.2), np.round(typical, 2)


def test_without_interpolation_m2_is_biased(ipol_trials) -> None:
    """The test can fail: left missing (nothing interpolated), M2's distance falls by > 1 % at 10 % missing."""
    ch = changes_pct(ipol_trials, max_burst=3, max_fill_s=0.0)
    assert np.median(ch[:, ESTIMATORS.index("M2")]) < -1.0
