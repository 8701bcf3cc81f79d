"""Report: M3 without K against the IPOL trials, its pendulum term and its double-support term.

Runs the offline chain of ``gaitlog evaluate ipol`` on an IPOL folder (the leave-one-subject-out event constants)
and :class:`gaitlog.host.studies.ipol_m3.M3Decomposition` on it: per subject and per age / height / step-length
group, the terms against what the 20 m implies, and each double-support rule's median, IQR and median |log ratio|
with 95 % subject-bootstrap intervals and its gain over the foot length (the shipped rule, measured in the same
run). The tables of ``docs/topics/accuracy.md`` ("M3 without K, by term") are this output on the dev subjects.
About a minute of CPU.

    python benchmarks/ipol_m3.py [../shared/data/ipol-lowerback-dev]
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.host.studies.ipol_evaluation import IpolEvaluation  # noqa: E402
from gaitlog.host.studies.ipol_m3 import M3Decomposition  # noqa: E402

DEFAULT_FOLDER = ROOT.parent / "shared" / "data" / "ipol-lowerback-dev"


def main(argv: list[str]) -> int:
    folder = Path(argv[0]) if argv else DEFAULT_FOLDER
    if not folder.is_dir():
        print(f"ipol_m3: {folder}: no such folder", file=sys.stderr)
        return 2
    evaluation = IpolEvaluation(arithmetic=("offline",)).run(folder)
    print(M3Decomposition().run(evaluation).format())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
