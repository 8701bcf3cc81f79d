"""Power-cut campaign (``PROTOCOL.md`` section 2.4): random power losses during logging, in both memory modes.

Each trial takes a fresh emulated logger, logs a few complete runs (random lengths; in OVERWRITE mode often
enough to wrap the memory), then starts a run, logs a random number of samples in random blocks and cuts the
power: between two samples, or inside the write in flight (a random byte of the page write, torn there, or of
the journal entry that commits it). In 30 % of the trials the cut falls instead inside a header commit
(section 2.5): START's (its journal clear, its header slot, its data EEPROM bytes) or the one that ends the
run (STOP's, or a full memory's); each of those parts is as likely. The device powers up (the committed
header from the data EEPROM and the header slots, recovery from the journal) and, in some trials, logs one
more complete run. Every sample's codes encode its absolute sample number and its run, so a sample
shown under the wrong number, or another run's sample, cannot pass.

Checked for every trial, against the model's truth (which samples were taken, which page writes completed):

- the memory is decoded twice: from the image the device writes after power-up, and from the data EEPROM
  as the cut left it (header with LOGGING set: the decoder recovers it; after a header cut, the header
  rolled forward from the slots as power-up does); both give the same samples;
- a header commit is all or nothing: START either never happened (the header as before it) or began a run
  that lost nothing; the commit ending a run either landed (every sample kept, no POWER_LOST) or the run is
  recovered from its journal;
- every valid decoded sample is exactly the one taken under that number (0 wrong samples, 0 of another run);
- the cut run keeps exactly the samples of its completed page commits: the samples lost are at most one page
  (32), and the header says so exactly: POWER_LOST, the recording number, ``samples_written`` = the run's
  first sample + the committed samples;
- every stored sample that is not valid is one of the torn slots of the page in flight (at most 32), reported
  with that reason.

Run ``python benchmarks/power_cut_campaign.py`` (1,000 cuts, both modes; 44 s at load ~2);
``tests/firmware_sim/test_fw_power_loss.py`` runs a smaller campaign. ``--journal-ring`` runs it on header
version 3 (section 2.7: the journal in the step EEPROM's ring, an entry every second page): a cut run then
keeps the samples of its journalled commits (an even number of pages), loses at most two pages (64) and
reports at most 64 torn slots; the EEPROMs as the cut left them are recovered with the ring, as power-up
does (``tests/firmware_sim/test_fw_journal_ring.py`` runs a smaller campaign).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.host.files.decode import REASONS, decode_bytes
from gaitlog.protocol.commit_journal import JOURNAL_OFFSET
from gaitlog.protocol.header import PAGE_SAMPLES, DeviceHeader
from gaitlog.protocol.header_slots import SLOT_ADDRESSES, SLOT_BYTES, committed_header
from gaitlog.protocol.image import build_image
from gaitlog.protocol.journal_ring import COMMIT_PAGES, last_ring_commit

_SENSOR = SensorModel.draw(seed=1)
_TORN = REASONS.index("slot of the page in flight when a power loss cut a run (contents undefined)")


@dataclass
class CampaignResult:
    """Counts over a campaign."""

    trials: int = 0
    wrong_samples: int = 0
    max_lost_samples: int = 0
    max_torn_slots: int = 0
    misreported: int = 0
    cut_kinds: Counter = field(default_factory=Counter)
    failures: list[str] = field(default_factory=list)
    #: Header version 3 (the journal ring): commits are journalled every second page.
    journal_ring: bool = False

    @property
    def commit_pages(self) -> int:
        """Pages per journalled commit: the loss bound in pages."""
        return COMMIT_PAGES if self.journal_ring else 1

    @property
    def ok(self) -> bool:
        bound = self.commit_pages * PAGE_SAMPLES
        return not (self.wrong_samples or self.misreported or self.max_lost_samples > bound
                    or self.max_torn_slots > bound)


def _codes(numbers: np.ndarray, run: int) -> np.ndarray:
    """Codes that name the sample: x, y the absolute number, z the run."""
    n = np.asarray(numbers, dtype=np.int64)
    return np.stack([n & 1023, (n >> 10) & 1023, np.full(n.size, run % 1024)], axis=1).astype(np.int64)


class Truth:
    """The codes taken under each absolute sample number (-1: none, or taken but never committed)."""

    def __init__(self, size: int) -> None:
        self.codes = np.full((size, 3), -1, dtype=np.int64)

    def clear(self) -> None:
        self.codes[:] = -1


def _log(logger: Logger, truth: Truth, run: int, n: int, rng: np.random.Generator) -> int:
    """Log ``n`` samples of run ``run`` in random blocks; record the truth; return how many were stored."""
    fw = logger.firmware
    stored = 0
    while n > 0 and logger.ring.logging:
        k = int(min(n, rng.choice([1, 7, 31, 32, 33, 100, 1000, 5000])))
        first = int(logger.header.samples_written)
        codes = _codes(first + np.arange(k), run)
        got = fw.log_samples(codes)
        truth.codes[first:first + got] = codes[:got]
        stored += got
        n -= k
    return stored


def _committed(n_taken: int, first_slot: int, room: int | None, last_page_in_flight: bool,
               commit_pages: int = 1) -> int:
    """Samples of a run that completed page commits (independent of the journal): the first page ends at the
    next page boundary, then every 32; the page the last sample completed is lost if the cut fell in its write
    (or in the journal entry after it). Journalled every ``commit_pages`` pages (header version 3), only a
    multiple of them counts."""
    f = PAGE_SAMPLES - first_slot % PAGE_SAMPLES
    if room is not None and n_taken >= room:  # the run filled the memory: it ended, committed, before the cut
        return room
    pages = 0 if n_taken < f else 1 + (n_taken - f) // PAGE_SAMPLES
    if last_page_in_flight and pages:
        pages -= 1
    pages -= pages % commit_pages
    return 0 if pages == 0 else f + (pages - 1) * PAGE_SAMPLES


def _check(rec, truth: Truth, res: CampaignResult, where: str) -> None:
    valid = np.asarray(rec.valid, bool)
    numbers = rec.sample_numbers[valid]
    codes = rec.codes[valid]
    expect = truth.codes[numbers]
    wrong = int((codes.astype(np.int64) != expect).any(axis=1).sum())
    if wrong:
        res.wrong_samples += wrong
        res.failures.append(f"{where}: {wrong} wrong samples")
    torn = rec.header.torn_slot_numbers()
    bad = int((~valid).sum())
    res.max_torn_slots = max(res.max_torn_slots, bad)
    reasons_ok = all(g.reason == REASONS[_TORN] for g in rec.gaps)
    if bad != torn.size or not reasons_ok:
        res.misreported += 1
        res.failures.append(f"{where}: {bad} invalid samples, torn slots {torn.size}, gaps {rec.gaps}")


def _decode(header_bytes: bytes, logger: Logger):
    header = DeviceHeader.from_bytes(header_bytes)
    if header.logging and header.header_version == 3:  # the journal is in the ring: recover as power-up does
        header = header.recovered(last_ring_commit(logger.ring.ring_entries(), recording_number=header.recording_number,
                                                   recording_nonce=header.recording_nonce))
        header_bytes = header.to_bytes()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return decode_bytes(build_image(header_bytes, logger.memory, step_memory=logger.step_memory))


def trial(seed: int, overwrite: bool, res: CampaignResult) -> None:
    """One power cut (see the module docstring)."""
    rng = np.random.default_rng(seed)
    logger = Logger(device_id=1 + seed % 3, sensor=_SENSOR, overwrite=overwrite, journal_ring=res.journal_ring)
    logger.firmware.nonce_source = lambda: int(rng.integers(0, 2**32))
    cap = logger.header.capacity_samples
    truth = Truth(16 * cap)
    run = 0
    for _ in range(int(rng.integers(0, 4))):  # earlier complete runs
        if not overwrite and logger.ring.full:
            break
        run += 1
        logger.firmware.start_logging(start_time_s=run, overwrite=overwrite)
        _log(logger, truth, run, int(rng.choice([int(rng.integers(1, 3000)), int(rng.integers(1, 2 * cap))])), rng)
        logger.firmware.stop_logging()
    if not overwrite and logger.ring.full:
        logger.erase()
        truth.clear()
    run += 1
    header_cut = str(rng.choice(["START", "STOP", "none"], p=[0.15, 0.15, 0.7]))
    if header_cut == "START":
        _header_cut_at_start(logger, truth, run, overwrite, rng, res, f"seed {seed}")
        res.trials += 1
        return
    logger.firmware.start_logging(start_time_s=run, overwrite=overwrite)
    h0 = logger.header
    s0, w0, number = int(h0.samples_written), int(h0.write_index), int(h0.recording_number)
    room = logger.ring.room_samples
    n = int(rng.choice([int(rng.integers(0, 200)), int(rng.integers(0, 3 * cap))]))
    if rng.random() < 0.6:  # end on a page boundary: the last sample starts a page write, the cut may fall in it
        n += (-(w0 + n)) % PAGE_SAMPLES
    n_taken = _log(logger, truth, run, n, rng)
    if header_cut == "STOP":
        _header_cut_at_stop(logger, truth, (s0, w0, number, room, n_taken), rng, res,
                            f"seed {seed} {'overwrite' if overwrite else 'stop-when-full'}")
        res.trials += 1
        return
    during_stop = bool(rng.random() < 0.1) and logger.ring.logging
    if during_stop:
        logger.firmware._end_steps()
        logger.ring._flush()
    in_flight = logger.ring.in_flight_bytes()
    n_page = len(logger.ring._in_flight[2]) if in_flight else 0
    at_byte = None
    if in_flight and rng.random() < 0.8:  # in the page write, in the journal write, or just after the commit
        at_byte = int(rng.integers(0, n_page)) if rng.random() < 0.6 else int(rng.integers(n_page, in_flight + 1))
    if not logger.ring.logging:
        kind = "after the run filled the memory"
    elif at_byte is None:
        kind = "between samples"
    elif at_byte < n_page:
        kind = "in the page write" + (" (STOP's flush)" if during_stop else "")
    elif at_byte < in_flight:
        kind = "in the journal write"
    else:
        kind = "after the commit"
    res.cut_kinds[kind] += 1
    was_logging = logger.ring.logging
    logger.ring.power_cut(at_byte)
    raw_header = logger.data_eeprom.read()
    if was_logging:
        logger.power_up()
    else:
        logger.firmware.stop_logging()
    where = f"seed {seed} {'overwrite' if overwrite else 'stop-when-full'} cut {kind} after {n_taken} samples"
    h = logger.header
    last_in_flight = was_logging and (during_stop or (at_byte is not None and at_byte < in_flight))
    if during_stop:  # the flushed partial page is lost: the committed pages are those the samples completed
        c_true = _committed(n_taken, w0, room, False, res.commit_pages)
    else:
        c_true = _committed(n_taken, w0, room, last_in_flight and n_page > 0, res.commit_pages)
    truth.codes[s0 + c_true:s0 + n_taken] = -1  # taken, never committed: must never be shown
    lost = n_taken - c_true
    res.max_lost_samples = max(res.max_lost_samples, lost)
    expect_flag = was_logging
    if (h.samples_written != s0 + c_true or h.recording_number != number or h.power_lost != expect_flag
            or lost > res.commit_pages * PAGE_SAMPLES):
        res.misreported += 1
        res.failures.append(f"{where}: samples_written {h.samples_written}, expected {s0 + c_true} "
                            f"(lost {lost}); POWER_LOST {h.power_lost}, recording {h.recording_number}/{number}")
    _check_both(logger, truth, raw_header, res, where)
    if rng.random() < 0.3 and not (not overwrite and logger.ring.full):  # one more run over the torn page
        run += 1
        logger.firmware.start_logging(start_time_s=run, overwrite=overwrite)
        _log(logger, truth, run, int(rng.integers(1, 100)), rng)
        logger.firmware.stop_logging()
        _check(_decode(logger.header.to_bytes(), logger), truth, res, where + " (then one more run)")
    res.trials += 1


def _cut_header_commit(logger: Logger, rng: np.random.Generator, res: CampaignResult,
                       label: str) -> tuple[str, bool, bytes]:
    """Cut the last header commit (``label``'s) at a random byte write (or just after it), count the cut's
    kind and power up: the kind, whether the new header is the committed one (its slot complete), and the
    header as the EEPROMs held it after the cut (power-up's rule)."""
    order = logger.ring.header_write_order()  # ("d", offset) data EEPROM bytes, ("s", i) slot bytes
    assert order, "no header commit to cut"
    # each part as often (the slot's 168 byte writes would otherwise drown the ~10 data EEPROM ones)
    parts = [[k for k, (w, i) in enumerate(order) if w == "d" and i >= JOURNAL_OFFSET],
             [k for k, (w, _) in enumerate(order) if w == "s"],
             [k for k, (w, i) in enumerate(order) if w == "d" and i < JOURNAL_OFFSET], [len(order)]]
    parts = [p for p in parts if p]
    at = int(rng.choice(parts[int(rng.integers(0, len(parts)))]))
    where = logger.ring.power_cut_header(at)
    slots = [logger.step_eeprom.sequential_read(a, SLOT_BYTES) for a in SLOT_ADDRESSES]
    raw_header = committed_header(logger.data_eeprom.read(), slots).header
    kind = f"in {label} header commit ({where})"
    res.cut_kinds[kind] += 1
    logger.power_up()
    return kind, where in ("data EEPROM", "after"), raw_header


def _header_cut_at_start(logger: Logger, truth: Truth, run: int, overwrite: bool, rng: np.random.Generator,
                         res: CampaignResult, where: str) -> None:
    """The power fails inside START's header commit (journal clear, slot, data EEPROM): either the run never
    started (the header as before START) or it started and lost nothing (POWER_LOST, no sample)."""
    before = logger.header.to_bytes()
    s0 = int(logger.header.samples_written)
    logger.firmware.start_logging(start_time_s=run, overwrite=overwrite)
    number = int(logger.header.recording_number)
    kind, landed, raw_header = _cut_header_commit(logger, rng, res, "START's")
    where = f"{where} cut {kind}"
    h = logger.header
    now = h.to_bytes()
    if landed:
        ok = (h.samples_written == s0 and h.recording_number == number and h.power_lost and not h.logging)
    else:
        ok = now[:JOURNAL_OFFSET] + now[-2:] == before[:JOURNAL_OFFSET] + before[-2:]
    if not ok:
        res.misreported += 1
        res.failures.append(f"{where}: header after power-up {h} (START {'landed' if landed else 'lost'})")
    _check_both(logger, truth, raw_header, res, where)


def _header_cut_at_stop(logger: Logger, truth: Truth, run_state: tuple[int, int, int, int | None, int],
                        rng: np.random.Generator, res: CampaignResult, where: str) -> None:
    """The power fails inside the header commit that ends the run (STOP's, or a full memory's in stop-when-full
    mode): either it landed (every sample stored, no loss) or the run is recovered from its journal as
    after a cut between samples (the partial page STOP flushed is lost)."""
    s0, w0, number, room, n_taken = run_state
    label = "STOP's" if logger.ring.logging else "the full memory's"
    logger.firmware.stop_logging()
    kind, landed, raw_header = _cut_header_commit(logger, rng, res, label)
    where = f"{where} cut {kind} after {n_taken} samples"
    h = logger.header
    # version 3: a full memory's last page may have no journal entry (an odd commit): without the header
    # commit, the run keeps its journalled pages only, like a run cut in STOP's
    c_true = n_taken if landed else _committed(n_taken, w0, None if res.journal_ring else room, False,
                                               res.commit_pages)
    truth.codes[s0 + c_true:s0 + n_taken] = -1  # taken, never committed: must never be shown
    lost = n_taken - c_true
    res.max_lost_samples = max(res.max_lost_samples, lost)
    if (h.samples_written != s0 + c_true or h.recording_number != number or h.power_lost == landed
            or h.logging or lost > res.commit_pages * PAGE_SAMPLES):
        res.misreported += 1
        res.failures.append(f"{where}: samples_written {h.samples_written}, expected {s0 + c_true} "
                            f"(lost {lost}); POWER_LOST {h.power_lost}, recording {h.recording_number}/{number}")
    _check_both(logger, truth, raw_header, res, where)


def _check_both(logger: Logger, truth: Truth, raw_header: bytes, res: CampaignResult, where: str) -> None:
    """Decode the image written after power-up and the EEPROMs as the cut left them; both must agree."""
    rec_after = _decode(logger.header.to_bytes(), logger)
    _check(rec_after, truth, res, where + " (image after power-up)")
    rec_raw = _decode(raw_header, logger)
    _check(rec_raw, truth, res, where + " (EEPROMs as the cut left them)")
    if not (np.array_equal(rec_raw.valid, rec_after.valid) and np.array_equal(rec_raw.codes, rec_after.codes)
            and np.array_equal(rec_raw.sample_numbers, rec_after.sample_numbers)):
        res.misreported += 1
        res.failures.append(f"{where}: the two decodes differ")


def run_campaign(n_cuts: int, seed: int = 0, *, journal_ring: bool = False) -> CampaignResult:
    """``n_cuts`` trials, alternating stop-when-full and OVERWRITE mode (``journal_ring``: header version 3)."""
    res = CampaignResult(journal_ring=journal_ring)
    for i in range(n_cuts):
        trial(seed * 1_000_003 + i, overwrite=bool(i % 2), res=res)
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cuts", type=int, default=1000, help="power cuts (half in each memory mode; default 1000)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--journal-ring", action="store_true",
                    help="header version 3: the journal in the step EEPROM's ring, an entry every second page")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    res = run_campaign(args.cuts, args.seed, journal_ring=args.journal_ring)
    print(f"{res.trials} power cuts ({args.cuts // 2 + args.cuts % 2} stop-when-full, {args.cuts // 2} overwrite) "
          f"in {time.perf_counter() - t0:.1f} s")
    for kind, count in sorted(res.cut_kinds.items()):
        print(f"  cut {kind:<48s} {count:5d}")
    print(f"wrong samples (any run)              {res.wrong_samples}")
    bound = res.commit_pages * PAGE_SAMPLES
    print(f"most samples a cut run lost          {res.max_lost_samples} (bound: {res.commit_pages} page(s), {bound})")
    print(f"most stored samples reported missing {res.max_torn_slots} (the torn slots of the page(s) in flight)")
    print(f"losses misreported                   {res.misreported}")
    for f in res.failures[:10]:
        print("  " + f)
    print("OK" if res.ok else "FAILED")
    return 0 if res.ok else 1


if __name__ == "__main__":
    sys.exit(main())
