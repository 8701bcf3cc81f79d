"""Benchmark: whole-process ``gaitlog decode`` of a full memory image, with and without ``--no-verify``.

Run ``python benchmarks/bench_decode.py [--repeat N]`` (about a minute: the image is recorded first).

Input: one full memory (65,536 samples, 1310.72 s at 50 Hz) of the simulated walker of ``benchmarks/_walker.py``
recorded by the emulated logger with the on-line step algorithm (its step records in the image's step memory),
saved as a ``.glimg`` image.

Measured, in fresh processes side by side (interleaved, best of ``--repeat``, wall and CPU seconds; the bytecode
cache and the compiled kernel written by one untimed round first):

- ``gaitlog decode IMAGE --out X`` (the step records checked against the host's replay of the device's algorithm);
- ``gaitlog decode --no-verify IMAGE --out X`` (no replay).

Target: the ``--no-verify`` process takes at most half the wall time of the verifying one (ratio <= 0.5). The
floor, in the same run: ``python -c "import numpy"``. Then, in this process, where a ``--no-verify`` decode's time
goes (best of ``--repeat`` per stage), and the replay's share of the verifying decode. Exits 1 if the target is
missed.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from _timing import best_of, process_seconds
from _walker import step_config, walker_motion

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gaitlog.firmware_sim.device import Logger  # noqa: E402

RATIO_TARGET = 0.5
REPEAT = 7


def make_image(folder: Path) -> Path:
    """The walker's full memory with its step records: ``folder/walk.glimg``."""
    motion, subject = walker_motion()
    logger = Logger(step_config=step_config(subject))
    logger.record(motion, start_time_s=1_700_000_000)
    logger.save_image(folder / "walk.glimg")
    return folder / "walk.glimg"


def process(cmd: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall and CPU seconds of one fresh process in the repository (it must exit 0)."""
    return process_seconds(cmd, env, ROOT)


def measure(image: Path, folder: Path, repeat: int) -> dict[str, tuple[float, float]]:
    """Best wall and best CPU seconds of each command, the commands interleaved round by round."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}  # as installed: bytecode cached
    gaitlog = [sys.executable, "-m", "gaitlog", "decode", str(image), "-q", "--force"]
    commands = {"verify": gaitlog + ["--out", str(folder / "v")],
                "no_verify": gaitlog + ["--out", str(folder / "n"), "--no-verify"],
                "import_numpy": [sys.executable, "-c", "import numpy"]}
    for cmd in commands.values():       # untimed: bytecode written, the compiled kernel built or loaded once
        process(cmd, env)
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name in commands}
    for _ in range(repeat):
        for name, cmd in commands.items():
            runs[name].append(process(cmd, env))
    for suffix in (".csv", ".steps.csv"):  # the same outputs, verified or not
        if (folder / f"v{suffix}").read_bytes() != (folder / f"n{suffix}").read_bytes():
            raise SystemExit(f"decode and decode --no-verify wrote different {suffix} files")
    return {name: (min(r[0] for r in rs), min(r[1] for r in rs)) for name, rs in runs.items()}


def stages(image: Path, folder: Path, repeat: int) -> dict[str, float]:
    """In this process (modules already imported), the best seconds of each stage of a decode."""
    from gaitlog.host.files.decode import decode_file
    from gaitlog.host.files.replay import verify_step_records

    rec = decode_file(image)
    cal = rec.default_calibration()[0]
    return {
        "decode the image": best_of(lambda: decode_file(image), repeat),
        "write the NPZ": best_of(lambda: rec.save_npz(folder / "s.npz"), repeat),
        "write the sample CSV": best_of(lambda: rec.to_csv(folder / "s.csv", cal), repeat),
        "write the step CSV": best_of(lambda: rec.to_steps_csv(folder / "s.steps.csv"), repeat),
        "replay the step records (verify only)": best_of(lambda: verify_step_records(rec), repeat),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=REPEAT, help=f"rounds, best taken (default {REPEAT})")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        image = make_image(folder)
        t = measure(image, folder, args.repeat)
        parts = stages(image, folder, args.repeat)
    load = os.getloadavg()[0]
    ratio = t["no_verify"][0] / t["verify"][0]
    print(f"whole-process gaitlog decode of a full 65,536-sample image ({os.cpu_count()} CPUs, load {load:.1f}, "
          f"best of {args.repeat}; wall s, CPU s in brackets)")
    print(f"  decode (step records replayed):  {t['verify'][0]:.3f} ({t['verify'][1]:.3f})")
    print(f"  decode --no-verify:              {t['no_verify'][0]:.3f} ({t['no_verify'][1]:.3f})")
    print(f"  ratio --no-verify / verify:      {ratio:.3f} wall, {t['no_verify'][1] / t['verify'][1]:.3f} CPU "
          f"(target <= {RATIO_TARGET})")
    print(f"  floor: python -c 'import numpy'  {t['import_numpy'][0]:.3f} ({t['import_numpy'][1]:.3f})")
    print("in-process stages (imports done), best s:")
    for name, seconds in parts.items():
        print(f"  {name:40s} {seconds:.4f}")
    ok = ratio <= RATIO_TARGET
    print("target met" if ok else "TARGET MISSED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
