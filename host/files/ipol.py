"""Reader of the IPOL lower-back gait recordings (Voisard et al., IPOL 2023).

Layout of a folder: ``GaitData/<subject>-<trial>_lb.txt`` (tab-separated, a first line
``Acquisition frequency: 100 Hz``, then a header ``PacketCounter Acc_X Acc_Y Acc_Z Gyr_X ...``; acceleration
in m/s^2, gravity included, +g on the axis pointing up) and ``GaitData/<subject>-<trial>.json``
(``TrialBoundaries``, ``UTurnBoundaries``, ``LeftFootEvents`` / ``RightFootEvents`` as [toe-off,
heel-strike] pairs, ``Height`` in cm, sometimes missing; ``WalkedDistance_m``, optional, the distance walked
between the trial boundaries when it is not 20 m).

Every sample index in the JSON counts *packets*, not file rows, and the files have lost packets. This
reader puts each file on the regular ``PacketCounter`` grid (its 16-bit wrap-around undone): index ``i`` of the returned arrays is packet
``first_counter + i``; a lost packet is a row of NaN with ``valid[i] = False``. Nothing is interpolated.
A duplicated packet keeps its first copy (a warning is issued when the copies differ).

:func:`write_trial` writes a trial in the same layout (the simulated walks of ``gaitlog simulate --ipol-out``),
so that anything reading IPOL folders reads them unchanged.
"""

from __future__ import annotations

import json
import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaitlog.host.errors import HostError
from gaitlog.host.storage.limits import (
    MAX_JSON_BYTES,
    MAX_TEXT_BYTES,
    check_file_size,
    check_grid,
    check_memory,
)
from gaitlog.atomic_write import atomic_write
from gaitlog.units import STANDARD_GRAVITY_M_S2

#: Rate of the IPOL lower-back files (Xsens MTw packets), and of the trials :func:`write_trial` writes.
IPOL_SAMPLING_RATE_HZ = 100.0
#: A trial's data file, ``<subject>-<trial>_lb.txt`` (the suffix in any case: ``1-2_LB.txt`` is trial 1-2).
_NAME = re.compile(r"^(\d+)-(\d+)_lb\.txt$", re.IGNORECASE)
#: A name that ends like a trial's data file (any case), whether or not the rest is ``<subject>-<trial>``.
_LIKE_NAME = re.compile(r"_lb\.txt$", re.IGNORECASE)
#: A trial JSON, ``<subject>-<trial>.json`` (any case).
_JSON_NAME = re.compile(r"^(\d+)-(\d+)\.json$", re.IGNORECASE)
#: The optional JSON field giving the distance walked between ``TrialBoundaries`` (m) when it is not the IPOL
#: protocol's (lab walking bouts in the same layout).
WALKED_DISTANCE_KEY = "WalkedDistance_m"
#: ``PacketCounter`` counts modulo 2**16 (the Xsens MTw's 16-bit counter): a long recording wraps to 0.
PACKET_COUNTER_MODULUS = 1 << 16
#: Columns written by :func:`write_trial` (the reader needs these four; the Xsens files add gyroscope and
#: magnetometer columns).
WRITTEN_COLUMNS = ("PacketCounter", "Acc_X", "Acc_Y", "Acc_Z")


@dataclass(frozen=True, eq=False)
class IpolTrial:
    """One IPOL trial on its regular packet grid.

    Attributes
    ----------
    subject, trial
        Identifiers from the file name ``<subject>-<trial>``.
    acc_g
        ``(n, 3)`` specific force in g (file's ``Acc_X..Z`` divided by :data:`~gaitlog.firmware_sim.world.base.STANDARD_GRAVITY_M_S2`), NaN at lost packets.
    valid
        ``(n,)`` bool, False at lost packets.
    sampling_rate_hz
        From the first line of the file (100 Hz).
    first_counter
        ``PacketCounter`` of grid index 0; JSON indices are used as grid indices unchanged.
    meta
        The JSON document as read.
    """

    subject: int
    trial: int
    acc_g: np.ndarray
    valid: np.ndarray
    sampling_rate_hz: float
    first_counter: int
    meta: dict = field(default_factory=dict)
    path: Path | None = None

    @property
    def name(self) -> str:
        """``"<subject>-<trial>"``."""
        return f"{self.subject}-{self.trial}"

    @property
    def trial_bounds(self) -> tuple[int, int]:
        """``TrialBoundaries`` (first and last sample index of the walk, packets)."""
        b = self.meta["TrialBoundaries"]
        return int(b[0]), int(b[1])

    @property
    def uturn_bounds(self) -> tuple[int, int] | None:
        """``UTurnBoundaries`` or None when absent."""
        b = self.meta.get("UTurnBoundaries")
        return (int(b[0]), int(b[1])) if b else None

    @property
    def height_m(self) -> float | None:
        """Body height in metres, None when the JSON has none (:func:`height_m_of`)."""
        return height_m_of(self.meta)

    def foot_events(self) -> tuple[np.ndarray, np.ndarray]:
        """Reference toe-off and heel-strike indices of both feet, sorted, shape ``(m,)`` each."""
        pairs = list(self.meta.get("LeftFootEvents") or []) + list(self.meta.get("RightFootEvents") or [])
        arr = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        return np.sort(arr[:, 0]), np.sort(arr[:, 1])

    def reference_steps(self) -> int:
        """Number of reference heel strikes inside ``TrialBoundaries`` (inclusive): one per step."""
        lo, hi = self.trial_bounds
        _, hs = self.foot_events()
        return int(np.count_nonzero((hs >= lo) & (hs <= hi)))


def read_lb_file(path: str | Path) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Read one ``*_lb.txt`` file onto its regular packet grid.

    Returns
    -------
    acc_g, valid, sampling_rate_hz, first_counter
        See :class:`IpolTrial`.

    Raises
    ------
    HostError
        Unreadable header, missing columns, non-numeric rows, or a counter that goes backwards.
    """
    path = Path(path)
    check_file_size(path, MAX_TEXT_BYTES, "an IPOL file")
    try:
        with open(path, encoding="utf-8", errors="strict") as fh:
            first = fh.readline()
            header = fh.readline().rstrip("\r\n").split("\t")
    except (OSError, UnicodeDecodeError) as err:
        raise HostError(f"{path}: cannot read IPOL file: {err}") from err
    rate = _rate_hz(path, first)
    try:
        cols = [header.index(c) for c in WRITTEN_COLUMNS]
    except ValueError as err:
        raise HostError(f"{path}: line 2: missing column ({err}); found {header}") from err
    try:
        data = np.loadtxt(path, skiprows=2, usecols=cols, ndmin=2, delimiter="\t")
    except ValueError as err:
        raise HostError(f"{path}: {_bad_line(path, cols) or f'bad numeric row: {err}'}") from err
    bad = np.flatnonzero(~np.all(np.isfinite(data), axis=1))
    if bad.size:
        raise HostError(f"{path}: line {bad[0] + 3}: bad numeric row: a value of {', '.join(WRITTEN_COLUMNS)} is not "
                        "a finite number")
    if data.shape[0] < 2:
        raise HostError(f"{path}: fewer than 2 samples")
    counter = data[:, 0]
    if not np.all(np.isfinite(counter)) or np.any(counter != np.round(counter)):
        raise HostError(f"{path}: PacketCounter is not an integer everywhere")
    raw = counter.astype(np.int64)
    counter = _unwrapped(raw)
    d = np.diff(counter)
    back = np.flatnonzero(d < 0)
    if back.size:
        raise HostError(f"{path}: line {back[0] + 4}: PacketCounter goes backwards ({raw[back[0]]} -> "
                        f"{raw[back[0] + 1]}), and not from the top of its 16 bits to the bottom (a wrap)")
    dup = np.flatnonzero(d == 0)
    if dup.size:
        differ = np.any(data[dup, 1:] != data[dup + 1, 1:])
        if differ:
            warnings.warn(f"{path}: {dup.size} duplicated packet(s) with different values; keeping the first",
                          stacklevel=2)
        keep = np.ones(counter.size, bool)
        keep[dup + 1] = False
        counter, data = counter[keep], data[keep]
    first_counter = int(counter[0])
    n = int(counter[-1] - first_counter + 1)
    check_grid(n, counter.size, path, f"PacketCounter {first_counter} .. {int(counter[-1])}")
    check_memory(25 * n, path, "its packet grid")
    acc = np.full((n, 3), np.nan)
    valid = np.zeros(n, bool)
    idx = counter - first_counter
    acc[idx] = data[:, 1:4] / STANDARD_GRAVITY_M_S2
    valid[idx] = True
    return acc, valid, rate, first_counter


def _unwrapped(counter: np.ndarray) -> np.ndarray:
    """``PacketCounter`` with its 16-bit wrap-arounds undone: a step down of more than half the range
    (65535 -> 0, across lost packets too) adds :data:`PACKET_COUNTER_MODULUS` to every later counter; any other step
    down is left for the caller to refuse.

    >>> _unwrapped(np.array([65534, 65535, 1, 2])).tolist()
    [65534, 65535, 65537, 65538]
    """
    wraps = np.diff(counter) < -PACKET_COUNTER_MODULUS // 2
    return counter + PACKET_COUNTER_MODULUS * np.concatenate([[0], np.cumsum(wraps)])


def _rate_hz(path: Path, first_line: str) -> float:
    """The rate stated on a file's first line, ``Acquisition frequency: <rate> Hz`` (finite, > 0)."""
    m = re.search(r"([0-9]+(?:\.[0-9]*)?|\.[0-9]+)\s*Hz", first_line)
    rate = float(m.group(1)) if m else math.nan
    if not (math.isfinite(rate) and rate > 0):
        raise HostError(f"{path}: line 1: expected 'Acquisition frequency: <rate> Hz' with a rate > 0, found "
                        f"{first_line.strip()!r}")
    return rate


def _bad_line(path: Path, cols: list[int]) -> str | None:
    """Where the data rows of ``path`` first fail to give a number in each of ``cols`` (``"line N: ..."``, the
    file's line number), None when they do not (the caller then says what the parser said)."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        for n, line in enumerate(fh, start=1):
            if n <= 2:
                continue
            cells = line.rstrip("\r\n").split("\t")
            if len(cells) <= max(cols):
                return f"line {n}: bad numeric row: {len(cells)} columns, the header has more (a truncated row?)"
            for c in cols:
                try:
                    float(cells[c])
                except ValueError:
                    return f"line {n}: bad numeric row: column {c + 1} is {cells[c]!r}, not a number"
    return None


def read_trial(lb_path: str | Path) -> IpolTrial:
    """Read ``<s>-<t>_lb.txt`` and its ``<s>-<t>.json``.

    Raises
    ------
    HostError
        Bad file name, missing or invalid JSON, or a bad data file.
    """
    lb_path = Path(lb_path)
    m = _NAME.match(lb_path.name)
    if not m:
        raise HostError(f"{lb_path}: expected a file name '<subject>-<trial>_lb.txt'")
    json_path = json_path_of(lb_path)
    check_file_size(json_path, MAX_JSON_BYTES, "a trial JSON")
    try:
        meta = json.loads(json_path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as err:
        raise HostError(f"{json_path}: cannot read trial JSON: {type(err).__name__}: {err}") from err
    if not isinstance(meta, dict) or not isinstance(meta.get("TrialBoundaries"), list) \
            or len(meta["TrialBoundaries"]) != 2:
        raise HostError(f"{json_path}: missing 'TrialBoundaries' [start, end]")
    acc, valid, rate, first = read_lb_file(lb_path)
    check_meta(meta, valid.size, json_path)
    return IpolTrial(int(m.group(1)), int(m.group(2)), acc, valid, rate, first, meta, lb_path)


def json_path_of(lb_path: str | Path) -> Path:
    """The JSON of ``<s>-<t>_lb.txt``: ``<s>-<t>.json`` beside it, or the one file of that name in another case
    (``<s>-<t>.JSON``); the lower-case name when there is none (the caller's read then says it is missing)."""
    lb_path = Path(lb_path)
    stem = lb_path.name[: -len("_lb.txt")]
    want = lb_path.with_name(f"{stem}.json")
    if want.exists():
        return want
    try:
        others = [q for q in lb_path.parent.iterdir() if q.name.lower() == want.name.lower()]
    except OSError:
        return want
    return others[0] if len(others) == 1 else want


def _is_index(x: object) -> bool:
    """A JSON sample index: a whole number (``459`` or ``459.0``), not a bool or a string."""
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) and float(x).is_integer()


def check_meta(meta: dict, n_packets: int, json_path: str | Path) -> None:
    """Refuse a trial JSON whose fields the evaluation reads are malformed: ``TrialBoundaries`` two whole
    numbers, start before end, both on the recording's packet grid (``0`` to ``n_packets - 1``); ``UTurnBoundaries``
    absent, empty or two whole numbers; ``LeftFootEvents`` / ``RightFootEvents`` absent or lists of
    [toe-off, heel-strike] pairs of whole numbers; ``WalkedDistance_m`` absent or a finite number > 0 (metres).
    Other fields (age, sex, weight, unknown ones) are not read.

    Raises
    ------
    HostError
        Naming the JSON file and the field.
    """
    tb = meta.get("TrialBoundaries")
    if not (isinstance(tb, list) and len(tb) == 2 and all(map(_is_index, tb))):
        raise HostError(f"{json_path}: 'TrialBoundaries' must be [start, end] sample indices, found {tb!r}")
    if not 0 <= tb[0] < tb[1] <= n_packets - 1:
        raise HostError(f"{json_path}: 'TrialBoundaries' {tb!r} must be increasing and within the recording's "
                        f"packets 0 .. {n_packets - 1}")
    ub = meta.get("UTurnBoundaries")
    if ub not in (None, []) and not (isinstance(ub, list) and len(ub) == 2 and all(map(_is_index, ub))):
        raise HostError(f"{json_path}: 'UTurnBoundaries' must be [start, end] sample indices, found {ub!r}")
    wd = meta.get(WALKED_DISTANCE_KEY)
    if WALKED_DISTANCE_KEY in meta and walked_distance_m_of(meta) is None:
        raise HostError(f"{json_path}: '{WALKED_DISTANCE_KEY}' must be the distance walked between the trial "
                        f"boundaries, a number of metres > 0, found {wd!r}")
    for key in ("LeftFootEvents", "RightFootEvents"):
        ev = meta.get(key) or []
        bad = [ev] if not isinstance(ev, list) else [
            e for e in ev if not (isinstance(e, list) and len(e) == 2 and all(map(_is_index, e)))]
        if bad:
            raise HostError(f"{json_path}: '{key}' must be a list of [toe-off, heel-strike] sample index pairs, "
                            f"found {bad[0]!r}")


def list_trials(folder: str | Path) -> list[Path]:
    """All ``*_lb.txt`` files of an IPOL folder (``folder`` or ``folder/GaitData``), by subject then trial.

    Raises
    ------
    HostError
        When the folder holds no such file.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise HostError(f"{folder}: not a directory")
    base = folder / "GaitData" if (folder / "GaitData").is_dir() else folder
    files = [p for p in base.iterdir() if _NAME.match(p.name)]
    if not files:
        raise HostError(f"{base}: no '<subject>-<trial>_lb.txt' files (IPOL layout expected)")
    seen: dict[tuple[int, int], Path] = {}
    for p in sorted(files, key=lambda q: q.name):
        twin = seen.setdefault(trial_key(p), p)
        if twin is not p:
            raise HostError(f"{base}: {twin.name} and {p.name} are both subject {trial_key(p)[0]} trial "
                            f"{trial_key(p)[1]}; keep one")
    return sorted(files, key=trial_key)


def trial_key(lb_path: str | Path) -> tuple[int, int]:
    """``(subject, trial)`` of a ``<subject>-<trial>_lb.txt`` name (numbers: ``012-1`` is subject 12)."""
    m = _NAME.match(Path(lb_path).name)
    if not m:
        raise HostError(f"{lb_path}: expected a file name '<subject>-<trial>_lb.txt'")
    return int(m.group(1)), int(m.group(2))


def stray_files(folder: str | Path) -> list[str]:
    """What :func:`list_trials` leaves out of an IPOL folder that looks meant for it, one line each: a file
    ending in ``_lb.txt`` whose name is not ``<subject>-<trial>_lb.txt``, and a ``<subject>-<trial>.json`` with
    no data file beside it."""
    folder = Path(folder)
    base = folder / "GaitData" if (folder / "GaitData").is_dir() else folder
    names = sorted(p.name for p in base.iterdir())
    trials = {trial_key(n) for n in names if _NAME.match(n)}
    out = [f"{n}: not a '<subject>-<trial>_lb.txt' name, not read" for n in names
           if _LIKE_NAME.search(n) and not _NAME.match(n)]
    for n in names:
        m = _JSON_NAME.match(n)
        if m and (int(m.group(1)), int(m.group(2))) not in trials:
            out.append(f"{n}: no '{m.group(1)}-{m.group(2)}_lb.txt' beside it, not read")
    return out


def walked_distance_m_of(meta: dict) -> float | None:
    """The distance walked between ``TrialBoundaries`` from a trial JSON's ``WalkedDistance_m`` (m); None when
    absent, or not a finite number > 0 (:func:`check_meta` refuses such a value, naming it)."""
    d = meta.get(WALKED_DISTANCE_KEY)
    if not isinstance(d, int | float) or isinstance(d, bool) or not math.isfinite(d) or d <= 0:
        return None
    return float(d)


def height_m_of(meta: dict) -> float | None:
    """The subject's height in metres from a trial JSON's ``Height`` (cm); None when absent, not a number or not
    positive (a height outside the plausible range is left to :func:`gaitlog.host.gait.anthropometry.anatomical_lengths`
    to refuse, naming it)."""
    h = meta.get("Height")
    try:
        h = float(h)
    except (TypeError, ValueError):
        return None
    return h / 100.0 if np.isfinite(h) and h > 0 else None


def write_trial(folder: str | Path, subject: int, trial: int, acc_m_s2: np.ndarray, meta: dict, *,
                sampling_rate_hz: float = IPOL_SAMPLING_RATE_HZ) -> tuple[Path, Path]:
    """Write one trial as ``<folder>/<subject>-<trial>_lb.txt`` and ``<subject>-<trial>.json`` (IPOL layout).

    Parameters
    ----------
    folder
        Destination folder (created if missing).
    subject, trial
        Positive identifiers of the file names (and ``Subject``/``Trial``/``Filename`` in the JSON).
    acc_m_s2
        ``(n, 3)`` specific force in m/s^2 in the sensor's axes (``Acc_X..Z``), one row per packet; the
        ``PacketCounter`` column counts from 0, so JSON sample indices are row indices.
    meta
        The rest of the JSON (``TrialBoundaries``, ``UTurnBoundaries``, ``LeftFootEvents``,
        ``RightFootEvents`` as [toe-off, heel-strike] packet pairs, ``Height`` in cm, ...).
    sampling_rate_hz
        Stated on the first line (``Acquisition frequency: 100 Hz`` for the IPOL files).

    Returns
    -------
    lb_path, json_path
        The two files written (each atomically: a failed write leaves no partial file).
    """
    acc = np.asarray(acc_m_s2, dtype=np.float64)
    if acc.ndim != 2 or acc.shape[1] != 3 or acc.shape[0] < 2 or not np.all(np.isfinite(acc)):
        raise HostError(f"IPOL trial {subject}-{trial}: acceleration must be a finite (n >= 2, 3) array, "
                        f"got shape {acc.shape}")
    if subject < 1 or trial < 1:
        raise HostError(f"IPOL trial {subject}-{trial}: subject and trial numbers must be >= 1")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = f"{subject}-{trial}"
    lb_path, json_path = folder / f"{name}_lb.txt", folder / f"{name}.json"
    doc = {"Subject": int(subject), "Trial": int(trial), "Filename": name, **meta}
    rows = np.column_stack([np.arange(acc.shape[0], dtype=np.float64), acc])
    with atomic_write(lb_path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(f"Acquisition frequency: {sampling_rate_hz:g} Hz\n")
        fh.write("\t".join(WRITTEN_COLUMNS) + "\n")
        np.savetxt(fh, rows, fmt=["%.1f", "%.6f", "%.6f", "%.6f"], delimiter="\t")
    with atomic_write(json_path, "w", encoding="utf-8") as fh:
        json.dump(doc, fh)
    return lb_path, json_path
