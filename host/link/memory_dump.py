"""Dump a logger's memory over a :class:`~gaitlog.host.link.logger_link.LoggerLink`: stream, check, re-read, resume, write.

Steps (``PROTOCOL.md`` sections 3-4 and 6):

1. IDENTIFY (refuses an unknown protocol version), STATUS (refuses a logging device), READ_HEADER.
2. The stored ranges of memory addresses: the sample memory ``[0, 4·n_stored)`` (the whole memory when
   WRAPPED), then the step memory's stored records ``[STEP_ADDRESS_BASE, STEP_ADDRESS_BASE + 20·n_steps)``
   (``header.step_used_bytes``; none without step memory or records; section 2.3). The transfer dumps memory
   addresses; ring order is the decoder's business. Both live in one buffer laid out as the image's memory
   region (sample memory, then step memory), so progress, re-reads, the partial state and ``--resume`` treat
   them alike; a range never crosses from one memory into the other on the wire.
3. Passes of DUMP_CHECKED over every range still missing, in DATA frames of ``chunk_bytes`` at first; each
   frame is used only with a good CRC-16, an address and size that fit the request and the device's CRC-32
   of its bytes (the DATA_CRC frame after it), so every byte stored was verified end to end against the
   memory. The chunk follows the line: from the share of frames that arrive verified the byte error rate is
   estimated and the chunk that carries most data per byte on the wire is chosen (:func:`best_chunk`); a
   stream whose frames mostly arrive damaged is abandoned early and the rest asked again with the smaller
   chunk (the device ends the old stream on the new command).
4. The passes go on while they bring new bytes; ``retries`` passes in a row that bring nothing end the dump
   (a dead line raises at the IDENTIFY that follows such a pass).
5. The image (``gaitlog.protocol.image.build_image``: version 2 with the step memory when the header has one;
   blocks never received marked missing) and its JSON metadata
   sidecar ``OUT.json`` are written atomically; the partial state ``OUT.part`` (itself an image with the
   missing blocks marked) is written atomically as blocks arrive and removed when the dump is complete.
   ``resume=True`` starts from that state after checking that the device still has the same header, so an
   interrupted dump neither loses nor doubles a sample: every byte has one address.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import json
import math
import os
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from gaitlog.host.errors import HostError
from gaitlog.host.files.decode import decode_bytes
from gaitlog.host.link.logger_link import LoggerLink, device_identity
from gaitlog.atomic_write import atomic_write_bytes, atomic_write_text
from gaitlog.protocol.data_blocks import MAX_BLOCKS_DATA, header_binding
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import FRAME_OVERHEAD, MAX_DATA, PAYLOAD_STRUCTS, DeviceState, FrameType
from gaitlog.protocol.header import PAGE_SAMPLES
from gaitlog.protocol.image import build_image, parse_image
from gaitlog.protocol.steps import STEP_ADDRESS_BASE

#: Block size of the image and of the resume bookkeeping (``PROTOCOL.md`` section 6).
BLOCK_SIZE = 1024
#: Smallest DATA chunk the dump asks for.
MIN_CHUNK = 16
#: Wire bytes of a DUMP_CHECKED chunk beyond its data: the DATA frame's framing and address, the DATA_CRC frame.
CHECKED_OVERHEAD_BYTES = 2 * FRAME_OVERHEAD + 4 + PAYLOAD_STRUCTS[FrameType.DATA_CRC].sizeof()
#: A stream is judged after this many chunk positions.
JUDGE_AFTER_FRAMES = 8


def best_chunk(byte_error_rate: float, max_chunk: int = MAX_DATA) -> int:
    """The DATA chunk that carries most data per wire byte when each byte is damaged with probability ``p``:
    maximises ``c / (c + o) · (1 - p)^(c + o)`` (``o`` = :data:`CHECKED_OVERHEAD_BYTES`), whose root is
    ``c = (sqrt(o² + 4o/λ) - o) / 2`` with ``λ = -ln(1 - p)``; a multiple of 4 in ``MIN_CHUNK … max_chunk``.

    >>> best_chunk(0.0), best_chunk(1e-3), best_chunk(1e-2), best_chunk(0.9)
    (4096, 152, 40, 16)
    """
    p = float(byte_error_rate)
    if not p > 1e-9:
        return max_chunk
    lam = -math.log1p(-min(p, 0.999))
    o = CHECKED_OVERHEAD_BYTES
    c = (math.sqrt(o * o + 4 * o / lam) - o) / 2
    return int(max(MIN_CHUNK, min(max_chunk, c // 4 * 4)))


def byte_error_rate(frames_verified: int, frames_seen: int, chunk: int) -> float:
    """Byte error rate that makes ``frames_verified`` of ``frames_seen`` chunk positions of ``chunk`` bytes arrive
    verified (none verified counts as half a frame: an upper estimate).

    >>> round(byte_error_rate(8, 8, 4096), 6), round(byte_error_rate(0, 8, 4096), 5)
    (0.0, 0.00067)
    """
    n = chunk + CHECKED_OVERHEAD_BYTES
    share = max(frames_verified, 0.5) / max(frames_seen, 1)
    return 1.0 - min(share, 1.0) ** (1.0 / n)
#: Version of the JSON metadata beside a dump. 2: ``device`` in the host's words (``sampling_rate_hz`` in Hz,
#: ``firmware_version`` "major.minor"; version 1 copied the INFO frame: ``sample_rate_mhz`` in millihertz).
METADATA_FORMAT_VERSION = 2


def _recording_text(header) -> str:
    """``recording N (nonce 0x…) of device D`` for messages (PROTOCOL.md 2.4)."""
    device, number, nonce = header.recording_id
    if header.header_version == 1:
        return f"an unnumbered recording (header version 1) of device {device}"
    return f"recording {number} (nonce 0x{nonce:08x}) of device {device}"


def state_path_for(out_path: str | os.PathLike[str]) -> Path:
    """Path of the partial-dump state of ``out_path`` (``OUT.part``)."""
    out = Path(out_path)
    return out.with_name(out.name + ".part")


def metadata_path_for(out_path: str | os.PathLike[str]) -> Path:
    """Path of the JSON metadata sidecar of ``out_path`` (``OUT.json``)."""
    out = Path(out_path)
    return out.with_name(out.name + ".json")


def _ranges(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` runs of True in a bool array.

    >>> _ranges(np.array([0, 1, 1, 0, 1], bool))
    [(1, 3), (4, 5)]
    """
    if not mask.any():
        return []
    d = np.diff(np.concatenate(([0], mask.view(np.int8), [0])))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


class MemoryDump:
    """Dump the stored memory of a logger to a memory image with metadata.

    Parameters
    ----------
    chunk_bytes
        DATA frame size of the first pass (None: the largest the device offers: 16,384 bytes of DATA_BLOCKS
        frames with protocol version 2, 4096 bytes of DUMP_CHECKED with version 1).
    retries
        Re-read passes over missing bytes after the first pass.
    state_interval_s
        Minimum time between two writes of the partial state.
    blocks
        None or True: DUMP_BLOCKS on a device of protocol version 2, DUMP_CHECKED on version 1; False:
        DUMP_CHECKED always (the format before version 2, e.g. as a benchmark's baseline).

    Attributes
    ----------
    header_
        The device header (``gaitlog.protocol.header.DeviceHeader``).
    info_
        IDENTIFY answer.
    complete_
        True when every stored byte was received intact.
    missing_ranges_
        ``(address, length)`` of the stored bytes still missing.
    metadata_
        The metadata written beside the image.
    image_path_, metadata_path_, state_path_
        Files written (the state file exists only while the dump is incomplete).
    """

    def __init__(self, *, chunk_bytes: int | None = None, retries: int = 8, state_interval_s: float = 1.0,
                 blocks: bool | None = None) -> None:
        self.chunk_bytes = chunk_bytes
        self.blocks = blocks
        self.retries = retries
        self.state_interval_s = state_interval_s

    # ------------------------------------------------------------------------------------------ helpers
    def _load_state(self, state_path: Path, header_bytes: bytes, memory: bytearray, have: np.ndarray) -> int:
        """Bytes of the image's memory region (sample then step memory) that the partial state holds."""
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the missing blocks of a partial state are expected
                contents = parse_image(state_path.read_bytes(), source=str(state_path))
        except (OSError, ProtocolError) as err:
            raise HostError(f"cannot resume from {state_path}: {err}; delete it to dump from the start") from err
        then, now = contents.header, self.header_
        if then.recording_id != now.recording_id:  # PROTOCOL.md 2.4: another recording, or another device
            raise HostError(
                f"cannot resume from {state_path}: it holds {_recording_text(then)}, the device now "
                f"{_recording_text(now)}; delete it and dump again without --resume")
        if then.to_bytes() != header_bytes:
            raise HostError(
                f"cannot resume from {state_path}: the device's header changed since that dump started "
                f"(samples_written {then.samples_written} then, {now.samples_written} now); "
                "delete it and dump again without --resume")
        ok = np.concatenate([contents.byte_ok(), contents.step_byte_ok()])[: len(memory)]
        mem = np.concatenate([np.asarray(contents.memory, np.uint8),
                              np.asarray(contents.step_memory, np.uint8)])[: len(memory)]
        idx = np.flatnonzero(ok)
        buf = np.frombuffer(memory, dtype=np.uint8)
        buf[idx] = mem[idx]
        have[idx] = True
        return int(ok.sum())

    @staticmethod
    def _missing_blocks(have: np.ndarray, need: np.ndarray) -> list[int]:
        """Blocks of the memory region with a stored byte not received, and blocks holding no stored byte
        (never read: their bytes beyond the stored ranges were not asked for)."""
        n_blocks = -(-have.size // BLOCK_SIZE)
        pad = n_blocks * BLOCK_SIZE - have.size
        lacking = np.concatenate([need & ~have, np.zeros(pad, bool)]).reshape(n_blocks, BLOCK_SIZE).any(axis=1)
        stored = np.concatenate([need, np.zeros(pad, bool)]).reshape(n_blocks, BLOCK_SIZE).any(axis=1)
        return np.flatnonzero(lacking | ~stored).tolist()

    # -------------------------------------------------------------------------------------------- run
    def run(self, link, out_path: str | os.PathLike[str], *, resume: bool = False,
            progress: bool | Callable[[int], None] = True) -> MemoryDump:
        """Dump through ``link`` (a :class:`~gaitlog.host.link.logger_link.LoggerLink`) to the image ``out_path``.

        Raises
        ------
        HostError
            No answer from the device, a refused command, or an interrupted line. The partial state is
            saved first (``OUT.part``) and the message says to run again with ``--resume``.
        """
        out = Path(out_path)
        if not out.parent.is_dir():
            raise HostError(f"output directory {out.parent} does not exist")
        self.image_path_ = out
        self.metadata_path_ = metadata_path_for(out)
        self.state_path_ = state_path_for(out)
        t_start = time.monotonic()
        started_utc = _dt.datetime.now(_dt.timezone.utc)
        # step 1: who is there, is it idle, its header
        self.info_ = link.identify()
        # DUMP_BLOCKS (4.1) when the device has it, else DUMP_CHECKED (4); ``blocks=False`` asks for the latter
        self.blocks_ = int(self.info_["protocol_version"]) >= 2 and self.blocks is not False
        self.max_chunk_ = self.chunk_bytes or (MAX_BLOCKS_DATA if self.blocks_ else MAX_DATA)
        status = link.status()
        if status["state"] == DeviceState.LOGGING:
            raise HostError(f"{link.port}: the device is logging; stop it before dumping its memory")
        header_bytes, self.header_ = link.read_header()
        # step 2: the stored ranges, and what a partial state already holds
        transfer = _Transfer(self.header_, header_bytes, self.state_path_, self.state_interval_s)
        resumed_bytes = transfer.resume(self) if resume and self.state_path_.exists() else None
        # steps 3-4: the first pass and the re-read passes
        with _progress_bar(progress, transfer) as update:
            transfer.update = update
            self._fetch(link, transfer)
        # step 5: image, metadata, state
        self.complete_ = not transfer.missing().any()
        self.missing_ranges_ = [(transfer.device_address(a), b - a) for a, b in transfer.todo_ranges()]
        image = transfer.image_bytes()
        self.recording_ = decode_bytes(image, source=str(out))
        self.metadata_ = self._metadata(link, status, transfer, image, started_utc, resumed_bytes)
        self._write(image, transfer, t_start)
        return self

    def _fetch(self, link, transfer: _Transfer) -> None:
        """Passes of DUMP_CHECKED over everything missing with a chunk fitted to the line (steps 3-4 above),
        until nothing is missing or ``retries`` passes in a row brought nothing; the partial state is saved
        and the device's stream ended on any error or interrupt."""
        chunk = self.max_chunk_
        binding = header_binding(transfer.header_bytes)
        p_hat: float | None = None
        idle_passes = 0

        def fitted(verified: int, seen: int, c: int) -> int:
            rate = byte_error_rate(verified, seen, c)
            return best_chunk(rate if p_hat is None else (p_hat + rate) / 2, self.max_chunk_)

        try:
            while transfer.missing().any():
                transfer.counters["passes"] += 1
                new_before = transfer.n_new
                cursor = 0
                while (todo := transfer.todo_ranges(after=cursor, merge_gap=max(1024, 4 * chunk))):
                    start, stop = todo[0]
                    length = stop - start
                    address = transfer.device_address(start)
                    if transfer.counters["passes"] > 1 or start > 0:
                        transfer.counters["reread_pieces"] += 1
                    c = min(chunk, length)

                    def keep_going(verified: int, seen: int, c: int = c) -> bool:
                        return seen < JUDGE_AFTER_FRAMES or c <= MIN_CHUNK or fitted(verified, seen, c) * 2 >= c

                    if self.blocks_:
                        result = link.dump_blocks(address, length, c, transfer.on_data, binding=binding,
                                                  keep_going=keep_going)
                    else:
                        result = link.dump_checked(address, length, c, transfer.on_data, keep_going=keep_going)
                    cursor = stop if result.ended or not result.frames_seen else min(
                        stop, start + result.frames_seen * c)
                    if result.frames_seen >= 2 or (result.frames_seen and (c == chunk or self.blocks_)):
                        rate = byte_error_rate(result.frames_verified, result.frames_seen, c)
                        p_hat = rate if p_hat is None else (p_hat + rate) / 2
                        chunk = min(best_chunk(p_hat, self.max_chunk_), 4 * chunk)
                    if not result.frames_seen and not result.ended:
                        break  # not a single frame: end the pass (the check below asks whether anybody is there)
                    transfer.chunk_used = chunk
                if transfer.n_new == new_before:
                    idle_passes += 1
                    link.identify()  # a whole pass brought nothing: a dead line raises HostError here
                    if idle_passes > self.retries:
                        break
                else:
                    idle_passes = 0
        except BaseException:
            link.abort(wait=False)  # the device must not stream on into the void
            if transfer.n_new or transfer.resumed:
                transfer.save_state()
            raise

    def _metadata(self, link, status: dict[str, int], transfer: _Transfer, image: bytes,
                  started_utc: _dt.datetime, resumed_bytes: int | None) -> dict[str, Any]:
        """The JSON metadata written beside the image (``duration_s`` is set when the image is written)."""
        header, stats, recording = self.header_, link.stats, self.recording_
        return {
            "format": "gaitlog dump metadata",
            "format_version": METADATA_FORMAT_VERSION,
            "image": self.image_path_.name,
            "sha256": hashlib.sha256(image).hexdigest(),
            "port": link.port,
            "baud": link.baud,
            "device": device_identity(self.info_),
            "status": status,
            "header": {
                "device_id": header.device_id, "firmware_version": header.firmware_version,
                "protocol_version": header.protocol_version, "sampling_rate_hz": header.sampling_rate_hz,
                "start_time_utc": header.start_time.isoformat(), "samples_written": header.samples_written,
                "write_index": header.write_index, "capacity_samples": header.capacity_samples,
                "wrapped": header.wrapped, "overwrite": header.overwrite,
                "calibration_valid": bool(header.calibration.valid),
                "steps_written": header.steps_written, "step_write_index": header.step_write_index,
                "step_capacity": header.step_capacity, "step_algorithm_on": bool(header.step_config.enabled),
                "header_version": header.header_version, "recording_number": header.recording_number,
                "recording_nonce": header.recording_nonce,
            },
            "power_loss": None if not recording.header.power_lost else {
                "recording_number": recording.header.recording_number,
                "first_sample_number": recording.header.run_start_sample,
                "last_committed_sample_number": recording.header.samples_written - 1,
                "lost_after_at_most_samples": PAGE_SAMPLES,
                "torn_slots": int(recording.header.torn_slot_numbers().size),
                "torn_step_records": recording.header.torn_step_records,
            },
            "stored_bytes": transfer.stored_end,
            "step_stored_bytes": transfer.step_stored,
            "started_utc": started_utc.isoformat(),
            "finished_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(),
            "duration_s": None,  # set after the image is written
            "resumed": resumed_bytes is not None,
            "bytes_from_partial_state": resumed_bytes or 0,
            "bytes_received": stats.bytes_received,
            "frames_ok": stats.frames_ok,
            "frames_damaged": stats.frame_errors,
            "data_frames_used": transfer.counters["frames_used"],
            "passes": transfer.counters["passes"],
            "reread_pieces": transfer.counters["reread_pieces"],
            "command_retries": stats.command_retries,
            "crc32_mismatches": stats.crc32_mismatches,
            "streams_abandoned": stats.streams_abandoned,
            "last_chunk_bytes": transfer.chunk_used,
            "complete": self.complete_,
            "missing_ranges": [{"address": a, "length": n} for a, n in self.missing_ranges_],
            "missing_samples": [
                {"first_sample_number": g.first_sample_number, "last_sample_number": g.last_sample_number,
                 "reason": g.reason} for g in recording.gaps
            ],
            "n_samples": recording.n_samples,
            "n_valid": recording.n_valid,
            "n_step_records_stored": int(header.n_steps_stored),
            "n_step_records": recording.n_step_records,
            "step_record_losses": [
                {"first_record_number": g.first_record_number, "last_record_number": g.last_record_number,
                 "reason": g.reason} for g in recording.step_losses
            ],
        }

    def _write(self, image: bytes, transfer: _Transfer, t_start: float) -> None:
        """Image, then metadata (the image is removed if the metadata cannot be written), then the partial
        state: removed when complete, else saved for ``--resume``."""
        atomic_write_bytes(self.image_path_, image)
        self.metadata_["duration_s"] = round(time.monotonic() - t_start, 3)
        try:
            atomic_write_text(self.metadata_path_, json.dumps(self.metadata_, indent=2, default=_json_default)
                              + "\n")
        except BaseException:
            self.image_path_.unlink(missing_ok=True)
            raise
        if self.complete_:
            self.state_path_.unlink(missing_ok=True)
        else:
            transfer.save_state()


def dump_memory(link: LoggerLink, out_path: str | os.PathLike[str], *,
                progress: bool | Callable[[int], None] = True, resume: bool = False, retries: int = 8,
                chunk_bytes: int | None = None, blocks: bool | None = None) -> MemoryDump:
    """Dump the stored memory of the logger on ``link`` to the image ``out_path`` (+ ``.json`` metadata):
    :meth:`MemoryDump.run` with ``retries`` and ``chunk_bytes``. Returns the finished :class:`MemoryDump`."""
    return MemoryDump(retries=retries, chunk_bytes=chunk_bytes, blocks=blocks).run(link, out_path, resume=resume,
                                                                                 progress=progress)


class _Transfer:
    """The memory region being filled (sample memory ``[0, mem_size)``, then step memory), what is needed and
    what has arrived, and the bookkeeping of one dump."""

    def __init__(self, header, header_bytes: bytes, state_path: Path, state_interval_s: float) -> None:
        self.header_bytes = header_bytes
        self.state_path = state_path
        self.state_interval_s = state_interval_s
        self.mem_size = int(header.memory_bytes)
        region_size = self.mem_size + int(header.step_memory_bytes)
        self.stored_end = int(header.used_bytes)
        self.step_stored = int(header.step_used_bytes)
        self.memory = bytearray(b"\xff" * region_size)
        self.have = np.zeros(region_size, dtype=bool)
        self.need = np.zeros(region_size, dtype=bool)
        self.need[: self.stored_end] = True
        self.need[self.mem_size: self.mem_size + self.step_stored] = True
        self.total_needed = self.stored_end + self.step_stored
        self.resumed = False
        self.n_new = 0
        self.counters = {"frames_used": 0, "passes": 0, "reread_pieces": 0}
        self.chunk_used = 0
        self.update: Callable[[int], None] | None = None
        self._last_state = time.monotonic()

    def resume(self, dump: MemoryDump) -> int:
        """Fill in what the partial state holds; return how many bytes that was."""
        self.resumed = True
        return dump._load_state(self.state_path, self.header_bytes, self.memory, self.have)

    def device_address(self, offset: int) -> int:
        """Memory-region offset -> device address (PROTOCOL.md 3.1)."""
        return offset if offset < self.mem_size else STEP_ADDRESS_BASE + offset - self.mem_size

    def region_offset(self, address: int) -> int:
        """Device address -> memory-region offset."""
        return address if address < STEP_ADDRESS_BASE else self.mem_size + address - STEP_ADDRESS_BASE

    def missing(self) -> np.ndarray:
        """Bool mask of the needed bytes not yet received."""
        return self.need & ~self.have

    def todo_ranges(self, *, after: int = 0, merge_gap: int = 0) -> list[tuple[int, int]]:
        """Region ranges still missing from offset ``after`` on, split where the sample memory ends (never one
        range on the wire); ranges less than ``merge_gap`` bytes apart are asked as one (a round trip costs
        more than a few bytes the host already has)."""
        missing = self.missing()
        missing[:after] = False
        out: list[tuple[int, int]] = []
        for a, b in _ranges(missing):
            if out and a - out[-1][1] < merge_gap and (out[-1][1] <= self.mem_size) == (b <= self.mem_size):
                out[-1] = (out[-1][0], b)
            else:
                out.append((a, b))
        split = []
        for a, b in out:
            split += [(a, self.mem_size), (self.mem_size, b)] if a < self.mem_size < b else [(a, b)]
        return split

    def image_bytes(self) -> bytes:
        """The image of what was received (``image_version`` 2 when the header has a step memory)."""
        return build_image(self.header_bytes, bytes(self.memory),
                           missing_blocks=MemoryDump._missing_blocks(self.have, self.need), block_size=BLOCK_SIZE)

    def save_state(self) -> None:
        atomic_write_bytes(self.state_path, self.image_bytes())

    def on_data(self, address: int, data: bytes) -> bool:
        """Store an intact DATA frame's bytes; save the partial state now and then. Never asks to stop."""
        start = self.region_offset(address)
        end = start + len(data)
        fresh = int(np.count_nonzero(~self.have[start:end]))
        np.frombuffer(self.memory, dtype=np.uint8)[start:end] = np.frombuffer(data, dtype=np.uint8)
        self.have[start:end] = True
        self.counters["frames_used"] += 1
        if fresh:
            self.n_new += fresh
            if self.update is not None:
                self.update(fresh)
            if time.monotonic() - self._last_state >= self.state_interval_s:
                self.save_state()
                self._last_state = time.monotonic()
        return False


@contextlib.contextmanager
def _progress_bar(progress: bool | Callable[[int], None], transfer: _Transfer):
    """Yield the progress callback: ``progress`` itself when callable, a tqdm bar on a terminal's stderr when
    True (closed on exit), None when False."""
    if callable(progress):
        yield progress
        return
    if not progress:
        yield None
        return
    already = int(np.count_nonzero(transfer.have & transfer.need))
    bar = tqdm(total=transfer.total_needed, initial=already, unit="B", unit_scale=True, file=sys.stderr,
               desc="dump", disable=not sys.stderr.isatty(), leave=False)
    try:
        yield bar.update
    finally:
        bar.close()


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
