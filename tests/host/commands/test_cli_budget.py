"""``gaitlog budget``: ADC, RAM, cycles, program memory, EEPROM bandwidth and dump time of the logger
configurations of the seed papers against the PIC16F877."""

from __future__ import annotations

import json

import pytest

from gaitlog.firmware_sim.fixedpoint import CYCLES
from gaitlog.firmware_sim.pic import gpsim_logger as gl
from gaitlog.host.cli import main


def test_budget_at_50_hz_fits(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["budget"]) == 0
    out = capsys.readouterr().out
    assert "total                                         368  fits (+0 bytes)" in out
    assert "cycles at 50 Hz, 18.432 MHz: 92,160 per sample" in out
    number = lambda key: float(out.split(key)[1].split()[0].replace(",", ""))  # noqa: E731
    assert 26_000 <= number("algorithm, mean") <= 28_800          # 27,600 on the default walker (I2C: 130 a byte)
    assert 23_500 <= number("mean at the kernels' mean costs") <= 26_500     # 25,243
    periods = number("algorithm, worst sample") / 92_160
    assert 5.0 <= periods <= 8.0          # 7.11: the end of a long step, its filters evaluated again on its a_v
    backlog = float(out.split("worst backlog")[1].split("(")[1].split()[0])
    assert backlog < 8.0                                          # 6.25 samples behind at worst (the buffer holds 32)
    assert "everything fits" in out and "dump, XMODEM-1K 115200 8N1 23.0 s" in out


def test_budget_at_100_hz_says_what_must_give_and_agrees_with_the_chain(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["budget", "--logger-rate", "100", "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["fits"] is False and doc["ram"]["fits"] is False and doc["ram"]["total_bytes"] == 404
    # the step's filters evaluated again on the scratch ring (37-tap FIR at 100 Hz): with the I2C byte at the
    # assembly's 130 cycles the mean load is 88 % and the backlog grows over the walk to 1,418 samples (1,306
    # before the scratch ring's tail writes, the version-3 page commit, the FIR's byte moves and the read's
    # closing byte were counted; 214 at the 99 cycles of the bus alone): more than the 32 the page buffer holds
    cycles, ram = doc["does_not_fit"]
    assert cycles.startswith("cycles: mean load 88 %, backlog 1417.8") and ram == "RAM: 404 of 368 bytes (36 over)"
    assert any("what must give: 36 bytes" in ln for ln in doc["ram"]["lines"])
    assert doc["sampling_rate_hz"] == 100.0 and doc["cycles"]["available_per_sample"] == pytest.approx(46_080)
    # the budget's figures are the chain's own counters on the same walk: RAM of the run's algorithm, and the
    # operation counts times the (measured) cycle table give the counter's mean cycles per sample
    assert doc["ram"]["algorithm_bytes"] == doc["ram"]["algorithm_bytes_of_the_run"]
    counts = doc["cycles"]["operation_counts"]
    from_counts = sum(CYCLES[k] * v for k, v in counts.items()) / doc["n_samples"]
    assert from_counts == pytest.approx(doc["cycles"]["mean_algorithm"], rel=1e-12)
    assert doc["cycles"]["mean_at_kernel_mean_costs"] < doc["cycles"]["mean_algorithm"]
    assert doc["cycles"]["worst_algorithm"] > 30 * doc["cycles"]["available_per_sample"]   # 48 periods


@pytest.mark.parametrize("config, channels, bytes_per_s", [("morris-5", 5, 800), ("morris-6", 6, 800)])
def test_morris_configurations_fit(config: str, channels: int, bytes_per_s: int,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["budget", "--config", config, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["adc_channels"] == channels and doc["sampling_rate_hz"] == 100.0 and doc["online_estimator"] is False
    assert doc["eeprom"]["write_bytes_per_s"] == bytes_per_s and doc["does_not_fit"] == []
    assert doc["ram"]["algorithm_bytes"] == 0 and doc["ram"]["total_bytes"] == 182
    # ADC: (2 + 12) x 1.736 us + 19.72 us acquisition per channel, busy-waited, + 14 cycles of polling and
    # reading (calibrated against gpsim): cycles at 4.608 MIPS
    # the page write: 131 bytes at the assembly's 130 cycles a byte (9 SCL periods of 12 cycles in gpsim + 22)
    # the page commit: header version 3's journal entry every 2 pages, its page write of 19 bytes at 130 and a
    # CRC-16 over 14 bytes at about 60 a byte (estimated; gpsim measures 3,092 with --measure)
    expected = (channels * (186.9 + 16.0 + 14) + 60 * 2 + 20 + 131 * 130 / 16
                + (19 * 130 + 14 * 60) / 32)
    assert doc["cycles"]["logging_per_sample"] == pytest.approx(expected, rel=2e-3)


def test_hall_at_10_khz_cannot_be_sampled(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["budget", "--config", "hall", "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["sampling_rate_hz"] == 10_000.0 and doc["adc_channels"] == 6 and doc["fosc_hz"] == 20e6
    adc, cycles, eeprom = doc["does_not_fit"]
    # 6 x (19.72 us + 12 x 1.6 us) = 233.5 us per sample against a 100 us period
    assert adc.startswith("ADC: 6 channels take 233.5 us per sample") and "at most 4,282 Hz" in adc
    assert doc["adc_max_sampling_rate_hz"] == pytest.approx(1 / (6 * 38.92e-6), rel=1e-3)
    assert cycles.startswith("cycles: the logging interrupt alone needs") and "of 500 per sample" in cycles
    assert eeprom.startswith("EEPROM: 80,000 B/s to write")


@pytest.mark.parametrize("argv, message", [
    (["budget", "--logger-rate", "0"], "argument --logger-rate: must be a finite number >= 1 and <= 1000 Hz, got '0'"),
    (["budget", "--crystal", "40"], "argument --crystal: must be a finite number >= 0.032 and <= 20 MHz, got '40'"),
    (["budget", "--channels", "9"], "argument --channels:"),
])
def test_budget_bad_input(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as usage:
        main(argv)
    assert usage.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and err.count("\n") == 1


@pytest.mark.parametrize("argv, message", [
    (["budget", "--config", "pdp11"], "--config 'pdp11' is not one of alvarez-50, alvarez-100, morris-5"),
    (["budget", "--config", "morris-5", "--estimator", "on"], "--estimator on reads the Alvarez logger's three axes"),
    (["budget", "--all", "--logger-rate", "25"], "--all budgets the five configurations as they are"),
])
def test_budget_bad_configuration(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2                                   # a bad option value or combination: a usage error
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and err.count("\n") == 1


def test_instruments_on_the_logger_morris_fits_hall_refused_with_the_closest_rate() -> None:
    """The kinematics instruments checked by the budget's own rules (one home for the ADC, cycle and EEPROM
    limits): Morris's platform fits at 100 Hz; Hall's six rate channels at 10 kHz do not, and the closest rate
    is the largest at which every rule passes."""
    from dataclasses import replace

    from gaitlog.firmware_sim.budget import CONFIGURATIONS, instrument_fit

    for name in ("morris-5", "morris-6"):
        assert instrument_fit(CONFIGURATIONS[name]) == ([], 100.0)
    short, fastest = instrument_fit(CONFIGURATIONS["hall"])
    assert [s.split(":")[0] for s in short] == ["ADC", "cycles", "EEPROM"]
    assert instrument_fit(replace(CONFIGURATIONS["hall"], sampling_rate_hz=fastest))[0] == []
    assert instrument_fit(replace(CONFIGURATIONS["hall"], sampling_rate_hz=fastest + 1))[0] != []


def test_budget_states_the_memories_lifetime(capsys: pytest.CaptureFixture[str]) -> None:
    """The lifetime of the 24LC1025s under continuous logging, from the write cycles the model counts over
    four laps of the scratch ring, against the design's count: a page write of 32 bytes every 16 samples at
    50 Hz, spread over the ring's 508 pages (65,024 bytes of block 1 before the header slots)."""
    assert main(["budget", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)["endurance"]
    regions = {r["name"]: r for r in doc["regions"]}
    scratch = regions["scratch ring"]
    assert doc["duration_s"] == pytest.approx(4 * 32_512 / 50.0)
    # each page's flushes (4 a lap), and the ring's tail writes before the step records that read past the last
    # flush (counted as the PIC makes them: tests/firmware_sim/test_scratch_tail_writes.py against gpsim): 86 of
    # them on the walk, about 1 % more page writes, 2 of them on the worst page
    flushes = 4 * 128 // 32
    tails = int(scratch["source"].split(" and ")[1].split()[0])
    assert 0 < tails <= 0.02 * 4 * 32_512 / 16 and tails == 86
    assert scratch["worst_cycles"] == flushes + 2
    rate = (flushes + 2) / doc["duration_s"]                     # 0.006921 against the design's 50 / 16 / 508
    assert scratch["cycles_per_s"] == pytest.approx(rate, rel=1e-12) and rate > 50.0 / 16 / 508
    years = 1_000_000 / rate / (8 * 3600) / 365.25                # 13.7 years at 8 h a day (15.45 without tails)
    assert scratch["years_at_8_h_a_day"] == pytest.approx(years, rel=1e-12) and years >= 10.0
    assert scratch["years_at_24_h_a_day"] == pytest.approx(years / 3, rel=1e-12)
    # the memory's lifetime is its first page to wear out: at least 10 years of 8 h a day
    limiting = regions[doc["limiting"]]
    assert doc["years_at_8_h_a_day"] == limiting["years_at_8_h_a_day"] >= 10.0 and doc["fits_10_years"] is True
    assert all(r["years_at_8_h_a_day"] >= doc["years_at_8_h_a_day"] for r in doc["regions"] if r["unit"] == "page")
    # the step records are stored one by one as they come: the step ring's pages wear about as fast
    assert 10.0 <= regions["step ring"]["years_at_8_h_a_day"] <= 40.0


def test_budget_every_memory_lasts_ten_years_with_the_journal_ring(capsys: pytest.CaptureFixture[str]) -> None:
    """The default logger, header version 3: the journal ring's counted cycles are the entries of the run (one
    per two 32-sample pages) spread over its 96 pages from the run's page on, and every region, the PIC's data
    EEPROM included, lasts 10 years of 8 h a day."""
    assert main(["budget", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)["endurance"]
    assert doc["header_version"] == 3 and doc["lines"][0].startswith("memory endurance (the logger, header version 3;")
    regions = {r["name"]: r for r in doc["regions"]}
    assert regions["step ring"]["source"].startswith("step EEPROM block 0: 2662 20-byte records")
    ring = regions["journal ring"]
    entries = int(doc["duration_s"] * 50.0) // 32 // 2             # 4 x 32,512 samples: 2032 entries
    assert ring["worst_cycles"] == -(-entries // 96) == 22
    assert ring["cycles_per_s"] == pytest.approx(22 / doc["duration_s"], rel=1e-12)
    assert ring["years_at_8_h_a_day"] == pytest.approx(1e6 / (22 / doc["duration_s"]) / (8 * 3600) / 365.25)
    assert all(r["years_at_8_h_a_day"] >= 10.0 for r in doc["regions"]), [
        (r["name"], r["years_at_8_h_a_day"]) for r in doc["regions"]]
    assert regions["PIC data EEPROM"]["worst_cycles"] == 2              # a START and a STOP, nothing between


needs_gpsim = pytest.mark.skipif(gl.missing_tools() is not None, reason=f"{gl.missing_tools()}")
IPOL_TRIAL = "ipol-lowerback-dev/GaitData/1-1_lb.txt"


def _within_10_percent(part: dict) -> None:
    measured, estimated = part["measured"]["mean"], part["estimated"]["mean"]
    assert abs(estimated - measured) <= 0.10 * measured, part
    assert part["error"]["mean_cycles"] == pytest.approx(estimated - measured, abs=1e-6)


@needs_gpsim
def test_measure_on_the_simulated_walk(capsys: pytest.CaptureFixture[str]) -> None:
    """--measure: the assembly part in gpsim beside the model, marked measured; the figures are gpsim's
    (the interrupt's period, the listing's RAM), the model's mean for steps 1-3, for steps 1-5 and per step
    record within 10 %."""
    assert main(["budget", "--measure", "--limit", "1200", "--json"]) == 0
    full = json.loads(capsys.readouterr().out)
    doc = full["assembly_part"]
    # the page commit: journal.asm's entry timed in gpsim (tests/firmware_sim/test_pic_journal.py), every 64 samples
    assert "measured in gpsim" in full["cycles"]["page_commit_source"]
    assert full["cycles"]["page_commit_per_sample"] == pytest.approx(3_092.4 / 64, rel=0.01)
    assert doc["measured"] is True and doc["n_samples"] == 1200 and doc["source"].startswith("simulated walker")
    cyc = doc["cycles_per_sample"]
    _within_10_percent(cyc["steps 1-3"])
    isr = cyc["sampling interrupt"]
    assert isr["measured"]["worst"] == isr["measured"]["mean"]                 # branch-free: every sample alike
    # the interrupt's ADC calibrated against gpsim: within 3 % (10.5 % below before)
    assert abs(isr["error"]["mean_percent"]) <= 3.0, isr
    total = cyc["total in assembly"]["measured"]
    assert total["mean"] <= total["p99"] <= total["worst"]
    # a step record takes several periods; the page buffer's 32 samples absorb the backlog
    assert total["worst"] > 3 * 92_160 and doc["period_cycles"] == 92_160
    assert 0 < doc["worst_backlog_samples_measured"] < 32 and doc["worst_backlog_cycles"] > 92_160
    _within_10_percent(cyc["steps 1-5"])
    records = doc["step_records"]
    assert records["n_records"] >= 10 and abs(records["error"]["mean_percent"]) <= 10.0
    assert len(records["records"]) == records["n_records"]
    assert doc["ram_total_bytes_measured"] == gl.memory_map().ram_total_bytes <= 368
    assert 0 < doc["program_words_measured"] <= 8192
    assert "the sample pages' I2C write and commit" in doc["still_estimated"]


@needs_gpsim
def test_measure_on_an_ipol_trial(shared_data, tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    trial = shared_data / IPOL_TRIAL
    if not trial.exists():
        pytest.skip(f"{trial} not present")
    image = tmp_path / "ipol.glimg"
    assert main(["record", "--motion", "replay", str(trial), "--steps", "off", "--start-time", "0",
                 "--out", str(image), "-q"]) == 0
    capsys.readouterr()
    assert main(["budget", "--measure", "--recording", str(image)]) == 0
    out = capsys.readouterr().out
    assert f"the assembly part measured in gpsim on {image}" in out and "still estimated:" in out
    row = next(ln for ln in out.splitlines() if ln.strip().startswith("steps 1-3 "))
    measured, estimated = (float(row.split()[i].replace(",", "")) for i in (2, 6))
    assert abs(estimated - measured) <= 0.10 * measured, row


def test_measure_without_gpsim_gives_the_models_figures(monkeypatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(gl, "missing_tools", lambda: "gpsim not installed")
    assert main(["budget", "--measure", "--limit", "300"]) == 0
    out = capsys.readouterr().out
    assert "not measured (gpsim not installed); the model's figures, estimated:" in out
    assert "measured in gpsim" not in out
    assert "of which page commit             51.7   (header version 3: a 16-byte journal entry every 2 pages (64 " \
           "samples), 3,310 cycles (estimated:" in out


@pytest.mark.parametrize("argv, message", [
    (["budget", "--recording", "x.glimg"], "--recording and --limit choose the walk of --measure"),
    (["budget", "--measure", "--all"], "--measure runs the Alvarez logger's assembly"),
    (["budget", "--measure", "--estimator", "off"], "--measure runs the Alvarez logger's assembly"),
])
def test_measure_usage_errors(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and err.count("\n") == 1


def test_measure_missing_recording_exit_1(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["budget", "--measure", "--recording", str(tmp_path / "none.glimg")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1
