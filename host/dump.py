"""Dump a logger's memory over a :class:`~host.link.LoggerLink`: stream, check, re-read, resume, write.

Steps (``PROTOCOL.md`` sections 3-4 and 6):

1. IDENTIFY (refuses an unknown protocol version), STATUS (refuses a logging device), READ_HEADER.
2. The stored range of memory addresses: ``[0, 4·n_stored)``, the whole memory when WRAPPED. The transfer
   dumps memory addresses; ring order is the decoder's business.
3. One DUMP of every range still missing, in DATA frames of ``chunk_bytes``; each frame is used only with a
   good CRC-16 and an address and size that fit the request.
4. Up to ``retries`` re-read passes over what is still missing, with ever smaller pieces (READ for a single
   piece, DUMP with a smaller chunk for more), so a noisy line still gets every byte through.
5. The image (``protocol.image.build_image``, blocks never received marked missing) and its JSON metadata
   sidecar ``OUT.json`` are written atomically; the partial state ``OUT.part`` (itself an image with the
   missing blocks marked) is written atomically as blocks arrive and removed when the dump is complete.
   ``resume=True`` starts from that state after checking that the device still has the same header, so an
   interrupted dump neither loses nor doubles a sample: every byte has one address.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from host.errors import HostError
from protocol.atomic_write import atomic_write_bytes, atomic_write_text

#: Block size of the image and of the resume bookkeeping (``PROTOCOL.md`` section 6).
BLOCK_SIZE = 1024
#: Smallest re-read piece.
MIN_PIECE = 64


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
        DATA frame size of the first pass (1 ... 4096; 4096 keeps the framing at 0.3 %).
    retries
        Re-read passes over missing bytes after the first pass.
    state_interval_s
        Minimum time between two writes of the partial state.

    Attributes
    ----------
    header_
        The device header (``protocol.header.DeviceHeader``).
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

    def __init__(self, *, chunk_bytes: int = 4096, retries: int = 8, state_interval_s: float = 1.0) -> None:
        self.chunk_bytes = chunk_bytes
        self.retries = retries
        self.state_interval_s = state_interval_s

    # ------------------------------------------------------------------------------------------ helpers
    def _load_state(self, state_path: Path, header_bytes: bytes, memory: bytearray, have: np.ndarray) -> int:
        from protocol.errors import ProtocolError
        from protocol.image import parse_image

        import warnings

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the missing blocks of a partial state are expected
                contents = parse_image(state_path.read_bytes(), source=str(state_path))
        except (OSError, ProtocolError) as err:
            raise HostError(f"cannot resume from {state_path}: {err}; delete it to dump from the start") from err
        if contents.header.to_bytes() != header_bytes:
            raise HostError(
                f"cannot resume from {state_path}: the device's header changed since that dump started "
                f"(samples_written {contents.header.samples_written} then, {self.header_.samples_written} now); "
                "delete it and dump again without --resume")
        ok = np.repeat(np.asarray(contents.block_ok, bool), int(contents.block_size))[: len(memory)]
        mem = np.asarray(contents.memory, np.uint8)[: len(memory)]
        idx = np.flatnonzero(ok)
        buf = np.frombuffer(memory, dtype=np.uint8)
        buf[idx] = mem[idx]
        have[idx] = True
        return int(ok.sum())

    def _missing_blocks(self, have: np.ndarray, stored_end: int) -> list[int]:
        """Blocks with any stored byte not received, and blocks entirely beyond the stored range."""
        n_blocks = -(-have.size // BLOCK_SIZE)
        padded = np.ones(n_blocks * BLOCK_SIZE, bool)
        padded[: have.size] = have
        padded[stored_end: have.size] = True  # bytes beyond the stored range do not count ...
        blocks_ok = padded.reshape(n_blocks, BLOCK_SIZE).all(axis=1)
        first_unread = -(-stored_end // BLOCK_SIZE)
        blocks_ok[first_unread:] = False  # ... but blocks wholly beyond it were never read
        return np.flatnonzero(~blocks_ok).tolist()

    def _image_bytes(self, header_bytes: bytes, memory: bytearray, have: np.ndarray, stored_end: int) -> bytes:
        from protocol.image import build_image

        missing = self._missing_blocks(have, stored_end)
        # this dump reads the sample memory only; a step memory (PROTOCOL.md 2.3) is in the image as blocks
        # never received
        steps = int(self.header_.step_memory_bytes)
        if steps:
            end = -(-(len(memory) + steps) // BLOCK_SIZE)
            missing = sorted(set(missing) | set(range(len(memory) // BLOCK_SIZE, end)))
        return build_image(header_bytes, bytes(memory) + b"\xff" * steps, missing_blocks=missing,
                           block_size=BLOCK_SIZE)

    # -------------------------------------------------------------------------------------------- run
    def run(self, link, out_path: str | os.PathLike[str], *, resume: bool = False,
            progress: bool | Callable[[int], None] = True) -> "MemoryDump":
        """Dump through ``link`` (a :class:`~host.link.LoggerLink`) to the image ``out_path``.

        Raises
        ------
        HostError
            No answer from the device, a refused command, or an interrupted line. The partial state is
            saved first (``OUT.part``) and the message says to run again with ``--resume``.
        """
        out = Path(out_path)
        if not out.parent.is_dir():
            raise HostError(f"output directory {out.parent} does not exist")
        state_path = state_path_for(out)
        self.image_path_ = out
        self.metadata_path_ = metadata_path_for(out)
        self.state_path_ = state_path
        t_start = time.monotonic()
        started_utc = _dt.datetime.now(_dt.timezone.utc)

        self.info_ = link.identify()
        status = link.status()
        if status["state"] == 1:
            raise HostError(f"{link.port}: the device is logging; stop it before dumping its memory")
        header_bytes, header = link.read_header()
        self.header_ = header
        mem_size = int(header.capacity_samples) * 4
        stored_end = mem_size if header.wrapped else 4 * int(header.n_stored)
        memory = bytearray(b"\xff" * mem_size)
        have = np.zeros(mem_size, dtype=bool)
        resumed_bytes = 0
        resumed = False
        if resume and state_path.exists():
            resumed_bytes = self._load_state(state_path, header_bytes, memory, have)
            resumed = True
        have_view = np.frombuffer(memory, dtype=np.uint8)
        need = np.zeros(mem_size, dtype=bool)
        need[:stored_end] = True

        bar = None
        update: Callable[[int], None] | None = None
        if callable(progress):
            update = progress
        elif progress:
            from tqdm import tqdm

            already = int(np.count_nonzero(have[:stored_end]))
            bar = tqdm(total=stored_end, initial=already, unit="B", unit_scale=True, file=sys.stderr,
                       desc="dump", disable=not sys.stderr.isatty(), leave=False)
            update = bar.update

        last_state = time.monotonic()
        n_new = 0
        counters = {"frames_used": 0, "passes": 0, "reread_pieces": 0}

        def save_state() -> None:
            atomic_write_bytes(state_path, self._image_bytes(header_bytes, memory, have, stored_end))

        def on_data(address: int, data: bytes) -> bool:
            nonlocal last_state, n_new
            end = address + len(data)
            fresh = int(np.count_nonzero(~have[address:end]))
            have_view[address:end] = np.frombuffer(data, dtype=np.uint8)
            have[address:end] = True
            counters["frames_used"] += 1
            if fresh:
                n_new += fresh
                if update is not None:
                    update(fresh)
                if time.monotonic() - last_state >= self.state_interval_s:
                    save_state()
                    last_state = time.monotonic()
            return False

        try:
            for attempt in range(self.retries + 1):
                todo = _ranges(need & ~have)
                if not todo:
                    break
                counters["passes"] += 1
                new_before = n_new
                piece = max(MIN_PIECE, self.chunk_bytes >> (2 * attempt))
                for start, stop in todo:
                    length = stop - start
                    if attempt and length <= piece:
                        counters["reread_pieces"] += 1
                        try:
                            on_data(start, link.read(start, length))
                        except HostError as err:
                            if "refused" in str(err):
                                raise
                            # no intact answer within the link's retries: is anybody there at all?
                            link.identify()
                        continue
                    if attempt:
                        counters["reread_pieces"] += -(-length // piece)
                    link.dump_stream(start, length, piece, on_data)
                if not (need & ~have).any():
                    break
                if n_new == new_before:
                    # a whole pass brought nothing: a dead line raises HostError here
                    link.identify()
        except BaseException:
            if n_new or resumed:
                save_state()
            if bar is not None:
                bar.close()
            raise
        if bar is not None:
            bar.close()

        missing = need & ~have
        self.complete_ = not missing.any()
        self.missing_ranges_ = [(a, b - a) for a, b in _ranges(missing)]
        image = self._image_bytes(header_bytes, memory, have, stored_end)
        finished_utc = _dt.datetime.now(_dt.timezone.utc)
        stats = link.stats
        from host.decode import decode_bytes

        recording = decode_bytes(image, source=str(out))
        self.metadata_ = {
            "format": "gaitlog dump metadata",
            "format_version": 1,
            "image": out.name,
            "sha256": hashlib.sha256(image).hexdigest(),
            "port": link.port,
            "baud": link.baud,
            "device": self.info_,
            "status": status,
            "header": {
                "device_id": header.device_id, "firmware_version": header.firmware_version,
                "protocol_version": header.protocol_version, "sample_rate_hz": header.sample_rate_hz,
                "start_time_utc": header.start_time.isoformat(), "samples_written": header.samples_written,
                "write_index": header.write_index, "capacity_samples": header.capacity_samples,
                "wrapped": header.wrapped, "overwrite": header.overwrite,
                "calibration_valid": bool(header.calibration.valid),
            },
            "stored_bytes": stored_end,
            "started_utc": started_utc.isoformat(),
            "finished_utc": finished_utc.isoformat(),
            "duration_s": None,  # set after the image is written
            "resumed": resumed,
            "bytes_from_partial_state": resumed_bytes if resumed else 0,
            "bytes_received": stats.bytes_received,
            "frames_ok": stats.frames_ok,
            "frames_damaged": stats.frame_errors,
            "data_frames_used": counters["frames_used"],
            "passes": counters["passes"],
            "reread_pieces": counters["reread_pieces"],
            "command_retries": stats.command_retries,
            "complete": self.complete_,
            "missing_ranges": [{"address": a, "length": n} for a, n in self.missing_ranges_],
            "missing_samples": [
                {"first_sample_number": g.first_sample_number, "last_sample_number": g.last_sample_number,
                 "reason": g.reason} for g in recording.gaps
            ],
            "n_samples": recording.n_samples,
            "n_valid": recording.n_valid,
        }
        atomic_write_bytes(out, image)
        self.metadata_["duration_s"] = round(time.monotonic() - t_start, 3)
        try:
            atomic_write_text(self.metadata_path_, json.dumps(self.metadata_, indent=2, default=_json_default)
                              + "\n")
        except BaseException:
            out.unlink(missing_ok=True)
            raise
        if self.complete_:
            state_path.unlink(missing_ok=True)
        else:
            save_state()
        self.recording_ = recording
        return self


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
