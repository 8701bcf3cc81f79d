"""Report: why the shipped chain's calibrated M4 spreads more than the recipe's, one ingredient swapped at a time.

Runs the offline chain of ``gaitlog evaluate ipol`` on an IPOL folder (the leave-one-subject-out event constants, K
from each subject's first trial, every step of the other trials summed) and scores the chain, the recipe
(``gaitlog.host.gait.recipe``) and every mix of the two with one ingredient swapped
(:func:`gaitlog.host.studies.ipol_decomposition.decompose`): median and IQR of the 20 m ratio of M2, M4 and a pure
step counter, with 95 % subject-bootstrap intervals, and each mix's gain over the chain. The table of
``docs/topics/accuracy.md`` ("Why M4 spreads more than the recipe's") is this output on the dev subjects.
About 30 s of CPU.

    python benchmarks/ipol_decomposition.py [../shared/data/ipol-lowerback-dev]
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.host.studies.ipol_decomposition import decompose_folder  # noqa: E402

DEFAULT_FOLDER = ROOT.parent / "shared" / "data" / "ipol-lowerback-dev"


def main(argv: list[str]) -> int:
    folder = Path(argv[0]) if argv else DEFAULT_FOLDER
    if not folder.is_dir():
        print(f"ipol_decomposition: {folder}: no such folder", file=sys.stderr)
        return 2
    print(decompose_folder(folder).format())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
