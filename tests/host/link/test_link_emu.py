"""gaitlog.host.link.logger_link over the in-process emu:// device: commands, dump round trip, noisy line, cut line + resume.

Truth is the device's own RecordResult (what the firmware stored), never the host's output.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_file
from gaitlog.host.link.logger_link import LoggerLink
from gaitlog.host.link.memory_dump import dump_memory

CAP = 65536


def smooth_motion(n: int, seed: int = 0) -> Motion:
    """``n`` samples at 50 Hz of a slowly turning 1 g vector plus wobble, all within ±2 g."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 50.0
    ph = rng.uniform(0, 2 * np.pi, 3)
    acc = np.c_[np.sin(0.05 * t + ph[0]), 0.6 * np.sin(0.031 * t + ph[1]), np.cos(0.05 * t + ph[0])]
    acc += 0.3 * np.sin(2 * np.pi * 1.7 * t[:, None] + ph)
    return Motion(acc_g=acc, sampling_rate_hz=50.0)


def record_image(path: Path, n: int, *, overwrite: bool = False, seed: int = 0):
    logger = Logger(overwrite=overwrite)
    result = logger.record(smooth_motion(n, seed), start_time_s=1_700_000_000)
    logger.save_image(path)
    return logger, result


def truth_of(result, capacity: int = CAP):
    codes = np.asarray(result.codes)
    flags = np.asarray(result.flags)
    return codes[-capacity:], flags[-capacity:]


@pytest.fixture(scope="module")
def small_image(tmp_path_factory):
    path = tmp_path_factory.mktemp("emu") / "small.glimg"
    logger, result = record_image(path, 3000, seed=1)
    return path, result


@pytest.fixture(scope="module")
def wrapped_image(tmp_path_factory):
    path = tmp_path_factory.mktemp("emu") / "wrapped.glimg"
    logger, result = record_image(path, CAP + 4321, overwrite=True, seed=2)
    return path, result


def test_commands(small_image):
    path, result = small_image
    with LoggerLink(f"emu://{path}", timeout_s=0.5) as link:
        info = link.identify()
        assert info["protocol_version"] == 2 and info["capacity_samples"] == CAP
        st = link.status()
        assert st["state"] == 0 and st["samples_written"] == 3000 and st["write_index"] == 3000
        raw, header = link.read_header()
        assert len(raw) == 256 and header.n_stored == 3000 and not header.wrapped
        data = link.read(4 * 10, 8)
        words = np.frombuffer(data, "<u4").astype(np.int64)
        codes = np.asarray(result.codes)[10:12].astype(np.int64)
        flags = np.asarray(result.flags)[10:12].astype(np.int64)
        np.testing.assert_array_equal(words, codes[:, 0] | codes[:, 1] << 10 | codes[:, 2] << 20 | flags << 30)
        with pytest.raises(HostError, match="BAD_ADDRESS"):
            link.read(4 * CAP - 4, 8)


@pytest.mark.parametrize("which", ["small", "wrapped"])
def test_dump_round_trip_bit_identical(which, small_image, wrapped_image, tmp_path):
    path, result = small_image if which == "small" else wrapped_image
    out = tmp_path / "dumped.glimg"
    with LoggerLink(f"emu://{path}", timeout_s=0.5) as link:
        dump = dump_memory(link, out, progress=False)
    assert dump.complete_
    rec = decode_file(out)
    codes, flags = truth_of(result)
    assert rec.valid.all() and rec.gaps == []
    np.testing.assert_array_equal(rec.codes, codes)
    np.testing.assert_array_equal(rec.flags, flags)
    np.testing.assert_array_equal(rec.sample_numbers, np.asarray(result.sample_numbers)[-CAP:])
    meta = json.loads((tmp_path / "dumped.glimg.json").read_text())
    import hashlib

    assert meta["sha256"] == hashlib.sha256(out.read_bytes()).hexdigest()
    assert meta["complete"] and meta["missing_ranges"] == [] and meta["device"]["device_id"] == 1
    assert meta["format_version"] == 2 and meta["device"]["sampling_rate_hz"] == 50.0  # Hz, not the wire's mHz
    assert "sampling_rate_millihz" not in meta["device"] and meta["device"]["firmware_version"] == "1.3"
    assert not (tmp_path / "dumped.glimg.part").exists()


def test_dump_through_noisy_line_is_exact(wrapped_image, tmp_path):
    path, result = wrapped_image
    out = tmp_path / "noisy.glimg"
    with LoggerLink(f"emu://{path}?corrupt=0.001&seed=4", timeout_s=0.2) as link:
        dump = dump_memory(link, out, progress=False, retries=12)
        n_corrupted = link.serial.faults.n_corrupted
    assert n_corrupted > 200  # the line really was noisy (one byte in a thousand of > 262 kB)
    assert dump.complete_, dump.missing_ranges_
    assert dump.metadata_["frames_damaged"] > 0 and dump.metadata_["passes"] > 1
    rec = decode_file(out)
    codes, flags = truth_of(result)
    assert rec.valid.all()
    np.testing.assert_array_equal(rec.codes, codes)
    np.testing.assert_array_equal(rec.flags, flags)


def test_cut_dump_completes_with_resume(wrapped_image, tmp_path):
    path, result = wrapped_image
    out = tmp_path / "cut.glimg"
    state = tmp_path / "cut.glimg.part"
    with LoggerLink(f"emu://{path}?cut_after=120000", timeout_s=0.1, retries=1) as link:
        with pytest.raises(HostError):
            dump_memory(link, out, progress=False)
    assert state.exists() and not out.exists() and not (tmp_path / "cut.glimg.json").exists()
    with LoggerLink(f"emu://{path}", timeout_s=0.5) as link:
        dump = dump_memory(link, out, progress=False, resume=True)
        received = link.stats.bytes_received
    assert dump.complete_ and dump.metadata_["resumed"]
    # only what was missing travelled the second time
    assert received < 4 * CAP - 100_000
    assert not state.exists()
    rec = decode_file(out)
    codes, flags = truth_of(result)
    assert rec.valid.all()
    np.testing.assert_array_equal(rec.codes, codes)  # no sample lost ...
    assert len(np.unique(rec.sample_numbers)) == rec.n_samples == CAP  # ... or doubled
    np.testing.assert_array_equal(rec.flags, flags)


def test_resume_refuses_a_changed_device(small_image, wrapped_image, tmp_path):
    out = tmp_path / "x.glimg"
    with LoggerLink(f"emu://{wrapped_image[0]}?cut_after=50000", timeout_s=0.1, retries=0) as link:
        with pytest.raises(HostError):
            dump_memory(link, out, progress=False)
    with LoggerLink(f"emu://{small_image[0]}", timeout_s=0.5) as link:
        with pytest.raises(HostError, match="it holds recording 1 .* the device now recording 1"):
            dump_memory(link, out, progress=False, resume=True)
    assert not out.exists()


def test_missing_port_and_bad_url():
    with pytest.raises(HostError, match="/dev/does-not-exist"):
        LoggerLink("/dev/does-not-exist")
    with pytest.raises(HostError, match="unknown option"):
        LoggerLink("emu://?colour=red")


def test_dead_line_fails_fast_with_clear_message(small_image, tmp_path):
    with LoggerLink(f"emu://{small_image[0]}?cut_after=0", timeout_s=0.05, retries=1) as link:
        with pytest.raises(HostError, match="no answer to IDENTIFY: not one byte received"):
            dump_memory(link, tmp_path / "d.glimg", progress=False)
    assert list(tmp_path.iterdir()) == []


def test_start_stop_erase_and_busy(small_image, tmp_path):
    path, _ = small_image
    with LoggerLink(f"emu://{path}", timeout_s=0.5) as link:
        link.erase()
        assert link.status()["samples_written"] == 0
        link.start(1_700_000_000, overwrite=True)
        assert link.status()["state"] == 1
        with pytest.raises(HostError, match="BUSY"):
            link.read(0, 4)
        with pytest.raises(HostError, match="logging"):
            dump_memory(link, tmp_path / "busy.glimg", progress=False)
        link.stop()
        st = link.status()
        assert st["state"] == 0
        _, header = link.read_header()
        assert header.overwrite and header.start_time_s == 1_700_000_000
    assert list(tmp_path.iterdir()) == []
