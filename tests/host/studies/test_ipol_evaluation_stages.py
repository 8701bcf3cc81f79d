"""The IPOL evaluation as an object (:class:`gaitlog.host.studies.ipol_evaluation.IpolEvaluation`) on a synthetic
folder: its numbered stages, and the command's files pinned byte for byte.

The digests were taken on the same folder with the evaluation before it became an object (one long
``evaluate_folder``) and after: equal. Update them only deliberately, when the figures are meant to change.
``eval.csv`` changed once more with the ``m3-single-support-speed`` rows: without those 5 rows it is the former
file byte for byte (checked); and again with M4's length rules' 20 rows (``m4-range-share``, ``m4-duration-share``,
offline and on-line): without them it is the file before (checked).
"""

from __future__ import annotations

import hashlib
import warnings

import pytest

from gaitlog.host.cli import main
from gaitlog.host.studies.ipol_evaluation import (
    EventConstantsStage,
    FitStage,
    IpolEvaluation,
    KConstantsStage,
    ReplayStage,
    ScoreStage,
)
from tests.host.studies.test_ipol_evaluation_synthetic import write_ipol_trial

#: sha256 of the files ``gaitlog evaluate ipol`` writes on :func:`folder`.
DIGESTS = {
    "eval.csv": "d289ebc3cf0ffc37d302de36eb6b9e6e981ffe1ed9e68d5aa0105d0023baba76",
    "eval_steps.csv": "dd483e51c82e7642aeb0d7d43301174c843e781a0b21b1c879a105543ad39eab",
    "eval_events.csv": "f6f094b61cc7ed56c99c4d7bab7c54687dfc3832c37659f7bbf9c06457ed440b",
}
#: ``eval.csv``'s digest without its ``walked_distance_m`` column: the digest pinned before that column was added.
WITHOUT_WALKED_DISTANCE = "91875da9f5e50df51f5db82819d061c239a62c90a7b8c147573ab057f66b164f"


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Subject 1 with two trials, subject 2 with one (skipped after replay)."""
    path = tmp_path_factory.mktemp("ipol")
    write_ipol_trial(path, 1, 1, seed=1)
    write_ipol_trial(path, 1, 2, seed=2)
    write_ipol_trial(path, 2, 1, seed=3)
    return path


def test_stages(folder) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ev = IpolEvaluation(arithmetic=("offline", "online-fixed")).run(folder)
    assert ev.arithmetic == ("offline", "online-fixed")            # __init__ stores, run leaves the parameters
    assert isinstance(ev.replay_, ReplayStage) and ev.replay_.n_files == {1: 2, 2: 1}
    assert [len(s.trials) for s in ev.replay_.subjects.values()] == [2, 1]
    assert all(len(t) == len(ev.replay_.candidates) for t in ev.replay_.subjects[1].offline_tables)
    assert isinstance(ev.event_constants_, EventConstantsStage) and set(ev.event_constants_.loso.chosen) == {1, 2}
    # one scorable subject: no other subject to learn a prior or an exponent on
    assert isinstance(ev.k_constants_, KConstantsStage) and ev.k_constants_.prior_all is None
    assert ev.k_constants_.folds[1].priors == {}
    assert isinstance(ev.fits_, FitStage) and list(ev.fits_.fits) == [1]
    assert ev.fits_.skipped == ["subject 2: only one trial, nothing to evaluate after calibration"]
    fit = ev.fits_.fits[1]
    assert fit.k is fit.k_fitted and fit.k_shrunk is None and fit.own is not None
    assert isinstance(ev.scores_, ScoreStage) and ev.scores_.n_trials == 1 and ev.scores_.step_rows == []
    res = ev.result_
    assert res.rows is ev.scores_.rows and res.calibrations == {1: fit.k} and res.calibrations_own == {1: fit.own}
    assert res.skipped == ev.replay_.skipped + ev.fits_.skipped
    assert {(r["arithmetic"], r["k_from"]) for r in res.rows if r["variant"] == "main"} == {
        ("offline", "offline"), ("online-fixed", "offline"), ("online-fixed", "own")}


def test_command_files_pinned(folder, tmp_path) -> None:
    out = tmp_path / "eval.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["evaluate", "ipol", str(folder), "--out", str(out), "-q"]) == 0
    got = {name: hashlib.sha256((tmp_path / name).read_bytes()).hexdigest() for name in DIGESTS}
    assert got == DIGESTS
    # the rows as pinned before the walked distance had a column: the same bytes once that column is removed
    text = (tmp_path / "eval.csv").read_bytes()
    end = b"\r\n" if b"\r\n" in text else b"\n"
    lines = text.split(end)
    col = lines[0].split(b",").index(b"walked_distance_m")
    assert all(ln.split(b",")[col] == b"20" for ln in lines[1:] if ln)
    without = end.join(b",".join(c for j, c in enumerate(ln.split(b",")) if j != col) if ln else ln
                          for ln in lines)
    assert hashlib.sha256(without).hexdigest() == WITHOUT_WALKED_DISTANCE
