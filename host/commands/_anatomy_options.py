"""``--leg-length``, ``--foot-length`` and ``--height`` of the gait commands, the lengths they choose, and the K
of ``--k-file`` (not a command: the underscore keeps it out of ``--help``)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from gaitlog.host.commands._options import POSITIVE_M

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

if TYPE_CHECKING:
    from gaitlog.host.files.acceleration import AccelerationInput
    from gaitlog.host.gait.anthropometry import AnatomyChoice
    from gaitlog.host.gait.k_calibration import KFit

#: The attribute names of the anatomy flags.
ANATOMY_FLAGS = ("leg_length", "foot_length", "height")


def _anatomy_length(what: str):
    """An argparse ``type`` for a ``what`` ("height", "leg length", "foot length") in metres, in the plausible
    range of :data:`gaitlog.host.gait.anthropometry.ANATOMY_RANGES_M` (imported when the flag is given, so that
    ``--help`` stays fast): a value outside is a usage error (exit 2), e.g. a height in cm or feet."""

    def parse(text: str) -> float:
        value = POSITIVE_M(text)
        from gaitlog.host.gait.anthropometry import ANATOMY_RANGES_M

        low, high = ANATOMY_RANGES_M[what]
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"must be a {what} of {low:g} to {high:g} m (give it in metres), got "
                                             f"{text!r}")
        return value

    parse.__name__ = what
    return parse


#: ``--height``, ``--leg-length``, ``--foot-length`` (every command that takes them).
HEIGHT_M, LEG_LENGTH_M, FOOT_LENGTH_M = (_anatomy_length(w) for w in ("height", "leg length", "foot length"))


def add_anatomy_options(parser: argparse.ArgumentParser) -> None:
    """--leg-length / --foot-length / --height."""
    parser.add_argument("--leg-length", type=LEG_LENGTH_M, metavar="M",
                        help="leg length (greater trochanter to floor), m")
    parser.add_argument("--foot-length", type=FOOT_LENGTH_M, metavar="M",
                        help="foot length heel to first metatarsal head (M3's S2), m")
    parser.add_argument("--height", type=HEIGHT_M, metavar="M",
                        help="body height, m: leg = 0.530 H, foot = 0.111 H when not given (Winter; ANSUR); "
                             "default: the K file's lengths, else an IPOL trial's height, else those of the logger's step "
                             "configuration, else a 1.70 m adult")


def given_anatomy_flags(args: argparse.Namespace) -> list[str]:
    """The anatomy flags given on the command line, spelled as flags."""
    return [f"--{n.replace('_', '-')}" for n in ANATOMY_FLAGS if getattr(args, n, None) is not None]


def k_fit_from_args(args: argparse.Namespace) -> KFit | None:
    """The step constants K of ``--k-file`` (:meth:`gaitlog.host.gait.k_calibration.KFit.load`), None without it
    (or with an empty path, as :func:`lengths_from_args` takes it)."""
    if not args.k_file:
        return None
    from gaitlog.host.gait.k_calibration import KFit

    return KFit.load(args.k_file)


def lengths_from_args(args: argparse.Namespace, *, k: KFit | None = None, k_source: str | None = None,
                      data: AccelerationInput | None = None) -> AnatomyChoice:
    """Leg and foot length by :func:`gaitlog.host.gait.anthropometry.choose_lengths` from the flags, the K file ``k``,
    the height of an IPOL trial read into ``data`` and the step configuration of a logger recording in ``data``."""
    from gaitlog.host.gait.anthropometry import choose_lengths

    trial = data.ipol_trial if data is not None else None
    config = data.recording.step_config if data is not None and data.recording is not None else None
    logger = (config.leg_length_m, config.foot_length_m) if config is not None and config.step_format else None
    return choose_lengths(leg_length_m=args.leg_length, foot_length_m=args.foot_length, height_m=args.height,
                          k_lengths_m=(k.leg_length_m, k.foot_length_m) if k is not None else None,
                          k_source=k_source or getattr(args, "k_file", None) or "the K file",
                          trial_height_m=trial.height_m if trial is not None else None,
                          trial_source=_trial_json(trial) if trial is not None else "",
                          logger_lengths_m=logger,
                          logger_source=f"{data.recording.source}'s step configuration" if logger else "")


def _trial_json(trial) -> str:
    """Where an IPOL trial's height came from: its JSON file (or its name)."""
    return str(trial.path.with_name(f"{trial.name}.json")) if trial.path is not None else f"IPOL trial {trial.name}"
