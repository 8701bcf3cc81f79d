"""``gaitlog budget``: the RAM and cycle budget of the logger with its on-line step algorithm."""

from __future__ import annotations

import pytest

from host.cli import main


def test_budget_at_50_hz_fits(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["budget"]) == 0
    out = capsys.readouterr().out
    assert "total                                         365  fits (+3 bytes)" in out
    assert "cycles at 50 Hz, 18.432 MHz: 92,160 per sample" in out
    number = lambda key: float(out.split(key)[1].split()[0].replace(",", ""))  # noqa: E731
    assert 18_500 <= number("algorithm, mean") <= 20_500          # 19,449 measured on the default walker
    periods = number("algorithm, worst sample") / 92_160
    assert 1.2 <= periods <= 2.2                                  # 1.47: the end of a long step
    backlog = float(out.split("worst backlog")[1].split("(")[1].split()[0])
    assert backlog < 1.2                                          # 0.49 samples behind at worst


def test_budget_at_100_hz_says_what_must_give(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["budget", "--logger-rate", "100"]) == 1
    out = capsys.readouterr().out
    assert "401  DOES NOT FIT (-33 bytes)" in out and "what must give: 33 bytes" in out


@pytest.mark.parametrize("argv, message", [
    (["budget", "--logger-rate", "0"], "argument --logger-rate: must be a finite number >= 1 and <= 1000 Hz, got '0'"),
    (["budget", "--crystal", "40"], "argument --crystal: must be a finite number >= 0.032 and <= 20 MHz, got '40'"),
])
def test_budget_bad_input(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as usage:
        main(argv)
    assert usage.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and err.count("\n") == 1


def test_budget_json_says_the_same_as_the_table(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    assert main(["budget", "--logger-rate", "100", "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["fits"] is False and doc["ram"]["fits"] is False and doc["ram"]["total_bytes"] == 401
    assert doc["sampling_rate_hz"] == 100.0 and doc["cycles"]["available_per_sample"] == pytest.approx(46_080)
