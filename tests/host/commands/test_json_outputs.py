"""``--json`` of every command whose output is a table: the commands the issue names have it, the document
parses, and every number the text prints is in the document (the same numbers, not a second computation)."""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import re
from itertools import permutations

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.host.cli import build_parser, main

#: The commands the issue asks ``--json`` of (a table on stdout).
TABLE_COMMANDS = {"info", "estimate", "budget", "device status", "device identify", "compare", "evaluate", "batch",
                  "calibrate", "calibrate-k"}

_ISO_TIME = re.compile(r"\d{4}-\d\d-\d\dT[\d:]+(?:[+-]\d\d:\d\d)?")
#: A number standing alone in the text (not part of a name such as Q2.29, v1, P32, mul16x16s); 9,412 is one.
_NUMBER = re.compile(r"(?<![\w.,])[-+]?\d{1,3}(?:,\d{3})+(?:\.\d+)?(?![\w.])|(?<![\w.,])[-+]?\d+(?:\.\d+)?(?![\w.])")


def _json_commands() -> set[str]:
    def walk(name: str, parser: argparse.ArgumentParser):
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            return {name} if any("--json" in a.option_strings for a in parser._actions) else set()
        return set().union(*(walk(f"{name} {n}".strip(), p) for n, p in subs[0].choices.items()))

    return walk("", build_parser())


def test_the_table_commands_have_json() -> None:
    assert TABLE_COMMANDS <= _json_commands()


def _leaves(x):
    if isinstance(x, dict):
        for v in x.values():
            yield from _leaves(v)
    elif isinstance(x, list):
        for v in x:
            yield from _leaves(v)
    else:
        yield x


def _run(argv: list[str]) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(argv)
    return code, out.getvalue()


def _numbers_missing_from_json(text: str, doc: object) -> list[tuple[str, str]]:
    """Numbers of ``text`` that no number of ``doc`` rounds to (a percentage may be the ratio of two)."""
    nums = [float(v) for v in _leaves(doc) if isinstance(v, (int, float)) and not isinstance(v, bool)]
    strings = " ".join(v for v in _leaves(doc) if isinstance(v, str))
    missing = []
    for line in text.splitlines():
        for m in _NUMBER.finditer(_ISO_TIME.sub("", line)):
            token = m.group(0)
            x = float(token.replace(",", ""))
            d = len(token.split(".")[1]) if "." in token else 0
            tol = 0.51 * 10.0 ** -d
            if any(abs(v - x) <= tol for v in nums) or token in strings:
                continue
            if line[m.end():].lstrip().startswith("%") and any(
                    b and abs(100.0 * a / b - x) <= tol for a, b in permutations(nums, 2)):
                continue
            missing.append((token, line.strip()))
    return missing


@pytest.fixture(scope="module")
def image(tmp_path_factory):
    rng = np.random.default_rng(1)
    logger = Logger(device_id=7)
    logger.record(Motion(acc_g=0.1 * rng.standard_normal((500, 3)) + [0, 0, 1], sampling_rate_hz=50.0),
                  start_time_s=1_700_000_000)
    path = tmp_path_factory.mktemp("json") / "dev.glimg"
    logger.save_image(path)
    return path


@pytest.mark.parametrize("argv", [["info", "{image}"], ["device", "status", "--port", "emu://{image}"],
                                  ["device", "identify", "--port", "emu://{image}"], ["budget"],
                                  ["budget", "--logger-rate", "100"], ["budget", "--config", "hall"],
                                  ["budget", "--config", "morris-6"], ["estimate", "{ipol}"]])
def test_json_holds_the_numbers_of_the_text(argv, image, shared_data) -> None:
    ipol = shared_data / "ipol-lowerback-dev" / "GaitData" / "2-1_lb.txt"
    argv = [a.format(image=image, ipol=ipol) for a in argv]
    code, text = _run(argv)
    code_json, out = _run([*argv, "--json"])
    text = text.replace(str(image), "IMAGE").replace(str(ipol), "IPOL")       # numbers of the paths are not data
    assert code == code_json                           # the same verdict (budget over its limits: 1 in both)
    doc = json.loads(out)
    assert len(_NUMBER.findall(text)) >= 3             # the text really has numbers to compare
    assert _numbers_missing_from_json(text, doc) == []


def test_the_comparison_can_fail() -> None:
    assert _numbers_missing_from_json("500 samples, 0.8 % full, 9,412 cycles", {"n": 500, "c": 9412}) == [
        ("0.8", "500 samples, 0.8 % full, 9,412 cycles")]
    assert _numbers_missing_from_json("0.8 % full", {"n": 4, "of": 500}) == []


def test_compare_and_batch_json_is_the_only_stdout(tmp_path, capsys) -> None:
    image = tmp_path / "in" / "walk.glimg"
    image.parent.mkdir()
    assert main(["record", "--motion", "walk", "--height", "1.75", "--out", str(image), "-q"]) == 0
    capsys.readouterr()
    assert main(["compare", str(image), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["steps"]["offline"] > 10 and {"estimator", "section"} <= set(doc["segments"][0])
    assert main(["batch", str(image.parent), "--out", str(tmp_path / "out"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [r["recording"] for r in doc["recordings"]] == ["walk.glimg"] and doc["recordings"][0]["status"] == "done"
