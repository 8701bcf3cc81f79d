"""``gaitlog demo``: the whole data path on defaults, as a sequence of stages.

record (calibration poses with the emulated logger) -> serve (the image as a live device on a pty) ->
dump (over the pty, as from a real logger) -> decode (CSV + NPZ) -> calibrate (9-parameter fit on the dumped
poses, CAL.json) -> summary (samples, gaps, duration and, per pose, the mean g against the truth and the
error of |a| before and after calibration) -> walk (a simulated subject through the paper's protocol,
recorded by the same emulated device with the pose calibration in its header and its on-line step algorithm
running) -> estimate (the host's offline float chain, K per subject, every 20 m section's ratio, CSV and the
Figs 5-6 box plots: :mod:`gaitlog.host.studies.evaluation`) -> device (K sent to the device, the walk recorded again: the
device's own per-step records, checked against the host's replay bit for bit, beside the offline chain)
-> split (offline vs on-line float vs on-line fixed on the same codes, one K: :mod:`gaitlog.host.studies.compare`)
-> plot (the device's walk decoded, K saved, a 30 s overview drawn: :mod:`gaitlog.host.studies.overview`) -> next (what
to open, and commands to try on the files written).

The files stay in ``./gaitlog-demo/`` (or ``--out DIR``). The folder is marked as the demo's by
:data:`MARKER` (written before anything else, with the list of files at the end), so a second run replaces
its own files; a non-empty folder without the marker is refused unless ``--force``.

The stages are :data:`gaitlog.host.studies.demo.STAGES` (each reads and adds entries of the shared ``context``
dict and returns lines to print); this command checks the folder, runs them in order and prints their lines.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from gaitlog.host.commands._options import SEED, add_verbosity_options, check_output_folder, printer, verbosity, whole
from gaitlog.host.errors import HostError

# The stages (gaitlog.host.studies.demo: numpy, scipy, numba, matplotlib) are imported inside run: `gaitlog --help`
# imports every command module and must stay light (tests/host/commands/test_cli_startup.py).

HELP = ("run the whole path on defaults: record poses -> serve on a pty -> dump -> decode -> calibrate -> summary "
        "-> walk a simulated subject -> M1-M5 per 20 m and box plots -> the device's own step records -> the "
        "error split -> an overview plot; the files stay in ./gaitlog-demo/")
#: Shown under "examples:" by ``gaitlog demo --help``.
EXAMPLES = (
    "gaitlog demo --out demo-out",
    "gaitlog demo --out demo-out --force -q",
)

#: Default output folder (relative to the working directory).
DEFAULT_OUT = "gaitlog-demo"
#: The file that marks a folder as a demo's output (JSON: what wrote it and the files it holds).
MARKER = "gaitlog-demo.json"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", metavar="DIR", default=DEFAULT_OUT,
                        help=f"keep the files in DIR (default ./{DEFAULT_OUT}; a previous demo's files there are "
                        "replaced)")
    parser.add_argument("--force", action="store_true",
                        help="write into --out even if it holds other files (files of the same names are replaced)")
    parser.add_argument("--poses", type=whole(minimum=1, maximum=1000), default=24, help="number of calibration poses (default 24)")
    parser.add_argument("--seed", type=SEED, default=0, help="seed of the sensor and the poses (default 0)")
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    from gaitlog.atomic_write import atomic_write_text
    from gaitlog.host.studies import demo

    say, detail = printer(args), printer(args, 1)
    out = Path(args.out)
    check_output_folder("--out", out)
    if out.is_dir() and any(out.iterdir()) and not (out / MARKER).is_file() and not args.force:
        raise HostError(f"--out {out}: not empty and not a previous 'gaitlog demo' output (no {MARKER}); give "
                        "another --out, or --force to write into it anyway")
    out.mkdir(parents=True, exist_ok=True)
    marker = out / MARKER

    def mark(files: list[str], complete: bool) -> None:
        atomic_write_text(marker, json.dumps({"written_by": "gaitlog demo", "complete": complete,
                                              "files": files}, indent=1) + "\n")

    foreign = set() if marker.is_file() else {p.name for p in out.iterdir()}  # a --force'd folder's own files
    mark([], False)
    ctx: dict[str, Any] = {"args": args, "dir": out, "progress": verbosity(args) >= 0, "cleanup": []}
    try:
        for stage in demo.STAGES:
            lines = stage.run(ctx)
            say(f"[{stage.name}] " + (lines[0] if lines else ""), flush=True)
            for line in lines[1:]:
                say(f"    {line}", flush=True)
        for path in sorted(out.iterdir()) if args.out else ():
            detail(f"kept: {path}")
    finally:
        for fn in reversed(ctx["cleanup"]):
            fn()
    mark(sorted(p.name for p in out.iterdir() if p.name != MARKER and p.name not in foreign), True)
    return 0
