"""``gaitlog simulate``: simulated walkers written as recordings that other tools read.

``gaitlog simulate --ipol-out DIR --subjects N``: N simulated subjects (``random_subjects(N, seed, population)``;
``--population people`` by default, the walker tuned to real lower-back walking) each walk the
IPOL lower-back trial (stand, 10 m, U-turn, 10 m back, stop) ``--trials`` times; every walk is written to
``DIR/<subject>-<trial>_lb.txt`` (100 Hz, ``PacketCounter`` and ``Acc_X..Z`` in m/s^2, x up, y left, z
backward) and ``DIR/<subject>-<trial>.json`` (trial and U-turn boundaries, foot events from the world's truth,
height in cm). The folder reads like the real IPOL ``GaitData`` (``gaitlog evaluate ipol DIR``,
``../shared/tools/walking_stats.py``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gaitlog.host.commands._options import SEED, add_verbosity_options, check_output_folder, printer, whole
from gaitlog.host.commands._progress import progress_bar
from gaitlog.host.errors import HostError

# Imports inside functions are only of numpy and of modules that load numpy, scipy, numba, dask or matplotlib:
# `gaitlog --help` imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

HELP = "write simulated walks as recordings (IPOL lower-back layout) for other tools"
#: Shown under "examples:" by ``gaitlog simulate --help``.
EXAMPLES = (
    "gaitlog simulate --subjects 2 --ipol-out sim-trials",
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--ipol-out", metavar="DIR", required=True,
                        help="folder to write <subject>-<trial>_lb.txt and .json into (created if missing)")
    parser.add_argument("--subjects", type=whole(minimum=1, maximum=10_000), default=20, help="simulated subjects (default 20)")
    parser.add_argument("--trials", type=whole(minimum=1, maximum=100), default=1, help="trials (separate walks) per subject (default 1)")
    parser.add_argument("--seed", type=SEED, default=0, help="seed of the simulated subjects (default 0)")
    parser.add_argument("--population", choices=("people", "v1"), default="people",
                        help="people: trunk motion and gait timing tuned to real lower-back walking (default); "
                             "v1: the population the other simulated studies use")
    parser.add_argument("--workers", type=whole(minimum=1, maximum=256), default=1, help="processes to use (default 1)")
    parser.add_argument("--force", action="store_true", help="write into a folder that already holds trials")
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    from gaitlog.host.studies.simulation import export_ipol

    out = Path(args.ipol_out)
    check_output_folder("--ipol-out", out)
    if out.is_dir() and not args.force and any(out.glob("*_lb.txt")):
        raise HostError(f"--ipol-out {out}: already holds trials (give --force to overwrite them)")
    with progress_bar(args, args.subjects * args.trials, "trial") as tick:
        names = export_ipol(out, args.subjects, seed=args.seed, trials=args.trials, population=args.population,
                            workers=args.workers, progress=tick)
    printer(args)(f"{len(names)} simulated trial(s) of {args.subjects} subject(s) ('{args.population}' population, "
                  f"seed {args.seed}) written to {out} in the IPOL layout (100 Hz, m/s^2; foot events and "
                  "boundaries from the world's truth)")
    return 0
