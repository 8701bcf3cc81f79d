"""``gaitlog evaluate ipol`` on data it has not seen: perturbed copies of the IPOL dev recordings.

Each copy is built in a temporary folder from a few real trials (symbolic links, or edited copies; the shared
data are never touched) and run through the command as an outsider would (``--arithmetic offline``: the replay,
the leave-one-subject-out choices, K and the rows, without the on-line chains, to stay fast). The truth is the
command's own run on the unperturbed subset: a perturbation that carries no information (other subject numbers,
the suffix's case, CRLF line ends, other column order, unknown JSON fields, stray files) must give the same rows
byte for byte, and one that removes information must be said, per file, on stderr (a skip) with the table
computed on the rest. The malformed inputs the reader refuses are checked without the real data.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from gaitlog.host.cli import main
from gaitlog.host.errors import HostError
from gaitlog.host.files.ipol import list_trials, read_trial, stray_files
from gaitlog.host.studies.ipol_m3 import TrialM3
from tests.host.studies.test_ipol_evaluation_synthetic import write_ipol_trial

#: The subset every real-data run starts from: 3 subjects, trials 1 and 2 (one scored trial each).
SUBJECTS, TRIALS = (1, 2, 3), (1, 2)


def run_ipol(folder: Path, out_dir: Path, *extra: str) -> SimpleNamespace:
    """``gaitlog evaluate ipol folder --out out_dir/eval.csv --arithmetic offline``: exit code, stdout, stderr, the
    CSV's lines and its events rows."""
    out = out_dir / "eval.csv"
    out_dir.mkdir(parents=True, exist_ok=True)
    so, se = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(so), contextlib.redirect_stderr(se):
        rc = main(["evaluate", "ipol", str(folder), "--out", str(out), "--arithmetic", "offline", "--resamples", "50",
                   *extra])
    lines = out.read_text().splitlines() if out.exists() else []
    events = list(csv.DictReader(open(out.with_name("eval_events.csv"), newline=""))) if rc == 0 else []
    return SimpleNamespace(rc=rc, out=so.getvalue(), err=se.getvalue(), lines=lines, events=events, csv=out)


def link_subset(dev: Path, folder: Path, subjects=SUBJECTS, trials=TRIALS, rename=None) -> Path:
    """``folder/GaitData`` with links to the dev trials (subject ``s`` as ``rename[s]``)."""
    g = folder / "GaitData"
    g.mkdir(parents=True, exist_ok=True)
    for s in subjects:
        for t in trials:
            for suffix in ("_lb.txt", ".json"):
                src = dev / f"{s}-{t}{suffix}"
                if src.exists():
                    (g / f"{(rename or {}).get(s, s)}-{t}{suffix}").symlink_to(src)
    return g


def rewrite(path: Path, text: str) -> None:
    """Replace a link (or file) by a file holding ``text``."""
    path.unlink()
    path.write_text(text, newline="")


def edit_json(path: Path, edit) -> None:
    meta = json.loads(path.read_text())
    edit(meta)
    rewrite(path, json.dumps(meta))


def renamed_lines(lines: list[str], mapping: dict[int, int]) -> list[str]:
    """CSV lines with the subject column mapped back (``mapping``: new -> old)."""
    out = [lines[0]]
    for ln in lines[1:]:
        subject, rest = ln.split(",", 1)
        out.append(f"{mapping.get(int(subject), int(subject))},{rest}")
    return out


def offline_table(text: str) -> list[str]:
    """The printed main table (``arithmetic = offline``): its estimator lines."""
    lines = text.splitlines()
    i = lines.index("arithmetic = offline")
    return lines[i + 2:i + 7]


@pytest.fixture(scope="module")
def dev(shared_data) -> Path:
    g = shared_data / "ipol-lowerback-dev" / "GaitData"
    if not g.is_dir():
        pytest.skip("ipol-lowerback-dev not present")
    return g


@pytest.fixture(scope="module")
def base(dev, tmp_path_factory) -> SimpleNamespace:
    """The command on the unperturbed subset: the truth of the runs below."""
    root = tmp_path_factory.mktemp("base")
    res = run_ipol(link_subset(dev, root / "in").parent, root / "out")
    assert res.rc == 0, res.err
    return res


@pytest.mark.slow
def test_other_subject_numbers_give_the_same_rows(dev, base, tmp_path) -> None:
    """Subjects 12, 40, 103 (not 1..9, with gaps, 103 after 40 in number but not in text): the rows are the
    subset's byte for byte once the numbers are mapped back, and so is the printed table (intervals included:
    the subjects keep their order)."""
    mapping = {1: 12, 2: 40, 3: 103}
    res = run_ipol(link_subset(dev, tmp_path / "in", rename=mapping).parent, tmp_path / "out")
    assert res.rc == 0 and res.err == "", res.err
    assert renamed_lines(res.lines, {v: k for k, v in mapping.items()}) == base.lines
    assert offline_table(res.out) == offline_table(base.out)
    assert res.out.startswith("3 subjects, 3 evaluated trials")


@pytest.mark.slow
def test_inert_perturbations_give_the_same_rows_and_stray_files_are_named(dev, base, tmp_path) -> None:
    """Upper-case suffixes, CRLF line ends, the columns in another order with an extra one, JSON without age and
    sex and with unknown fields change nothing; an unreadable extra trial, a stray data file and a JSON without
    data are each named on stderr and left out; the rows are the subset's byte for byte."""
    g = link_subset(dev, tmp_path / "in")
    (g / "1-2_lb.txt").rename(g / "1-2_LB.txt")
    (g / "1-2.json").rename(g / "1-2.JSON")
    rewrite(g / "2-2_lb.txt", (dev / "2-2_lb.txt").read_text().replace("\n", "\r\n"))
    for t in TRIALS:
        edit_json(g / f"2-{t}.json", lambda m: [m.pop("Age"), m.pop("Gender"), m.update(Unknown={"a": [1]}, Notes="x")])
        lines = (dev / f"3-{t}_lb.txt").read_text().splitlines()
        order = [3, 0, 9, 2, 1, 4, 5, 6, 7, 8]
        body = ["\t".join([c[i] for i in order] + ["7"]) for c in (ln.split("\t") for ln in lines[1:])]
        body[0] = body[0].rsplit("\t", 1)[0] + "\tExtra"
        rewrite(g / f"3-{t}_lb.txt", "\n".join([lines[0], *body]) + "\n")
    truncated = (dev / "3-3_lb.txt").read_text().splitlines(keepends=True)
    (g / "3-3_lb.txt").write_text("".join(truncated[:-1]) + truncated[-1][:9])     # a copy cut mid-row
    (g / "3-3.json").symlink_to(dev / "3-3.json")
    (g / "S5-1_lb.txt").symlink_to(dev / "1-3_lb.txt")
    (g / "4-1.json").symlink_to(dev / "4-1.json")
    res = run_ipol(g.parent, tmp_path / "out")
    assert res.rc == 0, res.err
    assert res.lines == base.lines
    skips = [ln for ln in res.err.splitlines()]
    assert len(skips) == 3, res.err
    assert re.search(rf"skipped: 3-3_lb.txt: .*3-3_lb.txt: line {len(truncated)}: bad numeric row", res.err)
    assert "skipped: S5-1_lb.txt: not a '<subject>-<trial>_lb.txt' name" in res.err
    assert "skipped: 4-1.json: no '4-1_lb.txt' beside it" in res.err
    assert all(ln.startswith("gaitlog evaluate ipol: skipped: ") for ln in skips)


@pytest.mark.slow
def test_duplicated_subjects_score_as_their_twins(dev, base, tmp_path) -> None:
    """The subset twice (subjects 21-23 copies of 1-3): twice the trials, each twin's rows those of its original,
    so every median of the table is the originals' median. (Not the subset's own rows: each subject's fold now
    trains on its twin, so the constants chosen leave-one-subject-out may differ.)"""
    g = link_subset(dev, tmp_path / "in")
    link_subset(dev, tmp_path / "in", rename={1: 21, 2: 22, 3: 23})
    res = run_ipol(g.parent, tmp_path / "out")
    assert res.rc == 0 and res.err == "", res.err
    assert res.out.startswith("6 subjects, 6 evaluated trials")
    rows = list(csv.DictReader(io.StringIO("\n".join(res.lines))))
    twins = [{**r, "subject": str(int(r["subject"]) - 20)} for r in rows if int(r["subject"]) > 20]
    originals = [r for r in rows if int(r["subject"]) < 20]
    assert twins == originals and len(rows) == 2 * len(base.lines[1:])
    for line in offline_table(res.out):
        name, n, median = line.split()[:3]
        mine = [float(r["ratio"]) for r in originals if r["estimator"] == name and r["variant"] == "main"]
        assert int(n) == 2 * len(mine) and float(median) == pytest.approx(np.median(mine), abs=6e-4), line


def _drop_rows(text: str, rng: np.random.Generator, fraction: float, block: slice) -> tuple[str, np.ndarray]:
    """``text`` with ``fraction`` of its data rows dropped at random and every row of ``block``; the packet
    counters kept."""
    lines = text.splitlines(keepends=True)
    keep = rng.random(len(lines) - 2) > fraction
    keep[:5] = keep[-5:] = True                   # the first and last packets: the grid's ends stay
    keep[block] = False
    kept = np.array([float(ln.split("\t")[0]) for ln, k in zip(lines[2:], keep) if k], dtype=np.int64)
    return "".join(lines[:2] + [ln for ln, k in zip(lines[2:], keep) if k]), kept


@pytest.mark.slow
def test_damaged_folder_is_scored_on_the_rest_and_says_what_it_left_out(dev, tmp_path) -> None:
    """Subject 1's calibration trial with 20 % of its packets lost and a 0.6 s hole; subject 2 without trial 1
    (K from 2-2, said in the heading); trial 3-2 without foot events (its distance scored, not its events);
    subject 4 with one trial (skipped: nothing to score)."""
    g = link_subset(dev, tmp_path / "in", trials=(1, 2, 3))
    for name in ("1-3", "2-1", "3-3"):
        (g / f"{name}_lb.txt").unlink()
        (g / f"{name}.json").unlink()
    link_subset(dev, tmp_path / "in", subjects=(4,), trials=(1,))
    meta = json.loads((dev / "1-1.json").read_text())
    lo, hi = meta["TrialBoundaries"]
    text, kept = _drop_rows((dev / "1-1_lb.txt").read_text(), np.random.default_rng(3), 0.2, slice(lo + 500, lo + 560))
    rewrite(g / "1-1_lb.txt", text)
    edit_json(g / "3-2.json", lambda m: [m.pop("LeftFootEvents"), m.pop("RightFootEvents")])
    res = run_ipol(g.parent, tmp_path / "out")
    assert res.rc == 0, res.err
    assert "skipped: subject 4: only one trial" in res.err
    assert "skipped: 3-2_lb.txt: no foot-sensor heel strike between the trial boundaries" in res.err
    assert res.out.startswith("3 subjects, 3 evaluated trials") and "subject 2: trial 2-2" in res.out.splitlines()[0]
    rows = list(csv.DictReader(io.StringIO("\n".join(res.lines))))
    assert {(r["subject"], r["trial"]) for r in rows} == {("1", "2"), ("2", "3"), ("3", "2")}
    assert {r["reference_steps"] for r in rows if r["subject"] == "3"} == {"0"}
    ev = {(r["subject"], r["trial"]): r for r in res.events}
    assert ev[("2", "2")]["calibration_trial"] == "1" and ev[("2", "3")]["calibration_trial"] == "0"
    # the logger samples at 50 Hz fall on the even packets: one is missing when its packet was lost
    even = np.arange(lo + (lo % 2), hi + 1, 2)
    lost = ~np.isin(even, kept)
    row = ev[("1", "1")]
    assert float(row["missing_fraction"]) == pytest.approx(lost.mean(), abs=0.01)
    assert float(row["longest_gap_s"]) == pytest.approx(0.6, abs=0.05)
    assert re.search(r"calibration trials with a gap over 0.1 s .*: 1-1 \(\d+\.\d % missing, longest gap 0.6\d s\)",
                     res.out)
    table = next(ln for ln in res.out.splitlines() if ln.startswith("1-1*"))
    assert table.split()[-2:] == [f"{100 * float(row['missing_fraction']):.1f}", f"{float(row['longest_gap_s']):.2f}"]


@pytest.mark.slow
def test_the_rate_of_the_file_is_read_not_assumed(dev, base, tmp_path) -> None:
    """The subset at 50 Hz (every other packet, counters and JSON indices halved, ``Acquisition frequency: 50 Hz``):
    the same reference steps, and ratios near the 100 Hz ones (the emulated sensor sees another input, so not
    equal; read as 100 Hz, the boundaries would land at half their times and the ratios near 0.5)."""
    g = link_subset(dev, tmp_path / "in")
    for s in SUBJECTS:
        for t in TRIALS:
            lines = (dev / f"{s}-{t}_lb.txt").read_text().splitlines(keepends=True)
            rows = [ln.split("\t", 1) for ln in lines[2:]]
            body = [f"{float(c) / 2:.1f}\t{rest}" for c, rest in rows if float(c) % 2 == 0]
            rewrite(g / f"{s}-{t}_lb.txt", lines[0].replace("100 Hz", "50 Hz") + lines[1] + "".join(body))

            def halve(m):
                for k in ("TrialBoundaries", "UTurnBoundaries"):
                    m[k] = [v // 2 for v in m[k]]
                for k in ("LeftFootEvents", "RightFootEvents"):
                    m[k] = [[a // 2, b // 2] for a, b in m[k]]
            edit_json(g / f"{s}-{t}.json", halve)
    res = run_ipol(g.parent, tmp_path / "out")
    assert res.rc == 0 and res.err == "", res.err
    mine = list(csv.DictReader(io.StringIO("\n".join(res.lines))))
    ref = list(csv.DictReader(io.StringIO("\n".join(base.lines))))
    assert [r["reference_steps"] for r in mine] == [r["reference_steps"] for r in ref]
    d = np.array([float(a["ratio"]) - float(b["ratio"]) for a, b in zip(mine, ref, strict=True)])
    assert np.median(np.abs(d)) < 0.05 and np.max(np.abs(d)) < 0.15


# -- without the real data: what the reader refuses, and the command's answer ---------------------------------------

HEADER = "PacketCounter\tAcc_X\tAcc_Y\tAcc_Z\n"


def write_small(folder: Path, name: str = "3-2", *, first: str = "Acquisition frequency: 100 Hz\n", rows=None,
                meta=None) -> Path:
    rows = rows if rows is not None else [f"{c}.0\t9.8\t0.1\t0.5\n" for c in range(12)]
    (folder / f"{name}_lb.txt").write_text(first + HEADER + "".join(rows))
    meta = meta if meta is not None else {"TrialBoundaries": [1, 10], "UTurnBoundaries": [3, 4], "Height": 170,
                                          "LeftFootEvents": [[1, 3], [5, 9]], "RightFootEvents": [[2, 6]]}
    (folder / f"{name}.json").write_text(json.dumps(meta))
    return folder / f"{name}_lb.txt"


GOOD_META = {"TrialBoundaries": [1, 10], "LeftFootEvents": [[1, 3]], "RightFootEvents": [[2, 6]]}


@pytest.mark.parametrize("kw, match", [
    (dict(first="Acquisition frequency: . Hz\n"), r"line 1: expected 'Acquisition frequency: <rate> Hz' with a rate > 0"),
    (dict(first="Acquisition frequency: 0 Hz\n"), r"line 1: .*rate > 0"),
    (dict(rows=[f"{c}.0\t9.8\t0.1\t0.5\n" for c in range(11)] + ["11.0\t9.8"]), r"line 14: bad numeric row: 2 columns"),
    (dict(rows=["0.0\t9.8\t0.1\t0.5\n", "1.0\t9.8\tx\t0.5\n"] * 1), r"line 4: bad numeric row: column 3 is 'x'"),
    (dict(rows=[f"{c}.0\t9.8\t{'nan' if c == 4 else 0.1}\t0.5\n" for c in range(12)]), r"line 7: .*not a finite number"),
    (dict(meta={**GOOD_META, "TrialBoundaries": ["1", "10"]}), r"3-2.json: 'TrialBoundaries' must be \[start, end\]"),
    (dict(meta={**GOOD_META, "TrialBoundaries": [10, 1]}), r"3-2.json: 'TrialBoundaries' \[10, 1\] must be increasing"),
    (dict(meta={**GOOD_META, "TrialBoundaries": [1, 12]}), r"within the recording's packets 0 .. 11"),
    (dict(meta={**GOOD_META, "UTurnBoundaries": [5]}), r"3-2.json: 'UTurnBoundaries' must be"),
    (dict(meta={**GOOD_META, "LeftFootEvents": [[1, 3], [5]]}), r"3-2.json: 'LeftFootEvents' must be .* found \[5\]"),
    (dict(meta={**GOOD_META, "RightFootEvents": "none"}), r"'RightFootEvents' must be a list"),
])
def test_malformed_trials_are_refused_naming_file_and_place(tmp_path, kw, match) -> None:
    with pytest.raises(HostError, match=match):
        read_trial(write_small(tmp_path, **kw))


def test_the_counter_wrap_is_undone(tmp_path) -> None:
    """A recording that starts near the top of the 16-bit ``PacketCounter`` and wraps to 0 (packet 65535 lost at
    the wrap) is one grid, the lost packet missing; a step down that is not a wrap is refused."""
    counters = [65530, 65531, 65532, 65533, 65534, 0, 1, 2, 3, 4, 5, 6]
    rows = [f"{c}.0\t9.8\t{0.1 * i}\t0.5\n" for i, c in enumerate(counters)]
    t = read_trial(write_small(tmp_path, rows=rows, meta=GOOD_META))
    assert t.first_counter == 65530 and t.valid.tolist() == [True] * 5 + [False] + [True] * 7
    assert t.acc_g[6, 1] * 9.80665 == pytest.approx(0.5)          # counter 0 is grid index 6
    rows[7] = "20000.0\t9.8\t0.1\t0.5\n"
    with pytest.raises(HostError, match=r"line 11: PacketCounter goes backwards \(20000 -> 3\)"):
        read_trial(write_small(tmp_path, rows=rows, meta=GOOD_META))


def test_names_in_other_cases_are_read_and_twins_refused(tmp_path) -> None:
    """``_LB.txt`` and ``.JSON`` are read (the JSON found in another case); two files of one subject and trial
    (``01-2`` and ``1-2``) are refused, naming both; stray names are listed, not dropped in silence."""
    write_small(tmp_path, "1-2", meta=GOOD_META)
    (tmp_path / "1-2_lb.txt").rename(tmp_path / "1-2_LB.txt")
    (tmp_path / "1-2.json").rename(tmp_path / "1-2.JSON")
    write_small(tmp_path, "12-1", meta=GOOD_META)
    assert [p.name for p in list_trials(tmp_path)] == ["1-2_LB.txt", "12-1_lb.txt"]
    t = read_trial(tmp_path / "1-2_LB.txt")
    assert (t.subject, t.trial, t.trial_bounds) == (1, 2, (1, 10))
    (tmp_path / "x-1_lb.txt").write_text("")
    (tmp_path / "7-1.json").write_text("{}")
    assert stray_files(tmp_path) == ["x-1_lb.txt: not a '<subject>-<trial>_lb.txt' name, not read",
                                     "7-1.json: no '7-1_lb.txt' beside it, not read"]
    write_small(tmp_path, "012-1", meta=GOOD_META)
    with pytest.raises(HostError, match="012-1_lb.txt and 12-1_lb.txt are both subject 12 trial 1; keep one"):
        list_trials(tmp_path)


def test_twin_files_are_an_error_with_nothing_written(tmp_path, capsys) -> None:
    """The command refuses an ambiguous folder: exit 1, one line on stderr naming the files, no output."""
    write_small(tmp_path, "1-2", meta=GOOD_META)
    write_small(tmp_path, "01-2", meta=GOOD_META)
    out = tmp_path / "o" / "eval.csv"
    out.parent.mkdir()
    assert main(["evaluate", "ipol", str(tmp_path), "--out", str(out), "-q"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "01-2_lb.txt and 1-2_lb.txt are both subject 1 trial 2" in err
    assert not list(out.parent.iterdir())


def test_one_subject_claims_no_interval_and_no_choice(tmp_path) -> None:
    """One subject (synthetic walks): a bootstrap over subjects would draw that subject every time, so the table
    prints no interval, scores no choice and says why, and the folds' constants are said to be the defaults by
    absence."""
    write_ipol_trial(tmp_path, 7, 1, seed=1)
    write_ipol_trial(tmp_path, 7, 2, seed=2)
    res = run_ipol(tmp_path, tmp_path / "out")
    assert res.rc == 0, res.err
    assert "1 subjects, 1 evaluated trials" in res.out
    assert "one subject: no other subject to choose on, so the defaults stand" in res.out
    assert "choices against the simpler one: not scored (one subject: a bootstrap over subjects" in res.out
    assert all("[" not in ln for ln in offline_table(res.out))


def test_no_foot_events_anywhere_scores_distance_and_says_the_defaults_stand(tmp_path) -> None:
    """Lab walks without foot sensors (two synthetic subjects, no foot events, no U-turn in the JSON): every trial
    is scored for distance and named as left out of the event scores; the constants are the defaults, said so."""
    for subject in (1, 2):
        for trial in (1, 2):
            write_ipol_trial(tmp_path, subject, trial, seed=10 * subject + trial)
            edit_json(tmp_path / f"{subject}-{trial}.json",
                      lambda m: [m.pop(k) for k in ("LeftFootEvents", "RightFootEvents", "UTurnBoundaries")])
    res = run_ipol(tmp_path, tmp_path / "out")
    assert res.rc == 0, res.err
    assert res.err.count("no foot-sensor heel strike between the trial boundaries") == 4
    assert "no criterion to choose the event and step-counting constants by, so the defaults stand" in res.out
    rows = list(csv.DictReader(io.StringIO("\n".join(res.lines))))
    main = [r for r in rows if r["variant"] == "main" and r["estimator"] == "M2"]
    assert [(r["subject"], r["trial"], r["reference_steps"]) for r in main] == [("1", "2", "0"), ("2", "2", "0")]
    assert all(float(r["ratio"]) == pytest.approx(1.0, abs=0.05) for r in main)


# ---------------------------------------------------------------------------- walks of another distance


def _synthetic_folder(folder: Path) -> Path:
    """Three synthetic subjects of two trials each (trial 1 calibrates, trial 2 is scored)."""
    folder.mkdir(parents=True, exist_ok=True)
    for subject in (1, 2, 3):
        for trial in (1, 2):
            write_ipol_trial(folder, subject, trial, seed=10 * subject + trial)
    return folder


def _json_rows(folder: Path, out_dir: Path, *extra: str) -> dict[tuple, dict]:
    """The command's rows (``--json``: full precision) by (subject, trial, estimator, variant, uturn)."""
    res = run_ipol(folder, out_dir, "--json", *extra)
    assert res.rc == 0, res.err
    return {(r["subject"], r["trial"], r["estimator"], r["variant"], r["uturn"]): r
            for r in json.loads(res.out)["rows"]}


@pytest.fixture(scope="module")
def synthetic_20(tmp_path_factory) -> tuple[Path, dict[tuple, dict]]:
    folder = _synthetic_folder(tmp_path_factory.mktemp("walks") / "in")
    return folder, _json_rows(folder, folder.parent / "out20")


#: Variants whose K is the subject's first trial's alone (the k-prior rows weigh K by the calibration distance
#: against a prior worth d0 metres: another distance weighs them otherwise, by design).
_FIRST_TRIAL_K = ("main", "uturn-exclude", "height-unknown", "m3-single-support-speed", "baseline")


def test_another_distance_leaves_calibrated_ratios_and_halves_m3(synthetic_20, tmp_path) -> None:
    """``--distance-m 40`` on walks that are the same: K = distance / calibration sum doubles, so every calibrated
    ratio (M1, M2, M4, M5; the recipe's M2, M4) is the 20 m run's, while M3, which has no K, reads half as far."""
    folder, rows20 = synthetic_20
    rows40 = _json_rows(folder, tmp_path / "out40", "--distance-m", "40")
    assert rows40.keys() == rows20.keys()
    checked = {"M3": 0, "K": 0}
    for key, r20 in rows20.items():
        if key[3] not in _FIRST_TRIAL_K:
            continue
        r40 = rows40[key]
        assert (r20["walked_distance_m"], r40["walked_distance_m"]) == (20.0, 40.0)
        want = r20["ratio"] / 2 if key[2] == "M3" else r20["ratio"]
        assert r40["ratio"] == pytest.approx(want, rel=1e-12, abs=1e-15), key
        checked["M3" if key[2] == "M3" else "K"] += 1
    assert checked["M3"] >= 3 and checked["K"] >= 12


def test_a_trials_walked_distance_scales_that_trial_alone(synthetic_20, tmp_path) -> None:
    """``WalkedDistance_m`` = 25 in a scored trial's JSON: that trial's ratios (calibrated or M3) are 20/25 of
    the 20 m run's, every other row unchanged; in a calibration trial, its subject's calibrated ratios scale by
    25/20 and its M3 ratios stay (the scored trial is still 20 m)."""
    folder, rows20 = synthetic_20
    edit_json(folder / "2-2.json", lambda m: m.update(WalkedDistance_m=25))
    edit_json(folder / "3-1.json", lambda m: m.update(WalkedDistance_m=25.0))
    try:
        rows = _json_rows(folder, tmp_path / "out")
    finally:
        edit_json(folder / "2-2.json", lambda m: m.pop("WalkedDistance_m"))
        edit_json(folder / "3-1.json", lambda m: m.pop("WalkedDistance_m"))
    for key, r20 in rows20.items():
        if key[3] not in _FIRST_TRIAL_K:
            continue
        subject, estimator = key[0], key[2]
        scale = (20 / 25 if subject == 2 else 25 / 20 if subject == 3 and estimator != "M3" else 1.0)
        assert rows[key]["walked_distance_m"] == (25.0 if subject == 2 else 20.0)
        assert rows[key]["ratio"] == pytest.approx(r20["ratio"] * scale, rel=1e-12, abs=1e-15), key


@pytest.mark.parametrize("value", ["0", "-3", "nan", "inf", "twenty"])
def test_a_bad_distance_is_a_usage_error_naming_the_option(tmp_path, value) -> None:
    so, se = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(so), contextlib.redirect_stderr(se), pytest.raises(SystemExit) as stop:
        main(["evaluate", "ipol", str(tmp_path), "--out", str(tmp_path / "e.csv"), "--distance-m", value])
    assert stop.value.code == 2 and so.getvalue() == ""
    message = se.getvalue().strip().splitlines()[-1]
    assert "--distance-m" in message and "> 0" in message and "Traceback" not in se.getvalue()
    assert not (tmp_path / "e.csv").exists()


@pytest.mark.parametrize("value", [0, -1.5, "20", True, None, [20]])
def test_a_bad_walked_distance_skips_the_trial_naming_file_and_field(tmp_path, value) -> None:
    """A ``WalkedDistance_m`` that is not a number of metres > 0: that trial is skipped, naming the JSON and the
    field; the rest is scored."""
    folder = _synthetic_folder(tmp_path / "in")
    edit_json(folder / "1-2.json", lambda m: m.update(WalkedDistance_m=value))
    res = run_ipol(folder, tmp_path / "out")
    assert res.rc == 0, res.err
    assert re.search(r"skipped: 1-2_lb\.txt: .*1-2\.json: 'WalkedDistance_m' must be .* > 0, found", res.err), res.err
    assert "2 subjects, 2 evaluated trials" in res.out     # subject 1 keeps its calibration trial alone


def test_m3_decomposition_reads_each_trials_distance() -> None:
    """M3 without K over the trial's walked distance: the same steps over 40 m read half the 20 m ratio, and the
    double support the distance implies is (distance - sum S1) / steps."""
    n = 30
    steps = {"foot": np.full(n, 0.7)}
    trial = {d: TrialM3(1, 2, True, np.zeros(n, bool), np.full(n, 0.55), np.full(n, 0.4), np.full(n, 0.5),
                        {"foot": np.full(n, 0.2)}, steps, n, 0.2, 1.8, 60.0, "M", distance_m=d) for d in (20.0, 40.0)}
    assert trial[20.0].ratio("foot") == pytest.approx(n * 0.7 / 20.0, rel=1e-12)
    assert trial[40.0].ratio("foot") == pytest.approx(trial[20.0].ratio("foot") / 2, rel=1e-12)
    assert trial[40.0].implied_double_support_m() == pytest.approx((40.0 - n * 0.5) / n, rel=1e-12)
