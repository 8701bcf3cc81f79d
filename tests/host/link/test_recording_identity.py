"""Every recording has an identity that cannot repeat (PROTOCOL.md 2.4), and the host checks it: a dump resumes only
into the same recording, a wire capture uses only the DATA frames of one recording. Before header version 2,
two recordings with the same device id, start time and length had byte-identical headers: a resume joined
them (5,120 of 8,300 samples from the wrong one, "complete") and a capture of both decoded wrong samples."""

from __future__ import annotations

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger, PowerCut
from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_bytes, decode_file
from gaitlog.host.link.logger_link import LoggerLink
from gaitlog.host.link.memory_dump import dump_memory
from gaitlog.protocol.frames import FrameType, build_payload, encode_frame
from tests.host.link.test_link_emu import smooth_motion


def _twins(tmp_path, n=8300):
    """Two devices with the same id, recording the same length at the same start time (different motion)."""
    out = []
    for name, seed in (("a", 1), ("b", 2)):
        logger = Logger(device_id=9)
        result = logger.record(smooth_motion(n, seed), start_time_s=1_700_000_000)
        path = tmp_path / f"{name}.glimg"
        logger.save_image(path)
        out.append((path, logger, result))
    return out


def test_twin_recordings_differ_only_by_their_nonce(tmp_path):
    (_, la, _), (_, lb, _) = _twins(tmp_path)
    ha, hb = la.header, lb.header
    assert ha.recording_number == hb.recording_number == 1
    assert ha.recording_nonce != hb.recording_nonce
    assert ha.replace(recording_nonce=hb.recording_nonce).to_bytes() == hb.to_bytes()


def test_resume_refuses_another_recording_with_the_same_device_id_and_start(tmp_path):
    (pa, _, _), (pb, _, rb) = _twins(tmp_path)
    out = tmp_path / "x.glimg"
    with LoggerLink(f"emu://{pa}?cut_after=20000", timeout_s=0.1, retries=0) as link:
        with pytest.raises(HostError):
            dump_memory(link, out, progress=False)
    with LoggerLink(f"emu://{pb}", timeout_s=0.5) as link:
        with pytest.raises(HostError, match=r"holds recording 1 \(nonce 0x[0-9a-f]{8}\) of device 9, the device now "
                                            r"recording 1 \(nonce"):
            dump_memory(link, out, progress=False, resume=True)
    assert not out.exists()
    with LoggerLink(f"emu://{pb}", timeout_s=0.5) as link:  # without --resume: all of b, exact
        dump = dump_memory(link, out, progress=False)
    assert dump.complete_ and dump.metadata_["header"]["recording_nonce"] == dump.header_.recording_nonce
    rec = decode_file(out)
    assert rec.valid.all()
    np.testing.assert_array_equal(rec.codes, rb.codes)


def _session(logger: Logger, length: int) -> bytes:
    """The device's bytes of READ_HEADER then DUMP of the first ``length`` bytes."""
    fw = logger.firmware
    out = fw.receive(encode_frame(FrameType.READ_HEADER, 1), now_s=0.0)
    payload = build_payload(FrameType.DUMP, address=0, length=length, chunk=1024)
    return out + fw.receive(encode_frame(FrameType.DUMP, 2, payload), now_s=0.0)


def test_capture_spanning_two_recordings_uses_only_the_last(tmp_path):
    (_, la, _), (_, lb, rb) = _twins(tmp_path)
    capture = _session(la, 4 * 8300) + _session(lb, 4 * 4096)  # all of a, then the first 4096 samples of b
    with pytest.warns(UserWarning, match=r"spans 2 device headers: decoded recording 1 \(nonce 0x[0-9a-f]{8}\) of "
                                         r"device 9 .*33 DATA frame\(s\) under 1 other recording"):
        rec = decode_bytes(capture, source="two.cap")
    assert rec.header.recording_nonce == lb.header.recording_nonce
    assert rec.valid[:4096].all() and not rec.valid[4096:].any()  # b's samples exact, the rest reported missing
    np.testing.assert_array_equal(rec.codes[:4096], rb.codes[:4096])
    # DATA frames before any HEADER frame belong to no known recording
    headerless = _session(la, 4 * 100)[262:] + _session(lb, 4 * 100)
    with pytest.warns(UserWarning, match="before any HEADER frame"):
        rec = decode_bytes(headerless)
    assert rec.valid[:100].all() and rec.valid.sum() == 100
    np.testing.assert_array_equal(rec.codes[:100], rb.codes[:100])


def test_dump_of_a_device_cut_by_a_power_loss_reports_it(tmp_path):
    """The dump's metadata says which recording a power loss cut and what survived (PROTOCOL.md 2.4)."""
    logger = Logger(device_id=4)
    motion = smooth_motion(3000, 3)
    res = logger.record(motion, power_cut=PowerCut(at_sample=2000))
    path = tmp_path / "cut.glimg"
    logger.save_image(path)
    out = tmp_path / "d.glimg"
    with LoggerLink(f"emu://{path}", timeout_s=0.5) as link, pytest.warns(UserWarning, match="cut by a power loss"):
        dump = dump_memory(link, out, progress=False)
    loss = dump.metadata_["power_loss"]
    assert dump.complete_ and loss["recording_number"] == 1 and loss["first_sample_number"] == 0
    assert loss["last_committed_sample_number"] == 2000 // 32 * 32 - 1 and loss["torn_slots"] == 0
    rec = decode_file(out)
    np.testing.assert_array_equal(rec.codes, res.codes[: 2000 // 32 * 32])
