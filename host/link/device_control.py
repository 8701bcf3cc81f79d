"""What ``gaitlog device`` does on a live logger, as answers a command prints: the identity and the status
(a JSON-ready dict and its lines), and start, stop, erase and set-calibration, each checked against the device's
state and said in one line. The connection itself is :class:`gaitlog.host.link.logger_link.LoggerLink`'s."""

from __future__ import annotations

import datetime
from typing import Any

from gaitlog.host.accelerometer.calibration import AccCalibration
from gaitlog.host.errors import HostError
from gaitlog.host.files.info_report import InfoReport, header_dict, header_lines
from gaitlog.host.link.logger_link import LoggerLink, device_identity
from gaitlog.protocol.errors import ProtocolError
from gaitlog.protocol.frames import DeviceState
from gaitlog.protocol.header import CALIBRATION_SIZE, CalibrationSlot

__all__ = ["STATE_WORDS", "DeviceControl", "LoggerLink", "calibration_slot", "device_info"]

#: STATUS ``state`` in the user's words.
STATE_WORDS = {0: "idle", 1: "logging", 2: "stopped because the memory is full"}


def calibration_slot(path: str | None) -> bytes:
    """The 64-byte calibration slot from the ``gaitlog calibrate`` file ``path``, or the empty slot (the nominal
    map) for None; checked before any connection is made.

    Raises
    ------
    HostError
        The file cannot be read, or its calibration does not fit the slot.
    """
    if path is None:
        return bytes(CALIBRATION_SIZE)
    try:
        cal = AccCalibration.load(path)
    except OSError as err:
        raise HostError(f"cannot read the calibration file {path}: {err.strerror or err}") from err
    try:
        return cal.to_header_calibration().to_bytes()
    except (ProtocolError, ValueError) as err:
        raise HostError(f"{path}: does not fit the logger's calibration slot: {err}") from err


class DeviceControl:
    """The actions of ``gaitlog device`` on the logger behind ``link`` (reached at ``port``, named in messages)."""

    def __init__(self, link: LoggerLink, port: str) -> None:
        self.link, self.port = link, port
        self.info = link.identify()

    # ---------------------------------------------------------------------------------------------- reports
    def identity(self) -> dict[str, Any]:
        """The IDENTIFY answer in the host's vocabulary (``sampling_rate_hz``, firmware as ``"major.minor"``)."""
        return device_identity(self.info)

    def identity_lines(self) -> list[str]:
        ident = self.identity()
        return [f"logger {ident['device_id']} on {self.port}",
                f"firmware {ident['firmware_version']}, protocol v{ident['protocol_version']}",
                (f"{ident['adc_bits']}-bit ADC at {ident['sampling_rate_hz']:g} Hz, room for "
                 f"{ident['capacity_samples']} samples ({ident['memory_bytes']} bytes)")]

    def status(self) -> dict[str, Any]:
        """STATUS plus what the header says about stored step records and the calibration slot."""
        status = self.link.status()
        _, header = self.link.read_header()
        return {"device_id": header.device_id, "state": STATE_WORDS.get(status["state"], str(status["state"])),
                "logging": status["state"] == DeviceState.LOGGING, "overwrite": header.overwrite,
                "samples_written": status["samples_written"], "samples_stored": header.n_stored,
                "capacity_samples": header.capacity_samples, "write_index": status["write_index"],
                "start_time_utc": header.start_time.isoformat() if header.start_time_s else None,
                "step_records_stored": header.n_steps_stored, "step_algorithm_on": bool(header.step_config.enabled),
                "calibration_set": bool(header.calibration.valid)}

    def status_lines(self, st: dict[str, Any]) -> list[str]:
        full = 100.0 * st["samples_stored"] / st["capacity_samples"]
        mode = "overwriting the oldest samples when full" if st["overwrite"] else "stopping when full"
        return [f"logger {st['device_id']} on {self.port}: {st['state']}"
                + (f" ({mode})" if st["logging"] else ""),
                (f"{st['samples_stored']} samples stored of {st['capacity_samples']} ({full:.1f} % full), "
                 f"{st['samples_written']} written since the last erase"),
                f"{st['step_records_stored']} step records stored; on-line step algorithm "
                + ("on" if st["step_algorithm_on"] else "off"),
                "calibration slot: " + ("set" if st["calibration_set"] else "empty (the nominal map is used)")]

    # ---------------------------------------------------------------------------------------------- actions
    def start(self, start_time_s: int | None, *, overwrite: bool) -> str:
        """START (refused when it is logging already); what happened."""
        before = self.link.status()
        if before["state"] == DeviceState.LOGGING:
            raise HostError(f"logger {self.info['device_id']} on {self.port} is already logging "
                            f"({before['samples_written']} samples written): nothing changed")
        self.link.start(start_time_s, overwrite=overwrite)
        after = self.status()
        when = datetime.datetime.fromisoformat(after["start_time_utc"]) if after["start_time_utc"] else None
        mode = "overwrites the oldest samples when full" if overwrite else "stops when the memory is full"
        return (f"logger {self.info['device_id']} is logging since {when.isoformat() if when else '?'} "
                f"({after['samples_stored']} samples already stored; it {mode})")

    def stop(self) -> str:
        """STOP; what happened."""
        was = self.link.status()["state"]
        self.link.stop()
        st = self.status()
        if was != DeviceState.LOGGING:
            return f"logger {self.info['device_id']} was not logging ({st['state']}); {st['samples_stored']} samples stored"
        return (f"logger {self.info['device_id']} stopped logging: {st['samples_stored']} samples and "
                f"{st['step_records_stored']} step records stored")

    def erasable(self) -> str:
        """What ERASE would erase (refused while logging), in words."""
        st = self.status()
        if st["logging"]:
            raise HostError(f"logger {self.info['device_id']} on {self.port} is logging: stop it first "
                            "(`gaitlog device stop`); nothing erased")
        return (f"{st['samples_stored']} stored samples and {st['step_records_stored']} step records of logger "
                f"{self.info['device_id']} on {self.port}")

    def set_calibration(self, slot: bytes, source: str | None) -> str:
        """SET_CALIBRATION with ``slot`` (:func:`calibration_slot` of ``source``), checked in the header read
        back; what happened."""
        info = self.info
        cal = CalibrationSlot.from_bytes(slot, info["adc_bits"])
        self.link.set_calibration(slot)
        _, header = self.link.read_header()
        stored = header.calibration
        if stored.valid != cal.valid or (cal.valid and stored.to_bytes() != slot):
            raise HostError(f"logger {info['device_id']} acknowledged the calibration but its header does not hold it")
        if cal.valid:
            offset = ", ".join(f"{v:.3f}" for v in stored.offset_counts)
            return (f"calibration of {source} stored in logger {info['device_id']}: offset {offset} "
                    "counts (fixed point: offset to 1/65536 count, matrix to 2^-30 g/count)")
        return (f"calibration slot of logger {info['device_id']} cleared: it uses the nominal map "
                f"(±2 g over the {info['adc_bits']}-bit ADC span)")


def device_info(port: str, *, baud: int = 115200, timeout_s: float = 1.0) -> InfoReport:
    """``gaitlog info --port PORT``: the live device's identity, status and header."""
    with LoggerLink(port, baud=baud, timeout_s=timeout_s) as link:
        info = link.identify()
        status = link.status()
        _, header = link.read_header()
    state = STATE_WORDS.get(status["state"], str(status["state"]))
    data = {"port": port, "baud": baud, "state": state, "device": device_identity(info),
            "header": header_dict(header)}
    lines = [f"port             {port} at {baud} baud",
             (f"state            {state}, {status['samples_written']} samples written, write index "
              f"{status['write_index']}"),
             f"memory           {info['memory_bytes']} bytes",
             *header_lines(header)]
    return InfoReport(data, lines)
