"""``gaitlog decode``: memory image, raw XMODEM dump or wire capture -> samples (and step records) as CSV and NPZ."""

from __future__ import annotations

import argparse

from gaitlog.host.commands._options import (
    add_force_option,
    add_max_missing_option,
    add_verbosity_options,
    check_outputs,
    input_stem,
    out_path,
    verbosity,
)
from gaitlog.host.errors import HostError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

HELP = ("decode a memory image, raw dump or wire capture to PREFIX.csv and PREFIX.npz (gaps reported), and the "
        "device's step records to PREFIX.steps.csv (checked against the host's replay)")
#: Shown under "examples:" by ``gaitlog decode --help``.
EXAMPLES = (
    "gaitlog decode walk.glimg --out walk",
    "gaitlog decode walk.glimg --out decoded/ --calibration cal.json",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT", help="memory image (.glimg), raw dump (rx output) or wire capture")
    parser.add_argument("--out", required=True, metavar="PREFIX",
                        help="writes PREFIX.csv and PREFIX.npz, and PREFIX.steps.csv when the input holds step records")
    parser.add_argument("--calibration", metavar="CAL.json",
                        help="convert counts to g with this calibration (default: the header's "
                             "calibration slot, else the nominal map)")
    parser.add_argument("--no-verify", action="store_true",
                        help="write the step records as the device stored them, without replaying the device's "
                             "algorithm to check them (default: a difference from the replay is an error and "
                             "nothing is written)")
    parser.add_argument("--accept-unverified", action="store_true",
                        help="keep the samples of a raw dump without its check trailer (cut off, or older "
                             "firmware) as the file holds them, marked UNVERIFIED in a warning and the notes "
                             "(default: nothing verifies them, so they are reported missing)")
    add_max_missing_option(parser)
    add_force_option(parser)
    add_verbosity_options(parser)

#: Gaps and lost record runs listed one per line without ``-v``.
_LISTED_WITHOUT_VERBOSE = 10


def replay_error(recording, check) -> str:
    """The message of a step-record mismatch: the first differing record and field."""
    end_sample, what = check.mismatches[0]
    numbers = recording.step_record_numbers[recording.step_records["end_sample"] == end_sample]
    which = f"record {int(numbers[0])} (foot-flat at sample {end_sample})" if numbers.size else \
        f"the step ending at sample {end_sample}"
    return (f"{recording.source}: the device's step records differ from the host's replay of its algorithm: "
            f"{check.n_compared - check.n_identical} of {check.n_compared} differ, the first is {which}: {what}. "
            "The device and this host do not compute the same steps (firmware, header or record damage, or the "
            "step configuration changed after these steps were logged: the header keeps only the last one); "
            "nothing written (--no-verify writes them anyway)")


def _run_instrument(args: argparse.Namespace, rec, csv_path) -> int:
    """An instrument's recording (a channel map in the header, PROTOCOL.md 2.6): PREFIX.csv in the recording
    format of ``gaitlog kinematics`` (:mod:`gaitlog.host.kinematics.sensor_csv`), one column per channel."""
    from gaitlog.host.kinematics.logger_instruments import decoded_columns
    from gaitlog.host.kinematics.sensor_csv import write_sensor_csv

    if args.calibration:
        raise HostError(f"--calibration: {args.input} holds an instrument's channels (a channel map), each with its "
                        "own full scale: no accelerometer calibration applies")
    t, columns = decoded_columns(rec)
    cmap = rec.header.calibration
    comment = (f"decoded from {args.input}: device {rec.header.device_id}, {cmap.n_channels} channels "
               f"({', '.join(f'AN{c.analog_input} {c.column} +-{c.full_scale:g}' for c in cmap.channels)}), "
               f"{rec.sampling_rate_hz:g} Hz, {rec.adc_bits}-bit ADC")
    write_sensor_csv(csv_path, t, columns, comment=comment)
    if verbosity(args) >= 0:
        print(f"{args.input}: {t.size} frames of {cmap.n_channels} channels at {rec.sampling_rate_hz:g} Hz "
              f"({t.size / rec.sampling_rate_hz:.2f} s); the recording format of `gaitlog kinematics` (its platform "
              "JSON is the one `gaitlog record` wrote beside the image)")
        print(f"wrote {csv_path}")
    return 0


def run(args: argparse.Namespace) -> int:
    from gaitlog.host.files.decode import decode_file, output_paths, save_decoded

    args.out = out_path(args.out, input_stem(args.input))
    paths = output_paths(args.out)
    check_outputs({f"--out ({p.name})": p for p in paths.values()},
                  {"INPUT": args.input, "--calibration": args.calibration}, force=args.force)
    from gaitlog.protocol.channel_map import ChannelMap

    rec = decode_file(args.input, accept_unverified=args.accept_unverified)
    if isinstance(rec.header.calibration, ChannelMap):
        return _run_instrument(args, rec, paths["csv"])
    calibration = None
    note = rec.default_calibration()[1]
    if args.calibration:
        from gaitlog.host.accelerometer.calibration import AccCalibration

        calibration = AccCalibration.load(args.calibration)
        if getattr(calibration, "input_unit", "counts") != "counts":
            raise HostError(f"{args.calibration}: this calibration takes {calibration.input_unit}; decoding "
                            "needs a calibration of ADC counts (input_unit 'counts')")
        note = f"g from the calibration {args.calibration}"
    check = None
    if not args.no_verify:  # the replay's modules (the on-line algorithm's kernel) only when it runs
        from gaitlog.host.files.replay import verify_step_records

        check = verify_step_records(rec)
    if check is not None and check.differs:
        raise HostError(replay_error(rec, check))
    from gaitlog.host.files.losses import SampleLosses

    losses = SampleLosses.from_recording(rec)
    over = losses.above(args.max_missing)
    if over:  # the outputs are written all the same; the NPZ's notes and both validity columns mark it
        rec.notes.append(losses.limit_text(args.max_missing))
    written = save_decoded(rec, args.out, calibration)
    if verbosity(args) >= 0:
        print(f"{args.input}: {rec.summary(None if verbosity(args) > 0 else _LISTED_WITHOUT_VERBOSE)}")
        print(note)
        if check is not None:
            print(check.summary())
        elif rec.n_step_records:
            print(f"{rec.n_step_records} device step records written unchecked (--no-verify: not replayed)")
        if rec.n_step_records == 0:
            print(f"no step records in {args.input}: {output_paths(args.out)['steps_csv']} not written")
        print("wrote " + ", ".join(str(p) for p in written))
    if over:
        raise HostError(f"{losses.limit_text(args.max_missing)}; wrote {', '.join(str(p) for p in written)} all the "
                        "same (their valid column marks the missing samples)")
    return 0
