"""``gaitlog decode --no-verify`` does no replay: a fresh process decoding an image with step records loads none of
the modules of the host's replay (the on-line algorithm, its kernels), and writes what the verifying decode writes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.world.subject import Subject
from gaitlog.firmware_sim.world.walk_plan import WalkPlan
from gaitlog.firmware_sim.world.walking import Walking
from gaitlog.host.cli import main
from gaitlog.protocol.steps import StepConfig

#: Run in a fresh interpreter: the decode, then the names of the loaded modules as JSON on stdout.
_DECODE = """
import json, sys
from gaitlog.host.cli import main
code = main(sys.argv[1:])
print(json.dumps({"exit": code, "modules": sorted(sys.modules)}))
"""

#: Modules only the replay needs.
REPLAY_MODULES = ("gaitlog.host.files.replay", "gaitlog.firmware_sim.algorithms.online",
                  "gaitlog.firmware_sim.algorithms.kernel", "gaitlog.firmware_sim.algorithms.aot_kernel")


def test_no_verify_loads_no_replay_and_writes_the_same_files(tmp_path: Path) -> None:
    plan = WalkPlan(corridor_length_m=20.0, speeds=("preferred",), initial_stand_s=3.0, final_stand_s=2.0,
                    lap_marks_m=(0.0, 20.0, 40.0))
    walk = Walking(subject=Subject.from_height(1.75), walk_plan=plan, seed=1)
    logger = Logger(device_id=9, step_config=StepConfig(step_format=4, leg_length_m=0.9275, foot_length_m=0.1943))
    logger.record(walk)
    image = tmp_path / "walk.glimg"
    logger.save_image(image)
    runs = {}
    for name, extra in (("verified", []), ("unverified", ["--no-verify"])):
        done = subprocess.run([sys.executable, "-c", _DECODE, "decode", str(image), "--out", str(tmp_path / name),
                               "-q", *extra], capture_output=True, text=True, check=True)
        runs[name] = json.loads(done.stdout.splitlines()[-1])
        assert runs[name]["exit"] == 0
    assert set(REPLAY_MODULES) <= set(runs["verified"]["modules"])        # the check can fail: verify loads them
    assert not set(REPLAY_MODULES) & set(runs["unverified"]["modules"])
    assert "numpy.ma" not in runs["unverified"]["modules"]
    for suffix in (".csv", ".steps.csv"):
        assert (tmp_path / f"verified{suffix}").read_bytes() == (tmp_path / f"unverified{suffix}").read_bytes()
    assert main(["decode", str(image), "--out", str(tmp_path / "again"), "-q", "--no-verify"]) == 0
