"""The whole logger: sensor -> ADC -> firmware -> ring buffer and step store over the EEPROMs, persisted as a
memory image.

:class:`Logger` wires the parts of ``firmware_sim`` together the way the board does. :meth:`Logger.record`
runs one logging session on a motion (START, the sample timer over the motion's duration, STOP) fully
vectorised: the motion is rendered on the sensor's fine grid, the sensor model filters it, the ADC
samples it at the timer instants where the sensor noise is added (drawn exactly there), and the firmware packs and stores the block of samples with
whole-array page writes. The UART side is :attr:`Logger.firmware` (sans-I/O; see
:mod:`gaitlog.firmware_sim.transport` to put it on a pty or a TCP port).

The EEPROM contents persist as a memory-image file (``PROTOCOL.md`` section 6, :mod:`gaitlog.protocol.image`)
between runs, as the real EEPROMs keep their data with the power off: ``Logger(image_path=p)`` restores
``p`` if it exists and every :meth:`record` saves it back (atomically); :meth:`Logger.from_image` restores
any image. The emulated logger has the step memory of section 2.3 (a third 24LC1025), so it writes
``image_version`` 2; an image of version 1 (no step memory) restores with an empty step memory. A new
logger has header version 3 (section 2.7: the run's page-commit journal in a 96-page ring of the step
EEPROM, ``step_capacity`` 2662); ``Logger(journal_ring=False)`` builds one of header version 2 (the journal
in the data EEPROM, ``step_capacity`` 3276), and a restored image keeps its own header version.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gaitlog.firmware_sim.adc import DEFAULT_SAMPLING_RATE_HZ, Adc
from gaitlog.firmware_sim.eeprom import DataEeprom, Eeprom24LC1025, EepromBank
from gaitlog.firmware_sim.errors import DeviceError
from gaitlog.firmware_sim.firmware import FIRMWARE_VERSION, Firmware, as_run
from gaitlog.firmware_sim.ring_buffer import MemoryFullError, RingBuffer
from gaitlog.firmware_sim.sensor import SensorModel
from gaitlog.firmware_sim.step_store import StepStore
from gaitlog.firmware_sim.world.base import Motion, MotionSource
from gaitlog.firmware_sim.world.resampling import resample_g
from gaitlog.atomic_write import atomic_write_bytes
from gaitlog.protocol.channel_map import ChannelMap
from gaitlog.protocol.commit_journal import torn_step_records
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.header import CAPACITY_SAMPLES, DeviceHeader, HeaderFlag
from gaitlog.protocol.header_slots import SLOT_ADDRESSES, SLOT_BYTES, committed_header
from gaitlog.protocol.image import build_image, parse_image
from gaitlog.protocol.journal_ring import (
    ENTRY_BYTES_V3,
    HEADER_VERSION_RING,
    RING_FIRST_BYTE,
    RING_PAGE_BYTES,
    RING_PAGES,
    STEP_CAPACITY_RECORDS_V3,
    last_ring_commit,
)
from gaitlog.protocol.packing import FLAG_MARK, FLAG_SESSION_START, unpack_words
from gaitlog.protocol.steps import STEP_CAPACITY_RECORDS, StepConfig

__all__ = ["Logger", "RecordResult", "PowerCut"]


@dataclass(frozen=True)
class PowerCut:
    """Where a power loss falls in a :meth:`Logger.record` (section 2.4 of ``PROTOCOL.md``).

    Attributes
    ----------
    at_sample
        Samples the timer took before the power failed (0 … all of them; all of them and ``during_stop``: the
        cut falls in STOP, after the run's last sample).
    at_byte
        None: between two samples. Otherwise inside the write in flight, if the last sample completed a page
        (or, with ``during_stop``, the partial page STOP flushes): see :meth:`RingBuffer.power_cut`.
    during_stop
        The cut falls in STOP's page flush (before its header commit).
    """

    at_sample: int
    at_byte: int | None = None
    during_stop: bool = False


@dataclass(frozen=True, eq=False)
class RecordResult:
    """What one :meth:`Logger.record` stored, with the truth beside it.

    Attributes
    ----------
    codes
        ``(n, 3)`` ``uint16`` ADC codes as stored (read back from the EEPROM), oldest first.
    flags
        ``(n,)`` ``uint8`` P32 flags (``FLAG_SESSION_START``, ``FLAG_MARK``).
    sample_times_s
        ``(n,)`` time of each stored sample on the motion's clock, s.
    sample_numbers
        ``(n,)`` absolute sample numbers (0 = first sample after ERASE).
    n_taken
        Samples the timer took during the motion (``n_taken - n`` were not stored: memory full, or
        overwritten within this same run).
    truth
        The motion's truth plus ``sensor`` (its parameters), ``adc`` (its settings), ``motion_sampling_rate_hz``.
    """

    codes: np.ndarray
    flags: np.ndarray
    sample_times_s: np.ndarray
    sample_numbers: np.ndarray
    n_taken: int
    truth: Mapping[str, Any] = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        """Number of stored samples."""
        return int(self.codes.shape[0])


class Logger:
    """The emulated gait logger.

    Parameters
    ----------
    sensor
        Sensor model; default :meth:`SensorModel.draw` seeded with ``device_id`` (one physical unit).
    adc
        ADC settings; default ``Adc(sampling_rate_hz=sampling_rate_hz)``.
    sampling_rate_hz
        Sample-timer rate when ``adc`` is not given (None: :data:`gaitlog.firmware_sim.adc.DEFAULT_SAMPLING_RATE_HZ`);
        with ``adc``, None or the ADC's own rate.
    device_id
        Serial number written to the header.
    overwrite
        Default START mode of :meth:`record`: overwrite the oldest samples when full (True) or stop.
    image_path
        Memory-image file: restored at construction if it exists, saved after every :meth:`record`.
    live_acc_g
        The world of a *served* device: when a host STARTs logging over the UART, :meth:`advance` takes
        samples in real time of a device lying still with this specific force (default: ``+z`` up).
    step_config
        Step configuration of the header (section 2.2); default off. A restored image brings its own. One
        that cannot be stored raises :class:`~gaitlog.protocol.errors.ProtocolError` (naming the field).
    journal_ring
        True: header version 3 (``PROTOCOL.md`` section 2.7), the run's page-commit journal in a 96-page ring
        of the step EEPROM, one entry every second page; the step ring holds 2662 records. False: header
        version 2, the journal in the data EEPROM's journal area (which wears out in about a month of 8 h
        logging); the step ring holds 3276 records. None (default): header version 3 for a new device, and
        a restored image's own version (2 or 3) for a device built from one.

    Examples
    --------
    >>> from gaitlog.firmware_sim.world.poses import CalibrationPoses
    >>> logger = Logger(device_id=3)
    >>> res = logger.record(CalibrationPoses(n_poses=4, hold_s=3.0, move_s=1.0))
    >>> res.n_samples, logger.header.samples_written, int(res.flags[0])
    (750, 750, 1)
    """

    def __init__(
        self,
        *,
        sensor: SensorModel | None = None,
        adc: Adc | None = None,
        sampling_rate_hz: float | None = None,
        device_id: int = 1,
        overwrite: bool = False,
        image_path: str | Path | None = None,
        live_acc_g: tuple[float, float, float] = (0.0, 0.0, 1.0),
        step_config: StepConfig | None = None,
        channel_map: ChannelMap | None = None,
        journal_ring: bool | None = None,
    ) -> None:
        if adc is not None and sampling_rate_hz is not None and abs(adc.sampling_rate_hz - sampling_rate_hz) > 1e-9:
            raise DeviceError(f"sampling_rate_hz {sampling_rate_hz} disagrees with adc.sampling_rate_hz {adc.sampling_rate_hz}")
        if adc is None:
            adc = Adc(sampling_rate_hz=DEFAULT_SAMPLING_RATE_HZ if sampling_rate_hz is None else sampling_rate_hz)
        self.sensor = sensor if sensor is not None else SensorModel.draw(seed=int(device_id))
        self.adc = adc
        self.overwrite = overwrite
        self.image_path = Path(image_path) if image_path is not None else None
        self.live_acc_g = np.asarray(live_acc_g, dtype=np.float64).reshape(1, 3)
        self._live_t0: float | None = None  # clock time of a START received over the UART
        self._live_taken = 0
        header = DeviceHeader(
            firmware_version=FIRMWARE_VERSION,
            device_id=int(device_id),
            sampling_rate_millihz=int(round(self.adc.sampling_rate_hz * 1000)),
            adc_bits=int(self.adc.adc_bits),
            capacity_samples=CAPACITY_SAMPLES,
            adc_vref_mv=int(round((self.adc.vref_high_v - self.adc.vref_low_v) * 1000)),
            step_capacity=STEP_CAPACITY_RECORDS if journal_ring is False else STEP_CAPACITY_RECORDS_V3,
            step_config=as_run(step_config),
        )
        self._journal_ring = journal_ring  # None: a restored image keeps its own header version
        if journal_ring is not False:  # header version 3: the run's journal in the step EEPROM (PROTOCOL.md 2.7)
            header.header_version = HEADER_VERSION_RING
        if channel_map is not None:  # an instrument's channels (PROTOCOL.md 2.6) instead of the three axes
            header.axes, header.calibration = channel_map.n_channels, channel_map
        header.validate()  # a step configuration that cannot be stored fails here, not at the first commit
        self.bank = EepromBank()
        self.step_eeprom = Eeprom24LC1025()
        self.data_eeprom = DataEeprom()
        self.ring = RingBuffer(self.bank, self.data_eeprom, header, slot_eeprom=self.step_eeprom)
        self.steps = StepStore(self.step_eeprom, header)
        self.firmware = Firmware(self.ring, steps=self.steps)
        if self.image_path is not None and self.image_path.exists():
            self._restore(self.image_path)
        else:
            self.ring.commit()

    # ------------------------------------------------------------------ state
    @property
    def header(self) -> DeviceHeader:
        """The current device header (RAM state; equal to the data EEPROM when not logging)."""
        return self.ring.header

    @property
    def memory(self) -> bytes:
        """The whole sample memory (262,144 bytes), as the EEPROMs hold it."""
        return self.bank.contents().tobytes()

    @property
    def step_memory(self) -> bytes:
        """The whole step memory (the ring of ``step_capacity`` records: 2662, 53,240 bytes, on header version
        3; 3276, 65,520 bytes, on version 2), as the step EEPROM holds it."""
        return self.steps.contents()

    @property
    def step_config(self) -> StepConfig:
        """The step configuration of the header (section 2.2)."""
        assert self.header.step_config is not None
        return self.header.step_config

    @step_config.setter
    def step_config(self, config: StepConfig) -> None:
        """Set it as SET_STEP_CONFIG does (committed to the data EEPROM; :class:`DeviceError` while logging)."""
        self.firmware.set_step_config(config)

    def advance(self, now_s: float) -> int:
        """Real-time sampling of a served device: take the samples the 50 Hz timer has fired since the
        last call (the transport calls this on every tick); returns how many were stored.

        Runs only while a run started over the UART is in progress; the device lies still at
        ``live_acc_g`` (sensor errors and noise included, the noise drawn at the sample instants).
        """
        if not self.ring.logging:
            self._live_t0 = None
            return 0
        if self._live_t0 is None:
            self._live_t0, self._live_taken = now_s, 0
        due = int(np.floor((now_s - self._live_t0) * self.adc.actual_rate_hz)) + 1 - self._live_taken
        if due <= 0:
            return 0
        times = self._live_t0 + (self._live_taken + np.arange(due)) / self.adc.actual_rate_hz
        self._live_taken += due
        volts = np.repeat(self.sensor.static_v(self.live_acc_g), due, axis=0)
        volts += (self.sensor.noise_g(times) + self.sensor.flicker_g(times)) * self.sensor.gain_v_per_g
        return self.firmware.log_samples(self.adc.convert(self.sensor.drifted_v(volts, times - self._live_t0)))

    def erase(self) -> None:
        """ERASE: forget every stored sample and per-step record (calibration and step configuration kept)."""
        self.firmware.erase()

    # ------------------------------------------------------------------ persistence
    def save_image(self, path: str | Path | None = None) -> Path:
        """Write the memory image (``.glimg``, version 2: sample and step memory) atomically to ``path``
        (default ``image_path``)."""
        target = Path(path) if path is not None else self.image_path
        if target is None:
            raise DeviceError("no image path: pass one to save_image() or Logger(image_path=...)")
        atomic_write_bytes(target, build_image(self.header.to_bytes(), self.memory, step_memory=self.step_memory))
        return target

    @classmethod
    def from_image(cls, path: str | Path, **kwargs: Any) -> Logger:
        """A logger whose EEPROMs hold the contents of the memory image ``path``.

        The device id, rate and ADC bits come from the image's header; ``kwargs`` go to :class:`Logger`
        (``sensor``, ``adc``, ``overwrite``, ``image_path``). Blocks the image marks missing read 0xFF
        (a warning says how many). An image without step memory (version 1) gives an empty step memory.
        """
        p = Path(path)
        header, memory, step_memory, notes = _read_image(p)
        kwargs.setdefault("device_id", header.device_id)
        if "adc" not in kwargs:
            kwargs["adc"] = Adc(sampling_rate_hz=header.sampling_rate_hz, adc_bits=header.adc_bits)
        logger = cls(**kwargs)
        logger._load(header, memory, step_memory, source=str(p))
        for note in notes:
            warnings.warn(f"{p}: {note}", stacklevel=2)
        return logger

    def _restore(self, path: Path) -> None:
        header, memory, step_memory, notes = _read_image(path)
        self._load(header, memory, step_memory, source=str(path))
        for note in notes:
            warnings.warn(f"{path}: {note}", stacklevel=3)

    def _load(self, header: DeviceHeader, memory: np.ndarray, step_memory: np.ndarray | None = None, *,
              source: str) -> None:
        """Put an image's header and memories on this device. A header without step memory (an image of
        version 1) gets this device's empty step ring (``steps_written`` 0, the EEPROM erased)."""
        if header.capacity_samples != self.header.capacity_samples or memory.size != self.bank.size_bytes:
            raise DeviceError(
                f"{source}: image holds {header.capacity_samples} samples / {memory.size} bytes; this device "
                f"{self.header.capacity_samples} / {self.bank.size_bytes}"
            )
        cap = self.header.step_capacity
        if self._journal_ring is None:  # the device is the image's: its header version's step ring
            cap = STEP_CAPACITY_RECORDS_V3 if header.header_version == HEADER_VERSION_RING else STEP_CAPACITY_RECORDS
        if header.step_capacity == 0:
            header.step_capacity = cap  # steps_written is 0: an empty ring
            step_memory = None
        elif header.step_capacity != cap:
            hint = ""
            if header.header_version == HEADER_VERSION_RING:
                hint = " (a header-version-3 image: Logger(journal_ring=True) or the default)"
            elif header.step_capacity == STEP_CAPACITY_RECORDS:
                hint = " (a header-version-2 image: Logger(journal_ring=False) or the default)"
            raise DeviceError(f"{source}: image holds {header.step_capacity} step records; this device "
                              f"{cap}" + hint)
        elif step_memory is None and header.steps_written:
            raise DeviceError(f"{source}: the header has {header.n_steps_stored} stored step records but no step "
                              "memory was given")
        self.bank.load(memory)
        self.steps = StepStore(self.step_eeprom, header)
        self.steps.load(np.full(self.steps.size_bytes, 0xFF, np.uint8) if step_memory is None else step_memory)
        self._boot(header)

    def _boot(self, header: DeviceHeader) -> None:
        """Power-up: a header left with ``LOGGING`` set (the power failed during a run) is recovered from its
        journal (``DeviceHeader.recovered``, with the step records written after the last commit counted as
        torn); a version-1 header has no journal and its run's samples are dropped (LOGGING cleared). The
        header is committed and the firmware starts afresh (RAM state lost)."""
        if header.logging:
            ring = None
            if int(header.header_version) == HEADER_VERSION_RING:
                entries = [self.step_eeprom.sequential_read(RING_FIRST_BYTE + RING_PAGE_BYTES * k, ENTRY_BYTES_V3)
                           for k in range(RING_PAGES)]
                ring = last_ring_commit(entries, recording_number=header.recording_number,
                                        recording_nonce=header.recording_nonce)
            header = header.recovered(ring)
            if header.power_lost:
                header.torn_step_records = torn_step_records(header, self.step_eeprom.memory)
            header.flags &= ~int(HeaderFlag.LOGGING)
        self.ring = RingBuffer(self.bank, self.data_eeprom, header, slot_eeprom=self.step_eeprom)
        self.steps = StepStore(self.step_eeprom, header)
        self.ring.commit()
        self.firmware = Firmware(self.ring, steps=self.steps, nonce_source=self.firmware.nonce_source)

    def power_up(self) -> None:
        """Power the device up from what its non-volatile memories hold (the data EEPROM's header, the sample
        and step EEPROMs): the RAM is lost, an interrupted run is recovered to its last committed page.

        The header is the committed one (section 2.5): the data EEPROM's, or the newest header slot's when a
        power loss cut a header commit after its slot was written (:func:`gaitlog.protocol.header_slots.committed_header`).

        Raises
        ------
        DeviceError
            Neither the data EEPROM nor a header slot holds a valid header.
        """
        slots = [self.step_eeprom.sequential_read(a, SLOT_BYTES) for a in SLOT_ADDRESSES]
        committed = committed_header(self.data_eeprom.read(), slots)
        try:
            header = DeviceHeader.from_bytes(committed.header, source="data EEPROM")
        except ProtocolError as err:
            raise DeviceError(f"power-up: {err}") from err
        self._boot(header)

    # ------------------------------------------------------------------ recording
    def record(
        self,
        motion: Motion | MotionSource,
        *,
        start_time_s: int = 0,
        overwrite: bool | None = None,
        power_cut: PowerCut | None = None,
    ) -> RecordResult:
        """Run one logging session over ``motion``: START, sample, STOP.

        With ``power_cut`` the power fails during the run (:class:`PowerCut`): the samples before the cut
        are logged, the write in flight is torn as the cut says, the RAM is lost and the device powers up again
        (:meth:`power_up`). The result then holds the samples *taken* (``codes``, ``flags`` as packed,
        ``sample_numbers``), not what survived: the decoder's business.

        Parameters
        ----------
        motion
            A :class:`Motion`, or a :class:`MotionSource` (rendered at the sensor's internal rate). A
            motion at another rate is resampled to the internal rate first (anti-aliased).
        start_time_s
            Unix time of the first sample, written to the header by START.
        overwrite
            START mode; default the logger's ``overwrite``.

        Raises
        ------
        DeviceError
            Already logging, or the memory is full in stop-when-full mode (ERASE first).
        """
        if not isinstance(motion, Motion):
            if not isinstance(motion, MotionSource):
                raise DeviceError(f"record() needs a Motion or a MotionSource, got {type(motion).__name__}")
            motion = motion.render(self.sensor.internal_rate_hz)
        acc, rate = motion.acc_g, motion.sampling_rate_hz
        if abs(rate - self.sensor.internal_rate_hz) > 1e-9 * rate:
            acc, rate = resample_g(acc, rate, self.sensor.internal_rate_hz)
        volts = self.sensor.respond(acc, rate, noise=False)
        t_last = motion.t0_s + (acc.shape[0] - 1) / rate
        times = self.adc.sample_times_s(motion.t0_s, t_last)
        held = self.adc.hold(volts, rate, motion.t0_s, times)
        # the sensor noise (an Ornstein-Uhlenbeck process after the RC filter) drawn at the sample instants
        held += self.sensor.noise_g(times) * self.sensor.gain_v_per_g
        if self.sensor.flicker_corner_hz:
            held += self.sensor.flicker_g(times) * self.sensor.gain_v_per_g
        codes = self.adc.convert(self.sensor.drifted_v(held, times - motion.t0_s))
        marks = np.zeros(times.size, dtype=bool)
        if motion.marker_times_s.size:
            k = np.searchsorted(times, motion.marker_times_s, side="left")
            marks[k[k < times.size]] = True
        mode = self.overwrite if overwrite is None else overwrite
        try:
            self.firmware.start_logging(start_time_s=int(start_time_s), overwrite=bool(mode))
        except MemoryFullError as err:
            raise DeviceError(f"cannot record: {err}") from err
        first_number = self.header.samples_written
        if power_cut is not None:
            return self._record_cut(power_cut, codes, marks, times, first_number, motion, rate)
        n_stored = self.firmware.log_samples(codes, marks)
        self.firmware.stop_logging()
        cap = self.header.capacity_samples
        keep = min(n_stored, cap)
        numbers = first_number + np.arange(n_stored - keep, n_stored, dtype=np.int64)
        slots = numbers % cap
        mem = np.frombuffer(self.bank.read(0, self.bank.size_bytes), dtype="<u4")
        stored_codes, stored_flags = unpack_words(mem[slots])
        truth = dict(motion.truth)
        truth.update(sensor=self.sensor.truth(), adc=_adc_truth(self.adc), motion_sampling_rate_hz=rate)
        if self.image_path is not None:
            self.save_image()
        return RecordResult(
            codes=stored_codes,
            flags=stored_flags,
            sample_times_s=times[n_stored - keep:n_stored],
            sample_numbers=numbers,
            n_taken=int(times.size),
            truth=truth,
        )


    def record_frames(self, frame_codes: np.ndarray, *, start_time_s: int = 0) -> int:
        """One logging session of an instrument (a header with a channel map, ``PROTOCOL.md`` 2.5): START,
        the timer's frames, STOP; returns the frames stored (the run stops when the memory is full).

        Parameters
        ----------
        frame_codes
            ``(m, n_channels)`` codes of each tick, in the channel map's order (from
            :meth:`gaitlog.firmware_sim.channel_sensors.ChannelSensors.sample`).
        """
        cmap = self.header.calibration
        if not isinstance(cmap, ChannelMap):
            raise DeviceError("record_frames() needs a logger with a channel map (Logger(channel_map=...))")
        words = cmap.words(np.asarray(frame_codes))
        room = self.header.capacity_samples - self.header.samples_written
        words = words[: room - room % cmap.frame_words]  # whole frames only, as the firmware stores a tick
        try:
            self.firmware.start_logging(start_time_s=int(start_time_s), overwrite=False)
        except MemoryFullError as err:
            raise DeviceError(f"cannot record: {err}") from err
        stored = self.firmware.log_samples(words)
        self.firmware.stop_logging()
        if self.image_path is not None:
            self.save_image()
        return stored // cmap.frame_words

    def _record_cut(self, cut: PowerCut, codes: np.ndarray, marks: np.ndarray, times: np.ndarray, first_number: int,
                    motion: Motion, rate: float) -> RecordResult:
        """The rest of :meth:`record` when the power fails at ``cut``."""
        n = int(cut.at_sample)
        if not 0 <= n <= codes.shape[0] or (cut.during_stop and n != codes.shape[0]):
            raise DeviceError(f"power cut at sample {n}: the run takes {codes.shape[0]} samples"
                              + (" (during_stop needs all of them)" if cut.during_stop else ""))
        self.firmware.log_samples(codes[:n], marks[:n])
        if cut.during_stop and self.ring.logging:
            self.firmware._end_steps()
            self.ring._flush()
        if self.ring.logging:
            self.ring.power_cut(cut.at_byte)
            self.power_up()
        else:  # the run had already ended (a full memory in stop-when-full mode): a cut changes nothing
            self.firmware.stop_logging()
        flags = np.zeros(n, dtype=np.uint8)
        flags[marks[:n]] |= FLAG_MARK
        if n:
            flags[0] |= FLAG_SESSION_START
        truth = dict(motion.truth)
        truth.update(sensor=self.sensor.truth(), adc=_adc_truth(self.adc), motion_sampling_rate_hz=rate, power_cut=cut)
        if self.image_path is not None:
            self.save_image()
        return RecordResult(codes=np.asarray(codes[:n], np.uint16), flags=flags, sample_times_s=times[:n],
                            sample_numbers=first_number + np.arange(n, dtype=np.int64), n_taken=n, truth=truth)


def _adc_truth(adc: Adc) -> dict[str, Any]:
    return {
        "adc_bits": adc.adc_bits, "sampling_rate_hz": adc.sampling_rate_hz, "actual_sampling_rate_hz": adc.actual_rate_hz,
        "vref_low_v": adc.vref_low_v, "vref_high_v": adc.vref_high_v, "gain": adc.gain, "ref_v": adc.ref_v,
        "timer_error_ppm": adc.timer_error_ppm, **adc.effects(), "channel_delays_s": adc.channel_delays_s(3).tolist(),
        "settling_fraction": adc.settling_fraction,
    }


def _read_image(path: Path) -> tuple[DeviceHeader, np.ndarray, np.ndarray, list[str]]:
    try:
        data = path.read_bytes()
    except OSError as err:
        raise DeviceError(f"{path}: cannot read memory image: {err.strerror or err}") from err
    try:
        contents = parse_image(data, source=str(path))
    except ProtocolError as err:
        raise DeviceError(f"{err}") from err
    memory = np.array(contents.memory, dtype=np.uint8, copy=True)
    step_memory = np.array(contents.step_memory, dtype=np.uint8, copy=True)
    notes = list(contents.notes)
    bad = np.flatnonzero(~np.asarray(contents.block_ok, dtype=bool))
    if bad.size:
        memory[~contents.byte_ok()] = 0xFF
        step_memory[~contents.step_byte_ok()] = 0xFF
        notes.append(f"{bad.size} memory block(s) missing in the image; they read 0xFF on the device")
    return contents.header, memory, step_memory, notes
