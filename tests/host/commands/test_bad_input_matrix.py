"""Every ``gaitlog`` subcommand x at least 25 kinds of bad input: one error line on stderr naming the problem's
place (the option or the file), a non-zero exit, no traceback, no output file left, the inputs unchanged.

The commands run in-process (``gaitlog.host.cli.main``) in one folder that holds the fixtures; each case snapshots the
folder (names and bytes) before and checks it is identical after. Run as a script for the counts::

    python tests/host/commands/test_bad_input_matrix.py        # prints each failing case and the totals
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import re
import signal
import sys
import zipfile
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

#: Kinds of bad input each command must get, at least.
MIN_KINDS_PER_COMMAND = 25


@dataclass(frozen=True)
class Case:
    """One bad invocation: ``argv`` (``{name}`` is replaced by the fixture's path), the kind of bad input and
    the text the error line must hold (an option name or a fixture's file name)."""

    command: str
    kind: str
    argv: tuple[str, ...]
    place: str
    code: int = 1           # 2: a usage error (a bad option value, a missing or extra argument); 1: data or I/O


# ---------------------------------------------------------------------------------------------------- fixtures
def _npz_with(path: Path, arrays: dict[str, bytes]) -> None:
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in arrays.items():
            zf.writestr(name, data)


def _npy_bytes(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array, allow_pickle=True)
    return buf.getvalue()


def _npy_header_only(shape: tuple[int, ...], dtype: str = "<u2") -> bytes:
    """A ``.npy`` whose header claims ``shape`` but that holds no data."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buf.getvalue()


def build_fixtures(folder: Path) -> dict[str, Path]:
    """Good and bad files in ``folder``; returns name -> path."""
    from gaitlog.host.cli import main

    folder.mkdir(parents=True, exist_ok=True)
    f = {n: folder / n for n in ("walk.glimg", "poses.glimg")}
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["record", "--motion", "walk", "--steps", "off", "--start-time", "0", "--out",
                     str(f["walk.glimg"]), "-q", "--force"]) == 0
        assert main(["record", "--motion", "poses", "--steps", "off", "--start-time", "0",
                     "--out", str(f["poses.glimg"]), "-q", "--force"]) == 0
        assert main(["decode", str(f["walk.glimg"]), "--out", str(folder / "walk"), "-q", "--force"]) == 0
        assert main(["decode", str(f["poses.glimg"]), "--out", str(folder / "poses"), "-q", "--force"]) == 0
        assert main(["calibrate", str(folder / "poses.npz"), "--out", str(folder / "cal.json"),
                     "-q", "--force"]) == 0
        assert main(["calibrate-k", str(folder / "walk.npz"), "--distance", "40", "--out", str(folder / "K.json"),
                     "-q", "--force"]) == 0
    for n in ("walk.npz", "walk.csv", "cal.json", "K.json"):
        f[n] = folder / n
    for extra in ("poses.npz", "poses.csv", "poses.steps.csv", "walk.steps.csv"):
        (folder / extra).unlink(missing_ok=True)
    image = f["walk.glimg"].read_bytes()
    npz = f["walk.npz"].read_bytes()
    rng = np.random.default_rng(13)

    def put(name: str, data: bytes | str) -> None:
        p = folder / name
        p.write_bytes(data.encode() if isinstance(data, str) else data)
        f[name] = p

    put("empty.bin", b"")
    put("truncated.glimg", image[:200])          # cut inside the preamble (its copy at the end is gone too)
    put("garbage.bin", rng.integers(0, 256, 5000, dtype=np.uint8).tobytes())
    put("garbage.txt", "hello world\nthis is not a recording\n")
    put("latin1.csv", "x;y;z\n\xe9\xe8\xff,1,2\n".encode("latin-1"))
    damaged = bytearray(image)
    damaged[8:40] = bytes(32)                     # image header zeroed, in both copies of the preamble
    end_copy = image.rfind(image[16:48]) - 16     # the preamble's copy at the end of a version-3 image
    damaged[end_copy + 8:end_copy + 40] = bytes(32)
    put("damaged_header.glimg", bytes(damaged))
    put("truncated.npz", npz[: len(npz) // 2])
    zipped = bytearray(npz)
    mid = len(zipped) // 2
    zipped[mid:mid + 64] = bytes(64)              # damaged deflate stream inside the zip
    put("damaged_zip.npz", bytes(zipped))
    _npz_with(folder / "object.npz", {"codes.npy": _npy_bytes(np.array([{"a": 1}], dtype=object))})
    f["object.npz"] = folder / "object.npz"
    _npz_with(folder / "huge_header.npz", {"codes.npy": _npy_header_only((1 << 40, 3))})
    f["huge_header.npz"] = folder / "huge_header.npz"
    put("gap.csv", "time_s,x_g,y_g,z_g\n0,0,0,1\n0.001,0,0,1\n0.002,0,0,1\n200000,0,0,1\n")
    put("nan.csv", "time_s,x_g,y_g,z_g\n0,nan,nan,nan\n0.02,nan,nan,nan\n0.04,inf,inf,inf\n")
    put("ragged.csv", "time_s,x_g,y_g,z_g\n0,0,0,1\n0.02,0\n0.04,0,0,1,5,6\n")
    put("backwards.csv", "time_s,x_g,y_g,z_g\n0,0,0,1\n0.02,0,0,1\n0.01,0,0,1\n")
    put("nested.json", "[" * 100_000 + "]" * 100_000)
    cal = json.loads(f["cal.json"].read_text())
    ragged = dict(cal)
    for key, value in cal.items():
        if isinstance(value, list):
            ragged[key] = [value, [1, 2], "x"]
    put("ragged_cal.json", json.dumps(ragged))
    k = json.loads(f["K.json"].read_text())
    put("ragged_k.json", json.dumps({**k, **{key: [[1], [2, 3]] for key in k if key.startswith("k")}}))
    put("wrongtype_k.json", json.dumps({**k, "leg_length_m": "long", "k_m1": None}))
    put("nan_k.json", json.dumps({**k, "k_m1": float("nan"), "leg_length_m": -1.0}))
    put("wrongtype_cal.json", json.dumps({**cal, **{key: {"a": 1} for key in cal if key not in ("cal_type",
                                                                                               "format_version")}}))
    put("notjson.json", "{not json")
    put("k_as_cal.json", f["K.json"].read_text())
    put("image_copy.csv", image)                  # a logger image under a name decode writes (output = input)
    (folder / "adir").mkdir(exist_ok=True)
    f["adir"] = folder / "adir"
    (folder / "emptydir").mkdir(exist_ok=True)
    f["emptydir"] = folder / "emptydir"
    link = folder / "walk_link.npz"
    if not link.exists():
        link.symlink_to("walk.npz")
    f["walk_link.npz"] = link
    f["missing.npz"] = folder / "missing.npz"
    f["missing.glimg"] = folder / "missing.glimg"
    f["missing.json"] = folder / "missing.json"
    f["nofolder/out"] = folder / "nofolder" / "out"
    f["underfile/out"] = folder / "walk.csv" / "out"
    return f


# ------------------------------------------------------------------------------------------------------- cases
#: Bad recording files every command reading a recording must refuse (name, place = the file's name).
RECORDING_FILES = ("missing.npz", "adir", "empty.bin", "truncated.glimg", "garbage.bin", "garbage.txt",
                   "latin1.csv", "damaged_header.glimg", "truncated.npz", "damaged_zip.npz", "object.npz",
                   "huge_header.npz", "gap.csv", "nan.csv", "ragged.csv", "backwards.csv")
#: Bad logger files (decode, info, serve, dump's emu://).
LOGGER_FILES = ("missing.glimg", "adir", "empty.bin", "truncated.glimg", "garbage.bin", "garbage.txt",
                "damaged_header.glimg", "walk.npz", "walk.csv")
#: Bad JSON files where a calibration is expected.
CAL_FILES = ("missing.json", "nested.json", "ragged_cal.json", "wrongtype_cal.json", "notjson.json", "k_as_cal.json",
             "garbage.bin", "adir")
#: ... and where K is expected.
K_FILES = ("missing.json", "nested.json", "ragged_k.json", "wrongtype_k.json", "nan_k.json", "notjson.json",
           "cal.json", "garbage.bin", "adir")
#: Bad values of a positive, finite number.
BAD_POSITIVE = ("nan", "inf", "-inf", "0", "-5", "1e300", "abc", "")
#: Bad values of a finite number of any sign.
BAD_FINITE = ("nan", "inf", "-inf", "1e300", "abc")
#: Bad values of a count that must be >= 1.
BAD_COUNT = ("0", "-1", "10000000000", "1.5", "abc")


def _cases() -> list[Case]:
    cases: list[Case] = []

    def add(command: str, kind: str, argv: list[str], place: str, code: int = 1) -> None:
        cases.append(Case(command, kind, tuple(argv), place, code))

    def usage(command: str, kind: str, argv: list[str], place: str) -> None:
        add(command, kind, argv, place, 2)

    def options(command: str, base: list[str], option: str, values: tuple[str, ...]) -> None:
        for v in values:
            usage(command, f"{option} {v!r}", [*base, option, v], option)

    def outputs(command: str, base: list[str], option: str, same_as: str, suffix: str = "") -> None:
        """The output ``option``: equal to the input ``same_as`` (as given and through a symlink), in a missing
        folder, a folder, under a file, unwritable."""
        add(command, f"{option} = the input", [*base, option, f"{{{same_as}}}"], option)
        if same_as == "walk.npz":
            add(command, f"{option} = the input by a symlink", [*base, option, "{walk_link.npz}"], option)
        add(command, f"{option} in a missing folder", [*base, option, "{nofolder/out}" + suffix], option)
        add(command, f"{option} in a missing folder/", [*base, option, "{nofolder/out}/"], option)
        add(command, f"{option} under a file", [*base, option, "{underfile/out}" + suffix], option)
        add(command, f"{option} unwritable", [*base, option, "/proc/gaitlog-out" + suffix], option)

    def recording_input(command: str, before: list[str], after: list[str]) -> None:
        for name in RECORDING_FILES:
            add(command, f"input {name}", [*before, f"{{{name}}}", *after], name)

    # decode
    recording_input_logger = [n for n in LOGGER_FILES]
    for name in recording_input_logger:
        add("decode", f"input {name}", ["decode", f"{{{name}}}", "--out", "{adir}/x"], name)
    for name in ("huge_header.npz", "damaged_zip.npz", "object.npz", "latin1.csv", "nan.csv"):
        add("decode", f"input {name}", ["decode", f"{{{name}}}", "--out", "{adir}/x"], name)
    for name in CAL_FILES:
        add("decode", f"--calibration {name}", ["decode", "{walk.glimg}", "--out", "{adir}/x", "--calibration",
                                                f"{{{name}}}"], name if name != "adir" else "adir")
    add("decode", "--out = the input", ["decode", "{image_copy.csv}", "--out", "{folder}/image_copy"], "--out")
    add("decode", "--out in a missing folder", ["decode", "{walk.glimg}", "--out", "{nofolder/out}"], "--out")
    add("decode", "--out under a file", ["decode", "{walk.glimg}", "--out", "{underfile/out}"], "--out")
    add("decode", "--out unwritable", ["decode", "{walk.glimg}", "--out", "/proc/gaitlog-out"], "--out")
    add("decode", "--out = --calibration", ["decode", "{walk.glimg}", "--calibration", "{walk.csv}", "--out",
                                            "{folder}/walk"], "--out")

    # info
    for name in LOGGER_FILES + ("huge_header.npz", "damaged_zip.npz", "nested.json"):
        add("info", f"input {name}", ["info", f"{{{name}}}"], name)
    options("info", ["info", "--port", "emu://{walk.glimg}"], "--timeout", BAD_POSITIVE)
    options("info", ["info", "--port", "emu://{walk.glimg}"], "--baud", BAD_COUNT)
    add("info", "--port missing device", ["info", "--port", "{folder}/no-such-port"], "no-such-port")
    usage("info", "neither IMAGE nor --port", ["info"], "IMAGE")
    usage("info", "IMAGE and --port", ["info", "{walk.glimg}", "--port", "emu://{walk.glimg}"], "--port")

    # serve (bad inputs only: a good one would serve forever)
    for name in LOGGER_FILES + ("huge_header.npz", "damaged_zip.npz", "nested.json"):
        add("serve", f"input {name}", ["serve", f"{{{name}}}", "--tcp", "0"], name)
    for v in ("70000", "-1", "abc", "1.5", "65536", "99999999999"):
        usage("serve", f"--tcp {v!r}", ["serve", "{walk.glimg}", "--tcp", v], "--tcp")
    options("serve", ["serve", "{walk.glimg}", "--tcp", "0"], "--baud", BAD_COUNT)
    add("serve", "--persist on a missing image", ["serve", "{missing.glimg}", "--persist", "--tcp", "0"],
        "missing.glimg")
    usage("serve", "--pty and --tcp", ["serve", "{walk.glimg}", "--pty", "--tcp", "0"], "--tcp")

    # device
    port = ["--port", "emu://{walk.glimg}"]
    options("device", ["device", "status", *port], "--timeout", BAD_POSITIVE)
    options("device", ["device", "identify", *port], "--baud", BAD_COUNT)
    for name in CAL_FILES:
        add("device", f"set-calibration {name}", ["device", "set-calibration", *port, f"{{{name}}}"], name)
    add("device", "--port missing device", ["device", "status", "--port", "{folder}/no-such-port"], "no-such-port")
    add("device", "emu:// missing image", ["device", "status", "--port", "emu://{missing.glimg}"], "missing.glimg")
    add("device", "emu:// garbage image", ["device", "status", "--port", "emu://{garbage.bin}"], "garbage.bin")
    for v in ("-1", "abc", "99999999999999"):
        usage("device", f"start --start-time {v!r}", ["device", "start", *port, "--start-time", v], "--start-time")
    usage("device", "unknown action", ["device", "explode", *port], "explode")

    # dump
    dump = ["dump", "--port", "emu://{walk.glimg}"]
    for name in LOGGER_FILES:
        add("dump", f"emu:// {name}", ["dump", "--port", f"emu://{{{name}}}", "--out", "{folder}/d.glimg"], name)
    add("dump", "--out = the emulated image", [*dump, "--out", "{walk.glimg}"], "--out")
    add("dump", "--out in a missing folder", [*dump, "--out", "{nofolder/out}"], "--out")
    add("dump", "--out in a missing folder/", [*dump, "--out", "{nofolder/out}/"], "--out")
    add("dump", "--out under a file", [*dump, "--out", "{underfile/out}"], "--out")
    add("dump", "--capture = the emulated image", [*dump, "--out", "{folder}/d.glimg", "--capture", "{walk.glimg}"],
        "--capture")
    add("dump", "--capture = --out", [*dump, "--out", "{folder}/d.glimg", "--capture", "{folder}/d.glimg"], "--capture")
    add("dump", "--capture in a missing folder", [*dump, "--out", "{folder}/d.glimg", "--capture", "{nofolder/out}"],
        "--capture")
    add("dump", "--capture is a folder", [*dump, "--out", "{folder}/d.glimg", "--capture", "{adir}"], "--capture")
    options("dump", [*dump, "--out", "{folder}/d.glimg"], "--timeout", BAD_POSITIVE)
    options("dump", [*dump, "--out", "{folder}/d.glimg"], "--retries", ("-1", "abc", "1.5", "10000000000"))
    options("dump", [*dump, "--out", "{folder}/d.glimg"], "--baud", BAD_COUNT)

    # record
    rec_out = ["--out", "{folder}/r.glimg"]
    recording_input("record", ["record", "--motion", "replay"], rec_out)
    options("record", ["record", "--motion", "walk", *rec_out], "--logger-rate", BAD_POSITIVE)
    options("record", ["record", "--motion", "walk", *rec_out], "--corridor-length", BAD_POSITIVE)
    options("record", ["record", "--motion", "walk", *rec_out], "--height", BAD_POSITIVE)
    options("record", ["record", "--motion", "walk", *rec_out], "--leg-length", ("nan", "-1", "0", "inf"))
    options("record", ["record", "--motion", "poses", *rec_out], "--poses", BAD_COUNT)
    options("record", ["record", "--motion", "replay", "{walk.csv}", *rec_out], "--rate", BAD_POSITIVE)
    options("record", ["record", "--motion", "walk", *rec_out], "--start-time", ("-1", "99999999999999", "abc"))
    options("record", ["record", "--motion", "replay", "{walk.csv}", *rec_out], "--skip-rows", ("-1", "abc"))
    for name in K_FILES:
        add("record", f"--k-file {name}", ["record", "--motion", "walk", *rec_out, "--k-file", f"{{{name}}}"], name)
    outputs("record", ["record", "--motion", "replay", "{walk.npz}"], "--out", "walk.npz")
    usage("record", "--motion unknown", ["record", "--motion", "fly", *rec_out], "--motion")
    usage("record", "--motion replay without file", ["record", "--motion", "replay", *rec_out], "--motion")

    # calibrate
    cal_out = ["--out", "{folder}/c.json"]
    recording_input("calibrate", ["calibrate"], cal_out)
    for option in ("--hold", "--sd-factor"):
        options("calibrate", ["calibrate", "{walk.npz}", *cal_out], option, BAD_POSITIVE)
    options("calibrate", ["calibrate", "{walk.npz}", *cal_out], "--min-angle", ("nan", "inf", "-5", "1e300"))
    options("calibrate", ["calibrate", "{walk.csv}", *cal_out, "--units", "counts"], "--counts-per-g",
            ("nan", "0", "-1", "inf"))
    options("calibrate", ["calibrate", "{walk.csv}", *cal_out, "--units", "counts"], "--zero-counts",
            ("nan", "inf"))
    options("calibrate", ["calibrate", "{walk.csv}", *cal_out], "--rate", BAD_POSITIVE)
    outputs("calibrate", ["calibrate", "{walk.npz}"], "--out", "walk.npz", ".json")

    # estimate
    recording_input("estimate", ["estimate"], [])
    for name in K_FILES:
        add("estimate", f"--k-file {name}", ["estimate", "{walk.npz}", "--k-file", f"{{{name}}}"], name)
    for name in CAL_FILES:
        add("estimate", f"--calibration {name}", ["estimate", "{walk.npz}", "--calibration", f"{{{name}}}"], name)
    options("estimate", ["estimate", "{walk.npz}"], "--height", BAD_POSITIVE + ("17.5", "175", "0.5"))
    options("estimate", ["estimate", "{walk.npz}"], "--leg-length", ("90", "0.1"))
    options("estimate", ["estimate", "{walk.npz}"], "--foot-length", ("nan", "-1", "0", "inf"))
    options("estimate", ["estimate", "{walk.csv}"], "--rate", BAD_POSITIVE)
    outputs("estimate", ["estimate", "{walk.npz}"], "--out", "walk.npz", ".csv")
    add("estimate", "--out = --k-file", ["estimate", "{walk.npz}", "--k-file", "{K.json}", "--out", "{K.json}"],
        "--out")

    # calibrate-k
    k_out = ["--out", "{folder}/k2.json"]
    recording_input("calibrate-k", ["calibrate-k"], ["--distance", "40", *k_out])
    options("calibrate-k", ["calibrate-k", "{walk.npz}", *k_out], "--distance", BAD_POSITIVE)
    options("calibrate-k", ["calibrate-k", "{walk.npz}", *k_out], "--lap-marks", BAD_POSITIVE)
    options("calibrate-k", ["calibrate-k", "{walk.npz}", "--distance", "40", *k_out], "--height", ("nan", "-1", "0"))
    options("calibrate-k", ["calibrate-k", "{walk.csv}", "--distance", "40", *k_out], "--rate", ("nan", "0", "-1"))
    outputs("calibrate-k", ["calibrate-k", "{walk.npz}", "--distance", "40"], "--out", "walk.npz", ".json")

    # evaluate
    for name in ("missing.npz", "walk.csv", "emptydir"):
        add("evaluate", f"ipol folder {name}", ["evaluate", "ipol", f"{{{name}}}", "--out", "{folder}/e.csv"], name)
    sim = ["evaluate", "sim", "--out", "{folder}/ev"]
    options("evaluate", sim, "--subjects", BAD_COUNT)
    options("evaluate", sim, "--workers", BAD_COUNT)
    options("evaluate", sim, "--adc-bits", ("0", "-1", "99", "abc", "11"))
    options("evaluate", ["evaluate", "ipol", "{emptydir}", "--out", "{folder}/e.csv"], "--adc-bits", ("12",))
    options("evaluate", sim, "--logger-rate", BAD_POSITIVE)
    add("evaluate", "sim DIR is a file", ["evaluate", "sim", "{walk.csv}"], "walk.csv")
    add("evaluate", "sim --out under a file", ["evaluate", "sim", "--out", "{underfile/out}"], "--out")
    add("evaluate", "ipol --out in a missing folder", ["evaluate", "ipol", "{emptydir}", "--out", "{nofolder/out}"],
        "--out")
    add("evaluate", "ipol --figure in a missing folder",
        ["evaluate", "ipol", "{emptydir}", "--out", "{folder}/e.csv", "--figure", "{nofolder/out}"], "--figure")
    usage("evaluate", "ipol without --out", ["evaluate", "ipol", "{emptydir}"], "--out")
    usage("evaluate", "unknown dataset", ["evaluate", "mars"], "mars")

    # compare
    recording_input("compare", ["compare"], [])
    options("compare", ["compare"], "--simulate", BAD_COUNT)
    options("compare", ["compare", "--simulate", "1"], "--adc-bits", ("0", "-1", "99", "abc"))
    options("compare", ["compare", "--simulate", "1"], "--workers", ("0", "-1", "abc"))
    options("compare", ["compare", "--simulate", "1"], "--resamples", ("0", "-1", "10000000000", "abc"))
    usage("compare", "--sweep (moved to gaitlog sweep)", ["compare", "--sweep"], "gaitlog sweep --out sweep-out")
    options("compare", ["compare", "{walk.npz}"], "--lap-m", BAD_POSITIVE)
    for name in K_FILES:
        add("compare", f"--k-file {name}", ["compare", "{walk.npz}", "--k-file", f"{{{name}}}"], name)
    outputs("compare", ["compare", "{walk.npz}"], "--out", "walk.npz", ".csv")

    # plot
    recording_input("plot", ["plot"], ["--out", "{folder}/p.png"])
    plot = ["plot", "{walk.npz}", "--out", "{folder}/p.png"]
    options("plot", plot, "--start", ("nan", "inf", "-inf", "abc", "-1"))
    add("plot", "--start after the end", [*plot, "--start", "1e300"], "--start")       # the recording's data
    options("plot", plot, "--duration", ("nan", "inf", "0", "-5", "abc", ""))
    options("plot", plot, "--size", ("0x0", "abc", "100000x100000", "-5x10"))
    options("plot", plot, "--estimators", ("M9", "", ",,"))
    for name in K_FILES:
        add("plot", f"--k-file {name}", [*plot, "--k-file", f"{{{name}}}"], name)
    outputs("plot", ["plot", "{walk.npz}"], "--out", "walk.npz", ".png")

    # pic
    for name in LOGGER_FILES + ("huge_header.npz", "damaged_zip.npz", "truncated.npz", "object.npz", "latin1.csv",
                                "nan.csv"):
        add("pic", f"verify {name}", ["pic", "verify", f"{{{name}}}"], name)
    options("pic", ["pic", "verify", "{walk.glimg}"], "--limit", ("0", "-1", "abc", "1.5", "", "nan", "1e3"))
    usage("pic", "unknown action", ["pic", "explode", "{walk.glimg}"], "explode")
    usage("pic", "no recording", ["pic", "verify"], "RECORDING")
    usage("pic", "unknown option", ["pic", "verify", "{walk.glimg}", "--limits", "3"], "--limits")
    usage("pic", "extra argument", ["pic", "verify", "{walk.glimg}", "extra"], "extra")

    # ranges
    recording_input("ranges", ["ranges"], [])
    options("ranges", ["ranges"], "--simulate", BAD_COUNT)
    options("ranges", ["ranges", "{walk.glimg}"], "--margin-bits", ("-1", "17", "abc", "1.5", ""))
    options("ranges", ["ranges", "{walk.glimg}"], "--seed", ("-1", "abc", "1.5", "99999999999999999999999"))
    usage("ranges", "no input", ["ranges"], "RECORDING")
    usage("ranges", "unknown option", ["ranges", "{walk.glimg}", "--margins", "3"], "--margins")
    add("ranges", "a folder without IPOL trials", ["ranges", "{emptydir}"], "emptydir")

    # budget
    options("budget", ["budget"], "--crystal", BAD_POSITIVE + ("1e9", "0.001", "1,5", "0x10"))
    options("budget", ["budget"], "--logger-rate", BAD_POSITIVE)
    options("budget", ["budget"], "--seed", ("-1", "abc", "1.5", "99999999999999999999999"))
    usage("budget", "unknown option", ["budget", "--crystals", "4"], "--crystals")
    usage("budget", "extra argument", ["budget", "extra"], "extra")

    # kinematics
    kin = ["kinematics", "--out", "{folder}/kin"]
    options("kinematics", kin, "--morris-rate", BAD_POSITIVE)
    options("kinematics", kin, "--hall-rate", BAD_POSITIVE)
    options("kinematics", kin, "--snr-db", ("nan", "-inf", "-5", "1e300", "abc"))
    options("kinematics", kin, "--azimuth", ("nan", "400", "abc"))
    options("kinematics", kin, "--elevation", ("nan", "91", "abc"))
    usage("kinematics", "morris without a recording", ["kinematics", "morris", "--out", "{folder}/kin"], "RECORDING")
    add("kinematics", "morris recording missing", ["kinematics", "morris", "{missing.npz}", "--platform",
                                                   "{walk.csv}", "--out", "{folder}/kin"], "missing.npz")
    add("kinematics", "morris recording is not a sensor CSV", ["kinematics", "morris", "{walk.csv}", "--platform",
                                                               "{cal.json}", "--out", "{folder}/kin"], "walk.csv")
    options("kinematics", kin, "--gyro-noise", ("nan", "inf", "-5", "1e300", "abc"))
    options("kinematics", kin, "--seed", ("-1", "abc"))
    add("kinematics", "--out is a file", ["kinematics", "--out", "{walk.csv}"], "--out")
    add("kinematics", "--out under a file", ["kinematics", "--out", "{underfile/out}"], "--out")

    # simulate
    sim = ["simulate", "--subjects", "1", "--ipol-out", "{folder}/sim-out"]
    options("simulate", sim, "--subjects", ("0", "-1", "10000000000", "abc", "1.5", "", "nan", "inf"))
    options("simulate", sim, "--trials", ("0", "-1", "101", "abc", "1.5"))
    options("simulate", sim, "--seed", ("-1", "abc", "", "nan"))
    options("simulate", sim, "--workers", ("0", "-3", "abc"))
    options("simulate", sim, "--population", ("martians", ""))
    add("simulate", "--ipol-out is a file", ["simulate", "--subjects", "1", "--ipol-out", "{walk.csv}"], "--ipol-out")
    add("simulate", "--ipol-out under a file", ["simulate", "--subjects", "1", "--ipol-out", "{underfile/out}"],
        "--ipol-out")
    add("simulate", "--ipol-out unwritable", ["simulate", "--subjects", "1", "--ipol-out", "/proc/gaitlog-sim"],
        "--ipol-out")
    usage("simulate", "--ipol-out missing", ["simulate", "--subjects", "1"], "--ipol-out")
    usage("simulate", "unknown option", [*sim, "--fast"], "--fast")
    usage("simulate", "extra argument", [*sim, "now"], "now")
    usage("simulate", "-q and -v", [*sim, "-q", "-v"], "-v")

    # demo
    demo = ["demo", "--out", "{folder}/demo-out"]
    options("demo", demo, "--poses", ("0", "-1", "10000000000", "abc", "1.5", "", "1e3", "nan", "inf"))
    options("demo", demo, "--seed", ("-1", "abc", "99999999999999999999999", "", "1.5", "nan"))
    add("demo", "--out is a file with --force", ["demo", "--force", "--out", "{walk.csv}"], "--out")
    add("demo", "--out is a device", ["demo", "--out", "/dev/null"], "--out")
    add("demo", "--out is a file", ["demo", "--out", "{walk.csv}"], "--out")
    add("demo", "--out under a file", ["demo", "--out", "{underfile/out}"], "--out")
    add("demo", "--out a non-empty foreign folder", ["demo", "--out", "{folder}"], "--out")
    add("demo", "--out unwritable", ["demo", "--out", "/proc/gaitlog-demo"], "--out")
    usage("demo", "unknown option", ["demo", "--fast"], "--fast")
    usage("demo", "extra argument", ["demo", "now"], "now")
    usage("demo", "--out without a value", ["demo", "--out"], "--out")
    add("demo", "--out under a missing folder under a file", ["demo", "--out", "{underfile/out}/deeper"], "--out")
    usage("demo", "-q and -v", ["demo", "-q", "-v", "--out", "{folder}/demo-out"], "-v")

    # sweep (a slip would run a 1-task sweep and leave its folder: the snapshot catches it)
    sweep = ["sweep", "--out", "{folder}/sweep-out", "--serial", "--protocol", "short", "--subjects", "1",
             "--adc-bits", "8", "--logger-rate", "50"]
    options("sweep", sweep, "--adc-bits", ("0", "-1", "99", "abc", "", "8,,10", "8,1.5"))
    options("sweep", sweep, "--logger-rate", BAD_POSITIVE + ("5",))
    options("sweep", sweep, "--noise-density", ("nan", "inf", "-1e-4", "1", "abc"))
    options("sweep", sweep, "--subjects", BAD_COUNT)
    options("sweep", sweep, "--seeds", ("-1", "abc", "0,x"))
    options("sweep", sweep, "--estimators", ("M9", "m1", "M1,"))
    options("sweep", sweep, "--workers", ("0", "-1", "abc"))
    for name in ("missing.json", "nested.json", "notjson.json", "garbage.bin", "adir", "cal.json", "latin1.csv"):
        add("sweep", f"--spec {name}", [*sweep, "--spec", f"{{{name}}}"], name)
    add("sweep", "--out is a file", [*sweep, "--out", "{walk.csv}"], "--out")
    add("sweep", "--out under a file", [*sweep, "--out", "{underfile/out}"], "--out")
    add("sweep", "--out unwritable", [*sweep, "--out", "/proc/gaitlog-sweep"], "--out")
    usage("sweep", "--serial and --scheduler", [*sweep, "--scheduler", "tcp://127.0.0.1:8786"], "--scheduler")
    sweep_dask = [a for a in sweep if a != "--serial"]
    for v in ("tcp://", "tcp://127.0.0.1:99999"):
        usage("sweep", f"--scheduler {v!r}", [*sweep_dask, "--scheduler", v], "--scheduler")
    for v in ("{garbage.bin}", "{nested.json}", "{nofolder/out}"):
        add("sweep", f"--scheduler {v!r}", [*sweep_dask, "--scheduler", v], "--scheduler")
    usage("sweep", "without --out", ["sweep", "--serial"], "--out")

    # batch (bad invocations; a bad recording inside the folder is reported by the batch, not refused)
    batch = ["batch", "{emptydir}", "--out", "{folder}/batch-out"]
    add("batch", "FOLDER missing", ["batch", "{folder}/no-such-folder", "--out", "{folder}/batch-out"], "no-such-folder")
    add("batch", "FOLDER is a file", ["batch", "{walk.csv}", "--out", "{folder}/batch-out"], "walk.csv")
    add("batch", "FOLDER without inputs", batch, "emptydir")
    add("batch", "--pattern matching nothing", ["batch", "{folder}", "--out", "{folder}/batch-out", "--pattern",
                                                "*.none"], "--pattern")
    usage("batch", "--pattern absolute", ["batch", "{folder}", "--out", "{folder}/batch-out", "--pattern", "/etc/*"],
        "--pattern")
    for name in CAL_FILES:
        add("batch", f"--calibration {name}", [*batch, "--calibration", f"{{{name}}}"], name)
    for name in K_FILES:
        add("batch", f"--k-file {name}", [*batch, "--k-file", f"{{{name}}}"], name)
    options("batch", batch, "--height", BAD_POSITIVE)
    add("batch", "--out = FOLDER", ["batch", "{emptydir}", "--out", "{emptydir}"], "--out")
    options("batch", batch, "--workers", ("0", "-1", "abc"))
    usage("batch", "--workers and --scheduler", [*batch, "--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"],
          "--scheduler")
    for v in ("tcp://", "tcp://127.0.0.1:99999"):
        usage("batch", f"--scheduler {v!r}", [*batch, "--scheduler", v], "--scheduler")
    for v in ("{garbage.bin}", "{nested.json}", "{nofolder/out}"):
        add("batch", f"--scheduler {v!r}", [*batch, "--scheduler", v], "--scheduler")
    add("batch", "--out is a file", ["batch", "{emptydir}", "--out", "{walk.csv}"], "--out")
    add("batch", "--out under a file", ["batch", "{emptydir}", "--out", "{underfile/out}"], "--out")
    add("batch", "--out unwritable", ["batch", "{emptydir}", "--out", "/proc/gaitlog-batch"], "--out")
    usage("batch", "without --out", ["batch", "{emptydir}"], "--out")
    return cases


CASES = _cases()


# --------------------------------------------------------------------------------------------------- running
def _snapshot(folder: Path) -> dict[str, str]:
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(root) / name
            rel = str(p.relative_to(folder))
            out[rel] = ("dir" if p.is_dir() and not p.is_symlink() else
                        "link" if p.is_symlink() else hashlib.sha256(p.read_bytes()).hexdigest())
    return out


class _Timeout(Exception):
    pass


def _on_alarm(signum, frame):
    raise _Timeout


def run_case(case: Case, fixtures: dict[str, Path], folder: Path, timeout_s: int = 60) -> list[str]:
    """Run ``case``; return the broken promises (empty when the error was as it should be)."""
    from gaitlog.host.cli import main

    names = {**{k: str(v) for k, v in fixtures.items()}, "folder": str(folder)}
    argv = [re.sub(r"\{([^{}]+)\}", lambda m: names[m[1]], a) for a in case.argv]
    before = _snapshot(folder)
    out, err = io.StringIO(), io.StringIO()
    problems: list[str] = []
    old = signal.signal(signal.SIGALRM, _on_alarm)
    signal.alarm(timeout_s)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except _Timeout:
        problems.append(f"ran more than {timeout_s} s (the bad input was not refused)")
        code = None
    except BaseException as exc:  # noqa: BLE001 - a traceback is what we count
        problems.append(f"traceback: {type(exc).__name__}: {str(exc)[:200]}")
        code = None
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    text = err.getvalue()
    lines = text.strip().splitlines()
    if code is not None:
        if code == 0:
            problems.append("exit 0")
        elif code != case.code:
            problems.append(f"exit {code}, not {case.code} ({'usage' if case.code == 2 else 'data or I/O'} error)")
        if "Traceback" in text:
            problems.append("traceback on stderr")
        if len(lines) != 1:
            problems.append(f"{len(lines)} lines on stderr: {text.strip()[:300]!r}")
        elif case.place not in lines[0]:
            problems.append(f"error line does not name {case.place!r}: {lines[0][:300]!r}")
    after = _snapshot(folder)
    if after != before:
        changed = sorted(k for k in before.keys() & after.keys() if before[k] != after[k])
        new = sorted(after.keys() - before.keys())
        gone = sorted(before.keys() - after.keys())
        problems.append(f"files changed {changed} new {new} gone {gone}")
        _restore(folder, fixtures, before, after)
    return problems


def _restore(folder: Path, fixtures: dict[str, Path], before: dict[str, str], after: dict[str, str]) -> None:
    """Put the folder back after a case that changed it (so later cases see the fixtures)."""
    import shutil

    for rel in sorted(after.keys() - before.keys(), reverse=True):
        p = folder / rel
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)
    changed = [k for k in before.keys() & after.keys() if before[k] != after[k]] + list(before.keys() - after.keys())
    if changed:
        fresh = build_fixtures(folder)
        fixtures.update(fresh)


@pytest.fixture(scope="module")
def bad_input_folder(tmp_path_factory) -> tuple[Path, dict[str, Path]]:
    folder = tmp_path_factory.mktemp("bad-input")
    return folder, build_fixtures(folder)


def test_every_command_gets_at_least_25_kinds_of_bad_input():
    from gaitlog.host.cli import _command_modules

    per_command = Counter(c.command for c in CASES)
    for name in _command_modules():
        command = name.replace("_", "-")
        assert per_command[command] >= MIN_KINDS_PER_COMMAND, (command, per_command[command])


@pytest.mark.parametrize("case", CASES, ids=[f"{c.command}: {c.kind}" for c in CASES])
def test_bad_input_is_one_clear_error_line(case, bad_input_folder):
    folder, fixtures = bad_input_folder
    problems = run_case(case, fixtures, folder)
    assert not problems, problems


# ------------------------------------------------------------------------------------------- the overwrite rule
#: Per command: a run whose output (the path after it, under ``{out}``'s folder) already exists, which must be
#: refused without ``--force``; or why the command has no output to refuse. A new command needs a row.
OVERWRITE: dict[str, tuple[tuple[str, ...], str] | str] = {
    "demo": "replaces its own previous output folder; a folder that is not one is refused (cases above)",
    "record": (("record", "--motion", "walk", "--out", "{out}/r.glimg"), "r.glimg"),
    "serve": "writes no file (--persist writes the served image back into itself, as asked)",
    "device": "writes no file (only the logger's memory)",
    "dump": (("dump", "--port", "emu://{walk.glimg}", "--out", "{out}/d.glimg"), "d.glimg"),
    "decode": (("decode", "{walk.glimg}", "--out", "{out}/w"), "w.csv"),
    "info": "writes no file",
    "calibrate": (("calibrate", "{walk.npz}", "--out", "{out}/c.json"), "c.json"),
    "estimate": (("estimate", "{walk.npz}", "--out", "{out}/s.csv"), "s.csv"),
    "calibrate-k": (("calibrate-k", "{walk.npz}", "--distance", "40", "--out", "{out}/k.json"), "k.json"),
    "evaluate": (("evaluate", "ipol", "{emptydir}", "--out", "{out}/e.csv"), "e.csv"),
    "compare": (("compare", "{walk.npz}", "--out", "{out}/c.csv"), "c.csv"),
    "simulate": (("simulate", "--subjects", "1", "--ipol-out", "{out}/sim"), "sim/1-1_lb.txt"),
    "sweep": "resumes into its --out folder: a re-run computes only the tasks that are missing",
    "batch": "resumes into its --out folder: a re-run skips the recordings it finished",
    "plot": (("plot", "{walk.npz}", "--out", "{out}/p.png"), "p.png"),
    "budget": "writes no file",
    "ranges": "writes no file",
    "pic": "writes no file",
    "kinematics": (("kinematics", "--out", "{out}/kin"), "kin/old.txt"),
}


def _top_commands() -> dict:
    import argparse

    from gaitlog.host.cli import build_parser

    parser = build_parser()
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def test_every_command_has_a_row_of_the_overwrite_rule() -> None:
    commands = _top_commands()
    assert set(commands) == set(OVERWRITE), (f"commands without a row in OVERWRITE: {set(commands) - set(OVERWRITE)}; "
                                             f"rows of no command: {set(OVERWRITE) - set(commands)}")
    for name, row in OVERWRITE.items():
        options = {o for a in commands[name]._actions for o in a.option_strings}
        assert isinstance(row, str) or "--force" in options, f"{name} writes files but has no --force"


@pytest.mark.parametrize("command", [c for c, row in OVERWRITE.items() if not isinstance(row, str)])
def test_an_existing_output_is_refused_without_force(command, bad_input_folder, tmp_path, capsys) -> None:
    from gaitlog.host.cli import main

    _, fixtures = bad_input_folder
    argv, existing = OVERWRITE[command]
    names = {**{k: str(v) for k, v in fixtures.items()}, "out": str(tmp_path)}
    target = tmp_path / existing
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_bytes(b"keep me")
    before = _snapshot(tmp_path)
    code = main([re.sub(r"\{([^{}]+)\}", lambda m: names[m[1]], a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and "--force" in err[0], (code, err)
    assert _snapshot(tmp_path) == before


def _main() -> int:
    import resource
    import tempfile
    import time

    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))  # a hostile file raises MemoryError, not OOM
    folder = Path(tempfile.mkdtemp(prefix="gaitlog-bad-input-"))
    fixtures = build_fixtures(folder)
    counts = Counter()
    t0 = time.perf_counter()
    only = sys.argv[1:]
    for case in CASES:
        if only and case.command not in only:
            continue
        problems = run_case(case, fixtures, folder, timeout_s=20)
        counts["cases"] += 1
        if problems:
            counts["failed"] += 1
            counts["tracebacks"] += any(p.startswith("traceback") for p in problems)
            counts["exit 0"] += "exit 0" in problems
            counts["files changed"] += any(p.startswith("files changed") for p in problems)
            print(f"{case.command}: {case.kind}: " + "; ".join(problems), flush=True)
    print(f"{counts['cases']} cases in {time.perf_counter() - t0:.0f} s: {counts['failed']} failed, "
          f"{counts['tracebacks']} tracebacks, {counts['exit 0']} exit 0, {counts['files changed']} with files "
          "changed or left")
    return 0


if __name__ == "__main__":
    sys.exit(_main())
