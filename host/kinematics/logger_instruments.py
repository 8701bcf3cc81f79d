"""Morris' and Hall's instruments on the emulated logger: channel maps, the budget check, recording, decoding.

The logger (PIC16F877, 8 analog inputs, 10-bit ADC, P32 words in the 24LC1025s) records an instrument through
the same path as its own accelerometer: sensor (:class:`gaitlog.firmware_sim.channel_sensors.ChannelSensors`) ->
conditioning and ADC -> firmware ring buffer -> memory image / dump, with the header's channel map
(``PROTOCOL.md`` 2.6) saying which input holds which sensor. The instruments:

``morris``
    Five (as published) or six single-axis accelerometers on the shank platform
    (:func:`gaitlog.host.kinematics.simulated_instruments.simulate_morris`), ``acc1``.. on AN0.., at 100 Hz (his 10 ms).
``hall``
    Two triaxial angular-rate sensors (links A and B, ``A_x``.. on AN0-AN5) of Hall's two-link test
    (:func:`~gaitlog.host.kinematics.simulated_instruments.simulate_hall`). Hall sampled at 10 kHz: the PIC cannot
    (:func:`check_fits`). His pre-test posture came from the links' gravity; with those six channels the
    instrument needs 12 inputs, so on the logger the posture is the platform's ``initial_joint_deg`` (a
    goniometer reading before the test: here the simulation's true initial angles).

:func:`check_fits` asks the budget model (:func:`gaitlog.firmware_sim.budget.instrument_fit`: ADC time, cycles, RAM,
EEPROM bandwidth) and refuses with the reason and the closest configuration that fits. :func:`decoded_columns`
turns a decoded dump (:class:`gaitlog.host.files.recording.Recording` of a channel-mapped header) into the recording CSV
columns of :mod:`gaitlog.host.kinematics.sensor_csv`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gaitlog.firmware_sim.budget import CONFIGURATIONS, LoggerConfig, instrument_fit
from gaitlog.firmware_sim.channel_sensors import ACCELEROMETER, RATE_SENSOR, ChannelSensors
from gaitlog.firmware_sim.device import Logger
from gaitlog.host.errors import HostError
from gaitlog.host.files.recording import Recording
from gaitlog.host.kinematics.platform_description import HallPlatform, MorrisPlatform
from gaitlog.host.kinematics.sensor_csv import SensorRecording, split_unit
from gaitlog.host.kinematics.simulated_instruments import simulate_hall, simulate_morris
from gaitlog.protocol.channel_map import (
    ANGULAR_RATE,
    MAX_CHANNELS,
    SPECIFIC_FORCE,
    Channel,
    ChannelMap,
)

__all__ = ["DEFAULT_RATE_HZ", "INSTRUMENTS", "LoggedInstrument", "check_fits", "decoded_columns", "instrument_config",
           "record_instrument", "sensor_recording"]

#: Instruments the logger records (``gaitlog record --motion``).
INSTRUMENTS = ("morris", "hall")
#: The papers' sampling rates: Morris 10 ms, Hall 10 kHz.
DEFAULT_RATE_HZ = {"morris": 100.0, "hall": 10_000.0}
#: Fine grid of the simulated world, as a multiple of the logger's rate (the sensors' filters run on it).
_FINE_FACTOR = 10


def _hall_channels(gravity: bool) -> int:
    return 12 if gravity else 6


def instrument_config(instrument: str, n_channels: int, sampling_rate_hz: float) -> LoggerConfig:
    """The budget's configuration of ``instrument`` with ``n_channels`` at ``sampling_rate_hz``."""
    base = CONFIGURATIONS["hall" if instrument == "hall" else ("morris-6" if n_channels == 6 else "morris-5")]
    return replace(base, sampling_rate_hz=float(sampling_rate_hz), adc_channels=int(n_channels))


def check_fits(instrument: str, n_channels: int, sampling_rate_hz: float) -> None:
    """Refuse (:class:`HostError`) a configuration the PIC16F877 cannot record: more channels than its 8 analog
    inputs, or what the budget model finds short (ADC, cycles, RAM, EEPROM); the message gives the reason and
    the closest configuration that fits (fewer channels: Hall's rate sensors without the gravity channels; the
    fastest rate that fits, from :func:`gaitlog.firmware_sim.budget.instrument_fit`)."""
    what = f"{instrument} with {n_channels} channels at {sampling_rate_hz:g} Hz"
    reasons, fits_channels = [], n_channels
    if n_channels > MAX_CHANNELS:
        reasons.append(f"{n_channels} channels, the PIC16F877 has {MAX_CHANNELS} analog inputs (AN0-AN7)")
        fits_channels = _hall_channels(False) if instrument == "hall" else MAX_CHANNELS
    short, fastest = instrument_fit(instrument_config(instrument, fits_channels, sampling_rate_hz))
    reasons += short
    if not reasons:
        return
    rate = min(float(sampling_rate_hz), math.floor(fastest))
    closest = f"{fits_channels} channels at {rate:g} Hz (--logger-rate {rate:g})"
    if fits_channels != n_channels:
        closest += (": the two triaxial rate sensors without the gravity channels, the pre-test posture from "
                    "the platform's initial_joint_deg (drop --gravity-channels)" if instrument == "hall" else "")
    raise HostError(f"the PIC16F877 logger cannot record {what}: " + "; ".join(reasons)
                    + f". The closest configuration that fits: {closest}")


@dataclass(frozen=True, eq=False)
class LoggedInstrument:
    """An instrument recorded by the emulated logger: the logger (its memory), the platform description, the
    truth at the logger's sample instants (columns as :mod:`gaitlog.host.kinematics.simulated_instruments` writes
    them), the sensors' parameters, the frames stored and taken (fewer stored: the memory filled up) and a
    comment."""

    logger: Logger
    platform: MorrisPlatform | HallPlatform
    t_s: np.ndarray
    truth: dict[str, np.ndarray]
    sensors: ChannelSensors
    n_frames: int
    n_taken: int
    comment: str


def record_instrument(instrument: str, *, sampling_rate_hz: float | None = None, n_accelerometers: int = 5,
                      duration_s: float = 2.56, gravity_channels: bool = False, seed: int = 0, noise: bool = True,
                      start_time_s: int = 0, sensors: ChannelSensors | None = None) -> LoggedInstrument:
    """Simulate ``instrument`` (``"morris"`` or ``"hall"``) and record it with the emulated logger.

    Refused (:func:`check_fits`) where the PIC16F877 cannot do it. ``noise=False``: sensors without noise
    (the ADC still quantises). ``sensors``: these parts instead of parts drawn from the specs with ``seed``
    (e.g. :meth:`ChannelSensors.ideal` for the error left without any sensor error).
    """
    if instrument not in INSTRUMENTS:
        raise HostError(f"unknown instrument {instrument!r} (expected {' or '.join(INSTRUMENTS)})")
    rate = DEFAULT_RATE_HZ[instrument] if sampling_rate_hz is None else float(sampling_rate_hz)
    n_channels = n_accelerometers if instrument == "morris" else _hall_channels(gravity_channels)
    check_fits(instrument, n_channels, rate)
    fine = _FINE_FACTOR * rate
    if instrument == "morris":
        sim = simulate_morris(n_accelerometers=n_accelerometers, snr_db=None, duration_s=duration_s,
                              sampling_rate_hz=fine, seed=seed)
        names = list(sim.platform.sensors)
        specs = [ACCELEROMETER] * len(names)
        platform: MorrisPlatform | HallPlatform = sim.platform
    else:
        sim = simulate_hall(sampling_rate_hz=fine, noise_rad_s=0.0, gravity_noise_g=0.0, seed=seed,
                            rate_offsets=False)
        p = sim.platform
        names = [*p.link_a.rate_sensors, *p.link_b.rate_sensors]
        specs = [RATE_SENSOR] * 6
        initial = np.degrees([sim.truth[f"{n}_rad"][0] for n in ("phi", "theta", "psi")])
        platform = HallPlatform(replace(p.link_a, gravity_sensors=None), replace(p.link_b, gravity_sensors=None),
                                p.sequence, p.side, p.pretest_s, np.round(initial, 3))
    units = {split_unit(c)[0]: c for c in sim.columns}
    values = np.column_stack([sim.columns[units[n]] for n in names])
    quantity = SPECIFIC_FORCE if instrument == "morris" else ANGULAR_RATE
    cmap = ChannelMap(tuple(Channel(i, quantity, n, s.range) for i, (n, s) in enumerate(zip(names, specs))))
    if sensors is None:
        sensors = ChannelSensors.draw(specs, seed=seed, noise=noise)
    elif sensors.n_channels != len(names) or not np.allclose(sensors.range, [s.range for s in specs]):
        raise HostError(f"{instrument}: sensors of ranges {sensors.range.tolist()} for {len(names)} channels of "
                        f"ranges {[s.range for s in specs]}")
    logger = Logger(sampling_rate_hz=rate, channel_map=cmap, device_id=1)
    adc = sensors.adc(rate, int(logger.header.adc_bits))
    times, codes = sensors.sample(values, fine, float(sim.t_s[0]), adc)
    n_frames = logger.record_frames(codes, start_time_s=start_time_s)
    idx = np.rint((times[:n_frames] - sim.t_s[0]) * fine).astype(np.int64)
    truth = {k: v[idx] for k, v in sim.truth.items()}
    kind = "five accelerometers (rate about axis 3 assumed zero)" if n_channels == 5 else f"{n_channels} channels"
    comment = (f"{instrument} on the emulated PIC16F877 logger: {kind} at {rate:g} Hz, sensors seed {seed}"
               + ("" if noise else ", no sensor noise") + f"; {sim.comment}")
    return LoggedInstrument(logger, platform, times[:n_frames] - sim.t_s[0], truth, sensors, n_frames, times.size,
                            comment)


def decoded_columns(recording: Recording) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The recording CSV's time (s from the first stored frame) and columns ``<name>_<unit>`` of a decoded dump
    whose header holds a channel map.

    Raises
    ------
    HostError
        No channel map, a partial frame, or frames not received intact: the recording format has no gaps
        (the decoder never invents samples), so the message names the missing frames.
    """
    cmap = recording.header.calibration
    if not isinstance(cmap, ChannelMap):
        raise HostError(f"{recording.source}: no channel map in the header: a three-axis logger recording, not an "
                        "instrument's (PROTOCOL.md 2.6)")
    w = cmap.frame_words
    n_words = recording.codes.shape[0]
    if n_words % w or recording.sample_numbers.size and recording.sample_numbers[0] % w:
        raise HostError(f"{recording.source}: {n_words} stored words from word {int(recording.sample_numbers[0])} "
                        f"are not whole frames of {w} words")
    ok = recording.valid.reshape(-1, w).all(axis=1)
    if not ok.all():
        bad = np.flatnonzero(~ok)
        raise HostError(f"{recording.source}: {bad.size} of {ok.size} frames not received intact (first: frame "
                        f"{int(bad[0])}, {recording.gaps[0].reason if recording.gaps else 'damaged'}); the "
                        "recording CSV has no gaps: dump again")
    codes = cmap.frames(recording.codes)
    values = cmap.values(codes, recording.adc_bits)
    t = np.arange(codes.shape[0]) / recording.sampling_rate_hz
    return t, {c.column: values[:, j] for j, c in enumerate(cmap.channels)}



def sensor_recording(recording: Recording) -> SensorRecording:
    """A decoded instrument dump as the kinematics' recording (what ``gaitlog decode`` writes as CSV and
    :func:`gaitlog.host.kinematics.sensor_csv.read_sensor_csv` reads back), in memory."""
    t, columns = decoded_columns(recording)
    channels, quantities = {}, {}
    for name, values in columns.items():
        sensor, quantity, factor = split_unit(name)
        channels[sensor], quantities[sensor] = values * factor, quantity
    return SensorRecording(t, channels, quantities, recording.sampling_rate_hz, recording.source or "<dump>")
