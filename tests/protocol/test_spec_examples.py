"""PROTOCOL.md and protocol/*.py agree: every worked example is built and parsed, every table is checked.

The examples are fenced blocks tagged ``example <name>`` in section 8 of the spec; their bytes are also
checked for internal consistency (offsets, lengths, CRCs) with a bitwise CRC written here, independent of the
code under test.
"""

from __future__ import annotations

import enum
import json
import re
import warnings
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gaitlog.host.files.decode import decode_bytes
from gaitlog.protocol.channel_map import Channel, ChannelMap
from gaitlog.protocol.commit_journal import ENTRY_BYTES, JOURNAL_BYTES, JOURNAL_ENTRIES, JOURNAL_OFFSET
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import (
    FRAME_HEAD_STRUCT,
    MAX_DATA,
    MAX_PAYLOAD,
    PAYLOAD_STRUCTS,
    ErrorCode,
    FrameType,
    build_payload,
    encode_frame,
    parse_payload,
    parse_stream,
)
from gaitlog.protocol.header import (
    CALIBRATION_OFFSETS,
    HEADER_OFFSETS,
    CalibrationSlot,
    DeviceHeader,
    HeaderFlag,
)
from gaitlog.protocol.image import (
    IMAGE_OFFSETS,
    IMAGE_PREFIX_STRUCT,
    SHIFT_SEARCH_BYTES,
    build_image,
    parse_image,
)
from gaitlog.protocol.packing import pack_words, unpack_words, words_to_bytes
from gaitlog.protocol.raw_dump import raw_dump_bytes
from gaitlog.protocol.steps import (
    STEP_CONFIG_OFFSETS,
    STEP_CONFIG_STRUCT,
    STEP_RECORD_BODY_STRUCT,
    STEP_RECORD_DTYPE,
    STEP_RECORD_OFFSETS,
    STEP_RECORD_STRUCT,
    StepConfig,
    StepFlag,
    empty_step_records,
    pack_step_records,
    parse_step_record,
    unpack_step_records,
)
from gaitlog.protocol.xmodem import PAD, build_block, parse_block

SPEC_PATH = Path(__file__).resolve().parents[2] / "protocol" / "PROTOCOL.md"
SPEC = SPEC_PATH.read_text(encoding="utf-8")


def _crc16(data: bytes) -> int:
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


# ------------------------------------------------------------------------------------------ example parsing
def _crc16_umts(data: bytes) -> int:
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def test_crc16_umts_check_value() -> None:
    assert _crc16_umts(b"123456789") == 0xFEE8  # the catalogue's check value: the bitwise CRC here is right


def _parse_hex(text: str, name: str) -> bytes:
    out = bytearray()
    for line in text.strip().splitlines():
        line = line.strip()
        m = re.match(r"^([0-9a-f]{4}):\s*(.*)$", line)
        if m:
            assert int(m.group(1), 16) == len(out), f"{name}: line offset {m.group(1)} but {len(out)} bytes so far"
            line = m.group(2)
        for tok in line.split():
            if "*" in tok:
                val, count = tok.split("*")
                out += bytes([int(val, 16)]) * int(count)
            else:
                out.append(int(tok, 16))
    return bytes(out)


def _load_examples() -> dict[str, dict[str, Any]]:
    examples = {}
    for m in re.finditer(r"```example (\S+)\n(.*?)```", SPEC, re.S):
        name, body = m.group(1), m.group(2)
        head, _, hex_text = body.partition("hex:")
        ex: dict[str, Any] = {}
        for line in head.strip().splitlines():
            key, _, value = line.partition(":")
            ex[key.strip()] = value.strip()
        ex["fields"] = json.loads(ex.get("fields", "{}"))
        ex["bytes"] = _parse_hex(hex_text, name)
        assert name not in examples, f"duplicate example {name}"
        examples[name] = ex
    return examples


EXAMPLES = _load_examples()


def _object(name: str) -> Any:
    """The object an example stands for (for "example:<name>" references)."""
    ex = EXAMPLES[name]
    if ex["kind"] == "calibration":
        return _calibration(ex["fields"])
    if ex["kind"] == "header":
        return _header(ex)
    if ex["kind"] == "step-config":
        return StepConfig(**ex["fields"])
    if ex["kind"] == "channel-map":
        return _channel_map(ex["fields"])
    raise AssertionError(f"example {name} of kind {ex['kind']} cannot be referenced")


def _resolve(value: Any) -> Any:
    if isinstance(value, str) and value.startswith("example:"):
        return _object(value.removeprefix("example:"))
    return value


def _calibration(fields: dict) -> CalibrationSlot:
    return CalibrationSlot(np.array(fields["offset_counts"]), np.array(fields["matrix_g_per_count"]), True)


def _channel_map(fields: dict) -> ChannelMap:
    return ChannelMap(tuple(Channel(*c) for c in fields["channels"]))


def _header(ex: dict) -> DeviceHeader:
    cal = _resolve(ex["calibration"]) if "calibration" in ex else None
    step_config = _resolve(ex["step_config"]) if "step_config" in ex else None
    fields = dict(ex["fields"])
    if "commit_journal" in fields:
        fields["commit_journal"] = bytes.fromhex(fields["commit_journal"])
    return DeviceHeader(**fields, calibration=cal, step_config=step_config)


def _records(fields: list[dict]) -> np.ndarray:
    rec = empty_step_records(len(fields))
    for i, f in enumerate(fields):
        for key, value in f.items():
            rec[key][i] = value
    return rec


def _same(expected: Any, actual: Any) -> bool:
    if isinstance(actual, enum.Enum):
        return expected == actual.name if isinstance(expected, str) else expected == int(actual)
    if isinstance(actual, (DeviceHeader, CalibrationSlot, StepConfig, ChannelMap)):
        return _resolve(expected).to_bytes() == actual.to_bytes()
    if isinstance(actual, bytes):
        return bytes.fromhex(expected) == actual
    return expected == actual


def test_examples_exist_for_everything() -> None:
    kinds = {ex["kind"] for ex in EXAMPLES.values()}
    assert kinds == {"calibration", "header", "sample", "frame", "xmodem-block", "image", "step-config", "step-record",
                     "channel-map", "channel-frame", "raw-dump", "capture"}
    frame_types = {ex["type"] for ex in EXAMPLES.values() if ex["kind"] == "frame"}
    assert frame_types == {t.name for t in FrameType}, "every frame type needs a worked example"


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_worked_example(name: str) -> None:
    ex = EXAMPLES[name]
    data, fields, kind = ex["bytes"], ex["fields"], ex["kind"]
    if kind == "calibration":
        cal = _calibration(fields)
        assert cal.to_bytes() == data
        back = CalibrationSlot.from_bytes(data)
        assert back.valid and data[0] == 1
        np.testing.assert_array_equal(back.offset_counts, fields["offset_counts"])
        np.testing.assert_array_equal(back.matrix_g_per_count, fields["matrix_g_per_count"])
    elif kind == "header":
        assert len(data) == 256 and data[:4] == b"GLOG"
        crc_end = 254 if data[4] == 1 else 160  # version 2: the journal (160-253) is outside the CRC (2.4)
        assert int.from_bytes(data[254:], "big") == _crc16(data[:crc_end])
        assert _header(ex).to_bytes() == data
        back = DeviceHeader.from_bytes(data)
        for key, value in fields.items():
            assert getattr(back, key) == (bytes.fromhex(value) if key == "commit_journal" else value), key
        if "calibration" in ex:
            assert back.calibration.to_bytes() == _resolve(ex["calibration"]).to_bytes()
        if "step_config" in ex:
            assert back.step_config == _resolve(ex["step_config"])
            assert data[128:160] == _resolve(ex["step_config"]).to_bytes()
        elif data[4] == 1:  # a header without step memory: the formerly reserved bytes are 0
            assert data[44:64] == bytes(20) and data[128:254] == bytes(126)
        if "recovered" in ex:  # section 2.4: what the device and a decoder make of it after a power loss
            rec = back.recovered()
            for key, value in json.loads(ex["recovered"]).items():
                assert getattr(rec, key) == value, key
    elif kind == "channel-map":  # section 2.6, checked against the table by hand-indexed bytes
        assert len(data) == 64 and data[0] == 2 and data[1] == len(fields["channels"]) and data[2:4] == bytes(2)
        for i, (an, quantity, name, fs) in enumerate(fields["channels"]):
            e = data[4 + 7 * i : 11 + 7 * i]
            assert e[0] == an | quantity << 4 and e[1:5] == name.encode().ljust(4, b"\0")
            assert int.from_bytes(e[5:7], "little") == round(fs * 1000)
        assert data[4 + 7 * len(fields["channels"]) :] == bytes(60 - 7 * len(fields["channels"]))
        assert _channel_map(fields).to_bytes() == data
        assert ChannelMap.from_bytes(data).channels == _channel_map(fields).channels
    elif kind == "channel-frame":
        cmap = _resolve(fields["channel_map"])
        codes = np.array(fields["codes"])
        words = cmap.words(codes)
        assert words_to_bytes(pack_words(words, np.zeros(len(words), dtype=np.uint8))) == data
        c2, f2 = unpack_words(data)
        assert (f2 == 0).all() and cmap.frames(c2).tolist() == fields["codes"]
        np.testing.assert_array_equal(cmap.values(cmap.frames(c2), adc_bits=10), fields["values"])
    elif kind == "step-config":
        eighths = round(8 * fields.get("m4_exponent", 0)) if fields["step_format"] >= 4 else 0
        assert len(data) == 32 and data[20] == eighths and data[21:] == bytes(11)
        assert StepConfig(**fields).to_bytes() == data
        back = StepConfig.from_bytes(data)
        for key, value in fields.items():
            assert getattr(back, key) == value, key  # the example's values are exact in their Q formats
    elif kind == "step-record":
        assert len(data) == 20 and int.from_bytes(data[18:], "big") == _crc16(data[:18])
        assert pack_step_records(_records([fields])) == data
        records, crc_ok = unpack_step_records(data)
        assert crc_ok.tolist() == [True]
        assert {k: int(records[k][0]) for k in fields} == fields
        assert parse_step_record(data) == fields  # the construct declaration agrees
    elif kind == "sample":
        codes, flags = np.array(fields["codes"]), np.array(fields["flags"])
        assert words_to_bytes(pack_words(codes, flags)) == data
        c2, f2 = unpack_words(data)
        assert c2.tolist() == fields["codes"] and f2.tolist() == fields["flags"]
    elif kind == "frame":
        ftype, seq = FrameType[ex["type"]], int(ex["seq"])
        # internal consistency of the example, independent of the code
        assert data[:2] == b"\xa5\x5a" and data[2] == ftype and data[3] == seq
        assert int.from_bytes(data[4:6], "little") == len(data) - 8
        assert int.from_bytes(data[-2:], "big") == _crc16(data[2:-2])
        build_fields = {k: _resolve(v) for k, v in fields.items()}
        for key in ("data", "blocks"):
            if key in build_fields:
                build_fields[key] = bytes.fromhex(build_fields[key])
        if ftype == FrameType.DATA_BLOCKS:  # section 4.1: each block followed by its CRC-16/UMTS, by hand
            binding, payload = bytes.fromhex(ex["binding"]), bytes.fromhex(ex["data"])
            expected = bytearray()
            for k in range(0, len(payload), 256):
                block = payload[k: k + 256]
                check = _crc16_umts(binding + (fields["address"] + k).to_bytes(4, "little") + block)
                expected += block + check.to_bytes(2, "big")
            assert bytes(expected) == build_fields["blocks"]
        assert encode_frame(ftype, seq, build_payload(ftype, **build_fields)) == data
        frames, errors = parse_stream(data)
        assert errors == [] and len(frames) == 1
        parsed = parse_payload(frames[0])
        assert set(parsed) == set(fields)
        for key, value in fields.items():
            assert _same(value, parsed[key]), key
    elif kind == "xmodem-block":
        payload = bytes.fromhex(fields["data"])
        assert build_block(fields["blk"], payload) == data
        assert data[0] == 2 and data[1] + data[2] == 255 and len(data) == 1029
        assert int.from_bytes(data[-2:], "big") == _crc16(data[3:-2])
        assert parse_block(data) == (fields["blk"], payload + bytes([PAD]) * (1024 - len(payload)))
    elif kind == "image":
        header = DeviceHeader(**{k: _resolve(v) for k, v in fields["header"].items()})
        bs = fields["block_size"]
        samples = words_to_bytes(pack_words(np.array(fields["samples"]["codes"]), np.array(fields["samples"]["flags"])))
        memory = samples + b"\xff" * (header.memory_bytes - len(samples))
        records = pack_step_records(_records(fields.get("step_records", [])))
        steps = records + b"\xff" * (header.step_memory_bytes - len(records))
        version = data[4]
        if header.step_capacity:
            assert version in (2, 3)
            assert build_image(header, memory, fields["missing_blocks"], bs, step_memory=steps,
                               image_version=version) == data
            assert build_image(header, memory + steps, fields["missing_blocks"], bs, image_version=version) == data
        else:
            assert version in (1, 3) and steps == b""
            assert build_image(header, memory, fields["missing_blocks"], bs, image_version=version) == data
        region = memory + steps
        n = -(-len(region) // bs)
        assert int.from_bytes(data[8:12], "little") == len(region) and int.from_bytes(data[12:16], "little") == n
        stored = bytearray(region)  # the memory as stored: missing blocks erased
        for b in fields["missing_blocks"]:
            stored[b * bs : (b + 1) * bs] = b"\xff" * len(stored[b * bs : (b + 1) * bs])
        if version == 3:  # preamble, framed blocks, preamble again (section 6), checked with zlib directly
            pre = data[:276]
            assert pre[16:272] == header.to_bytes() and data[-276:] == pre
            assert int.from_bytes(pre[272:276], "little") == zlib.crc32(pre[:272])
            pos = 276
            for i in range(n):
                size = min(bs, len(region) - i * bs)
                fr = data[pos : pos + 16 + size]
                assert fr[:4] == b"GLBK" and int.from_bytes(fr[4:8], "little") == i and fr[9:12] == bytes(3)
                assert fr[8] == (1 if i in fields["missing_blocks"] else 0)
                assert fr[12 : 12 + size] == bytes(stored[i * bs : i * bs + size])
                assert int.from_bytes(fr[12 + size :], "little") == zlib.crc32(pre[272:276] + fr[4 : 12 + size])
                pos += 16 + size
            assert pos + 276 == len(data)
        else:
            table_end = 16 + 5 * n
            assert int.from_bytes(data[table_end : table_end + 4], "little") == zlib.crc32(data[:table_end])
            assert data[table_end + 4 + 256 :] == bytes(stored)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # the missing block holds no stored sample or record: no warning
            contents = parse_image(data)
        assert np.flatnonzero(~contents.block_ok).tolist() == fields["missing_blocks"]
        ok = contents.byte_ok()
        assert bytes(contents.memory[ok]) == bytes(np.frombuffer(memory, np.uint8)[ok])
        assert contents.header.to_bytes() == header.to_bytes()
        step_ok = contents.step_byte_ok()
        assert step_ok.size == len(steps)
        assert bytes(contents.step_memory[step_ok]) == bytes(np.frombuffer(steps, np.uint8)[step_ok])
        got, usable = contents.step_records()
        assert usable.all() and pack_step_records(got) == records
    elif kind == "raw-dump":
        _check_raw_dump(data, fields)
    elif kind == "capture":
        _check_capture(data, fields)
    else:  # pragma: no cover
        raise AssertionError(f"unknown example kind {kind}")


def _raw_dump_parts(fields: dict) -> tuple[DeviceHeader, bytes, np.ndarray, np.ndarray]:
    codes, flags = np.array(fields["samples"]["codes"]), np.array(fields["samples"]["flags"])
    return DeviceHeader(**fields["header"]), words_to_bytes(pack_words(codes, flags)), codes, flags


def _decoded(data: bytes, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = decode_bytes(data, **kw)
    return rec, " ".join(str(w.message) for w in caught)


def _check_raw_dump(data: bytes, fields: dict) -> None:
    """Section 5.1: the trailer checked with zlib here; the whole file verifies, the file cut before its
    trailer is reported missing unless accepted unverified."""
    header, samples, codes, flags = _raw_dump_parts(fields)
    assert raw_dump_bytes(header.to_bytes(), samples) == data
    body = 256 + len(samples)
    assert data[:body] == header.to_bytes() + samples and len(data) % 1024 == 0
    trailer, n = data[body:], -(-body // 256)
    assert trailer[:4] == b"GLCK" and trailer[4] == 1 and int.from_bytes(trailer[6:8], "little") == 256
    assert int.from_bytes(trailer[8:12], "little") == body and int.from_bytes(trailer[12:16], "little") == n
    for k in range(n):
        chunk = k.to_bytes(4, "little") + data[256 * k: min(256 * (k + 1), body)]
        assert int.from_bytes(trailer[16 + 4 * k: 20 + 4 * k], "little") == zlib.crc32(chunk)
    end = 16 + 4 * n + 256
    assert trailer[16 + 4 * n: end] == header.to_bytes()
    assert int.from_bytes(trailer[end: end + 4], "little") == zlib.crc32(trailer[:end])
    size = end + 4
    assert trailer[size: size + 64] == b"\x1a" * 64 and trailer[size + 64: 2 * size + 64] == trailer[:size]
    assert set(trailer[2 * size + 64:]) == {0x1A}
    rec, _ = _decoded(data)
    assert rec.valid.all() and rec.codes.tolist() == codes.tolist() and rec.flags.tolist() == flags.tolist()
    cut = data[: fields["cut"]]
    rec, said = _decoded(cut)
    assert not rec.valid.any() and "without its check trailer" in rec.gaps[0].reason and "verified: NO" in said
    rec, said = _decoded(cut, accept_unverified=True)
    assert rec.valid.all() and rec.codes.tolist() == codes.tolist() and "UNVERIFIED" in said


def _check_capture(data: bytes, fields: dict) -> None:
    if fields.get("blocks"):
        _check_capture_blocks(data, fields)
        return
    _check_capture_frames(data, fields)


def _check_capture_blocks(data: bytes, fields: dict) -> None:
    """Section 4.1: a DUMP_BLOCKS session carries the header twice; the first copy damaged, the second places
    the samples, and the DATA_BLOCKS frame's block verifies under its binding."""
    header, samples, codes, _ = _raw_dump_parts(EXAMPLES[fields["example"]]["fields"])
    binding = header.to_bytes()[254:256]
    block = samples + _crc16_umts(binding + bytes(4) + samples).to_bytes(2, "big")
    clean = bytearray(encode_frame(FrameType.HEADER, 1, header.to_bytes())
                      + encode_frame(FrameType.DATA_BLOCKS, 0, bytes(4) + block)
                      + encode_frame(FrameType.HEADER, 2, header.to_bytes())
                      + encode_frame(FrameType.DUMP_END, 2, build_payload(FrameType.DUMP_END, address=0,
                                                                         length=len(samples), frames=1)))
    damaged = bytearray(clean)
    damaged[fields["damaged_byte"]] ^= fields["xor"]
    assert bytes(damaged) == data
    assert int.from_bytes(data[260:262], "big") != _crc16(data[6:166])  # the first copy fails its own CRC
    frames, _ = parse_stream(data)
    assert [f.type for f in frames] == [FrameType.DATA_BLOCKS, FrameType.HEADER, FrameType.DUMP_END]
    rec, said = _decoded(data)
    assert rec.valid.all() and rec.codes.tolist() == codes.tolist()
    with pytest.raises(ProtocolError, match="no intact HEADER frame"):  # without the second copy: refused
        decode_bytes(bytes(damaged[:0x122]))


def _check_capture_frames(data: bytes, fields: dict) -> None:
    """Section 4, decoding a capture: a HEADER frame that fails its CRC-16 but whose header verifies places
    the samples; one damaged inside the header's CRC does not."""
    header, samples, codes, _ = _raw_dump_parts(EXAMPLES[fields["example"]]["fields"])
    clean = bytearray(encode_frame(FrameType.HEADER, 1, header.to_bytes())
                      + encode_frame(FrameType.DATA, 0, build_payload(FrameType.DATA, address=0, data=samples)))
    damaged = bytearray(clean)
    damaged[fields["damaged_byte"]] ^= fields["xor"]
    assert bytes(damaged) == data
    assert int.from_bytes(data[262:264], "big") != _crc16(data[2:262])  # the frame fails its CRC-16
    assert int.from_bytes(data[260:262], "big") == _crc16(data[6:166])  # its header passes its own
    frames, errors = parse_stream(data)
    assert [f.type for f in frames] == [FrameType.DATA] and errors[0].reason == "bad_crc"
    rec, said = _decoded(data)
    assert "HEADER frame at offset 0 is damaged" in said
    assert rec.valid.all() and rec.codes.tolist() == codes.tolist()
    inside = bytearray(clean)
    inside[fields["damaged_inside"]] ^= fields["xor"]
    with pytest.raises(ProtocolError, match="no intact HEADER frame"):
        decode_bytes(bytes(inside))


# ------------------------------------------------------------------------------------------------ tables
def _section(title_regex: str) -> str:
    m = re.search(rf"^(#+) {title_regex}.*?$(.*?)(?=^#+ )", SPEC, re.S | re.M)
    assert m, title_regex
    return m.group(2)


def _table_rows(text: str) -> list[list[str]]:
    rows = []
    for line in text.splitlines():
        if line.startswith("|") and not re.match(r"^\|[-| ]+\|$", line):
            rows.append([c.strip() for c in line.strip("|").split("|")])
    return rows[1:] if rows else rows  # drop the header row of the first table only


def _field_rows(text: str) -> list[tuple[int, int, str]]:
    """(offset, size, field) of the rows of the first table of ``text`` (reserved rows: field '')."""
    table = text.split("\n\n|", 1)[1] if not text.lstrip().startswith("|") else text
    out = []
    for line in ("|" + table).splitlines():
        if not line.startswith("|"):
            if out:
                break
            continue
        cells = [c.strip() for c in line.strip("|").split("|")]
        if not cells[0].isdigit():
            continue
        name = re.search(r"`(\w+)`", cells[3])
        out.append((int(cells[0]), int(cells[1]), name.group(1) if name else ""))
    return out


def test_header_table_matches_struct() -> None:
    rows = _field_rows(_section(r"2\. Device header"))
    pos = 0
    for offset, size, name in rows:
        assert offset == pos, f"gap or overlap before offset {offset}"
        pos = offset + size
        if name:
            assert HEADER_OFFSETS[name] == (offset, size), name
    assert pos == 256
    assert {n for _, _, n in rows if n} == set(HEADER_OFFSETS) - {"reserved0", "reserved1"}


def test_commit_journal_table_matches_module() -> None:
    text = _section(r"2\.4 Recording identity")
    assert f"{JOURNAL_ENTRIES} entries of {ENTRY_BYTES} bytes" in text
    assert HEADER_OFFSETS["commit_journal"] == (JOURNAL_OFFSET, JOURNAL_BYTES)


def test_flag_table_matches_enum() -> None:
    text = _section(r"2\. Device header")
    rows = re.findall(r"^\| (\d) \| 0x([0-9A-F]{2}) \| (\w+) \|", text, re.M)
    assert {name: int(v, 16) for _, v, name in rows} == {f.name: f.value for f in HeaderFlag}
    assert all(int(v, 16) == 1 << int(bit) for bit, v, _ in rows)


def test_calibration_table_matches_struct() -> None:
    rows = _field_rows(_section(r"2\.1 Calibration slot"))
    pos = 0
    for offset, size, name in rows:
        assert offset == pos
        pos = offset + size
        if name:
            assert CALIBRATION_OFFSETS[name] == (offset, size), name
    assert pos == 64


_TYPE_FMT = {"u8": "<B", "i8": "<b", "u16": "<H", "i32": "<l", "u32": "<L", "u16 **BE**": ">H"}


def _typed_rows(text: str) -> list[tuple[int, int, str, str]]:
    """(offset, size, type, field) of the rows of the first table of ``text`` (reserved rows: field '')."""
    table = text.split("\n\n|", 1)[1]
    out = []
    for line in ("|" + table).splitlines():
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        if cells[0].isdigit():
            name = re.search(r"`(\w+)`", cells[3])
            out.append((int(cells[0]), int(cells[1]), cells[2], name.group(1) if name else ""))
    return out


def _check_typed_table(rows: list[tuple[int, int, str, str]], offsets: dict, subcons: dict, total: int) -> None:
    pos = 0
    for offset, size, typ, name in rows:
        assert offset == pos, f"gap or overlap before offset {offset}"
        pos = offset + size
        if name:
            assert offsets[name] == (offset, size), name
            assert subcons[name].fmtstr == _TYPE_FMT[typ], name
    assert pos == total
    assert {n for *_, n in rows if n} == {n for n in offsets if not n.startswith("reserved")}


def test_step_config_table_matches_struct() -> None:
    rows = _typed_rows(_section(r"2\.2 Step configuration block"))
    subcons = {sc.name: sc.subcon for sc in STEP_CONFIG_STRUCT.subcons if sc.name}
    _check_typed_table(rows, STEP_CONFIG_OFFSETS, subcons, 32)


def test_step_record_table_matches_struct_and_dtype() -> None:
    rows = _typed_rows(_section(r"2\.3 Step memory"))
    subcons = {sc.name: sc.subcon for sc in STEP_RECORD_BODY_STRUCT.subcons}
    subcons["record_crc"] = STEP_RECORD_STRUCT.subcons[1].subcon.checksumfield  # the Checksum's Int16ub
    _check_typed_table(rows, STEP_RECORD_OFFSETS, subcons, 20)
    assert [name for *_, name in rows] == list(STEP_RECORD_DTYPE.names)
    for offset, _, _, name in rows:
        assert STEP_RECORD_DTYPE.fields[name][1] == offset, name


def test_step_flag_table_matches_enum() -> None:
    text = _section(r"2\.3 Step memory")
    rows = re.findall(r"^\| (\d) \| 0x([0-9A-F]{2}) \| (\w+) \|", text, re.M)
    assert {name: int(v, 16) for _, v, name in rows} == {f.name: f.value for f in StepFlag}
    assert all(int(v, 16) == 1 << int(bit) for bit, v, _ in rows)


def test_frame_table_matches_struct() -> None:
    text = _section(r"3\. Frames")
    rows = re.findall(r"^\| (\d+\+?N?) \| (\w+) \| (.*?) \|$", text, re.M)
    fixed = {r[2].split()[0].strip("`"): (int(r[0]), int(r[1])) for r in rows if r[0].isdigit() and r[1].isdigit()}
    assert fixed == {"sync": (0, 2), "type": (2, 1), "seq": (3, 1), "length": (4, 2)}
    assert FRAME_HEAD_STRUCT.sizeof() == 6
    assert f"0 ≤ N ≤ {MAX_PAYLOAD}" in text and f"length above {MAX_PAYLOAD}" in text


SIZES = {"u8": 1, "u16": 2, "u32": 4}


def test_type_table_matches_enum_and_payload_structs() -> None:
    text = _section(r"3\.1 Commands")
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in text.splitlines()
            if line.startswith("| 0x")]
    rows = [(r[0][2:], r[1], r[2], r[3]) for r in rows]
    assert {name: int(code, 16) for code, name, _, _ in rows} == {t.name: t.value for t in FrameType}
    for code, name, payload, _ in rows:
        struct = PAYLOAD_STRUCTS[FrameType[name]]
        names = re.findall(r"`(\w+)`", payload)
        names = [n for n in names if n != "ERASE"]
        assert names == [sc.name for sc in struct.subcons if sc.name], name
        for field, kind in re.findall(r"`(\w+)` (u8|u16|u32)\b", payload):
            sc = next(sc for sc in struct.subcons if sc.name == field)
            assert sc.sizeof() == SIZES[kind], (name, field)
    assert f"1 … {MAX_DATA}" in text


def test_error_table_matches_enum() -> None:
    rows = re.findall(r"^\| 0x([0-9A-F]{2}) \| (\w+) \|", _section(r"3\.2 Error codes"), re.M)
    assert {name: int(code, 16) for code, name in rows} == {e.name: e.value for e in ErrorCode}


def test_image_table_matches_struct() -> None:
    text = _section(r"6\. Memory-image file")
    rows = re.findall(r"^\| (\d+) \| (\d+) \| (.*?) \|$", text, re.M)
    pos = 0
    for offset, size, desc in rows:
        assert int(offset) == pos
        pos += int(size)
        m = re.search(r"`(\w+)`", desc)
        if m:
            assert IMAGE_OFFSETS[m.group(1)] == int(offset)
    assert pos == 16 == IMAGE_PREFIX_STRUCT.sizeof()
    assert f"±{SHIFT_SEARCH_BYTES} bytes" in text
