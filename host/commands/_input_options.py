"""The input flags of every command that reads a recording (not a command: the underscore keeps it out of
``--help``): one spelling and one meaning each, read by :func:`gaitlog.host.files.inputs.read_acceleration`.

``--rate HZ`` is always the rate of the input (a CSV's; it must agree with a file that states its own);
the emulated logger's own rate is ``--logger-rate`` wherever a command has one.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from gaitlog.host.commands._options import SAMPLING_RATE_HZ, whole

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

if TYPE_CHECKING:
    from gaitlog.host.files.acceleration import AccelerationInput

#: What every input argument accepts, for the help texts.
INPUT_HELP = ("memory image, raw dump or wire capture, decoded .npz, IPOL trial (_lb.txt, .json or a one-trial "
              "folder) or CSV")


def add_input_options(parser: argparse.ArgumentParser) -> None:
    """``--rate``, ``--columns``, ``--units``, ``--skip-rows`` and ``--calibration``."""
    grp = parser.add_argument_group("input (CSV layout; logger, .npz and IPOL files state their own)")
    grp.add_argument("--rate", type=SAMPLING_RATE_HZ, metavar="HZ",
                     help="sampling rate of the input, Hz (default: the file's own, or a CSV's time_s column)")
    grp.add_argument("--columns", metavar="X,Y,Z",
                     help="the three acceleration columns of a CSV, comma-separated header names or 0-based "
                          "indices (default: x_g/acc_x/ax/x... by name, or the only three numeric columns)")
    grp.add_argument("--units", choices=("g", "m/s2", "counts"),
                     help="unit of the CSV columns (default: from the names x_g / x_counts / x_m_s2, else ~1 g "
                          "or ~9.8 m/s^2 from the data)")
    grp.add_argument("--skip-rows", type=whole(minimum=0, maximum=10**9), default=0, metavar="N",
                     help="lines to skip at the top of a CSV before looking for the header and data (default 0)")
    grp.add_argument("--calibration", metavar="CAL.json",
                     help="accelerometer calibration (from 'gaitlog calibrate') applied to the readings")


def read_input(args: argparse.Namespace, path: str | Path, *, arrays: bool = True) -> AccelerationInput:
    """Read ``path`` with the flags of :func:`add_input_options` (``arrays``: see
    :func:`gaitlog.host.files.inputs.read_acceleration`). A decoded ``.npz`` is read without loading the
    logger-file decoders (:func:`gaitlog.host.files.acceleration.read_npz`: the same result and errors)."""
    from gaitlog.host.files.acceleration import is_npz, read_npz

    flags = dict(sampling_rate_hz=args.rate, columns=args.columns, units=args.units, calibration=args.calibration,
                 skip_rows=args.skip_rows, arrays=arrays)
    if is_npz(path):
        return read_npz(path, **flags)
    from gaitlog.host.files.inputs import read_acceleration

    return read_acceleration(path, **flags)


def given_input_flags(args: argparse.Namespace) -> list[str]:
    """The flags of :func:`add_input_options` given on the command line (for "cannot honour" errors)."""
    given = [f"--{n.replace('_', '-')}" for n in ("rate", "columns", "units", "calibration")
             if getattr(args, n, None) is not None]
    return given + (["--skip-rows"] if getattr(args, "skip_rows", 0) else [])
