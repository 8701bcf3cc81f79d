"""`gaitlog ranges`: the table and --json say the same, a logger image and IPOL trials are read, bad input exits
1 or 2 with one line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gaitlog.firmware_sim.device import Logger
from gaitlog.firmware_sim.world.base import Motion
from gaitlog.host.cli import main
from gaitlog.protocol.steps import StepConfig
from gaitlog.units import STANDARD_GRAVITY_M_S2
from tests.conftest import DATA_DIR

IPOL = DATA_DIR / "ipol-lowerback-dev" / "GaitData"


@pytest.fixture
def image(tmp_path):
    """20 s of a sinusoidal centre of mass (h = 4 cm, 2 steps/s) on z, logged."""
    t = np.arange(1000) / 50.0
    acc = np.zeros((t.size, 3))
    acc[:, 2] = 1 - 0.02 * (4 * np.pi) ** 2 * np.cos(4 * np.pi * t) / STANDARD_GRAVITY_M_S2
    logger = Logger(device_id=7)
    logger.record(Motion(acc_g=acc, sampling_rate_hz=50.0), start_time_s=1_700_000_000)
    path = tmp_path / "rec.glimg"
    logger.save_image(path)
    return path


def test_json_gives_the_table(image, capsys):
    assert main(["ranges", str(image)]) == 0
    table = capsys.readouterr().out.splitlines()
    assert main(["ranges", str(image), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["n_steps"] > 20 and doc["sources"] == [str(image)] and doc["margin_bits"] == 1
    assert len(doc["rows"]) == len([ln for ln in table if ln.split(" ")[0].endswith("_Q")])
    for row in doc["rows"]:
        line = next(ln for ln in table if ln.startswith(f"{row['format_name']} ") and f" {row['variable']} " in ln)
        cells = line[len(row["format_name"]):].replace(row["variable"], "", 1).split()
        assert cells[0] == row["how"] and cells[1] == row["format"]
        if row["min_raw"] is None:
            assert cells[2:4] == ["-", "-"] and row["proposed"] is None
            continue
        assert [int(cells[2]), int(cells[3])] == [row["min_raw"], row["max_raw"]]
        assert float(cells[4]) == pytest.approx(row["min_real"], rel=1e-4, abs=1e-9)
        assert cells[-3:] == [str(row["saturations"]), row["proposed"], str(row["proposed_bits"])]
    assert doc["headline"] in table


def test_margin_bits_widen_the_proposals(image, capsys):
    docs = []
    for b in ("0", "4"):
        assert main(["ranges", str(image), "--margin-bits", b, "--json"]) == 0
        docs.append({r["variable"]: r for r in json.loads(capsys.readouterr().out)["rows"]})
    assert docs[1]["a_v"]["proposed_bits"] == docs[0]["a_v"]["proposed_bits"] + 4


@pytest.mark.skipif(not IPOL.is_dir(), reason=f"the IPOL trials are not at {IPOL} (set GAITLOG_DATA_DIR)")
def test_ipol_trials_are_replayed(capsys):
    trial = sorted(IPOL.glob("*_lb.txt"))[0]
    assert main(["ranges", str(trial), str(trial.with_name(trial.name.replace("_lb.txt", ".json"))), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["sources"] == [str(trial)] * 2 and doc["n_steps"] > 0


@pytest.mark.parametrize(("argv", "code", "says"), [
    (["ranges"], 2, "RECORDING"),
    (["ranges", "--simulate", "0"], 2, "--simulate"),
    (["ranges", "--margin-bits", "17", "{image}"], 2, "--margin-bits"),
    (["ranges", "{missing}"], 1, "missing.glimg"),
    (["ranges", "{empty_dir}"], 1, "without IPOL trials"),
    (["ranges", "{garbage}"], 1, "garbage.bin"),
])
def test_bad_input_exits_with_one_line(argv, code, says, image, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    (tmp_path / "garbage.bin").write_bytes(b"\x00garbage" * 10)
    paths = {"image": image, "missing": tmp_path / "missing.glimg", "empty_dir": tmp_path / "empty",
             "garbage": tmp_path / "garbage.bin"}
    args = [a.format(**{k: str(v) for k, v in paths.items()}) for a in argv]
    with pytest.raises(SystemExit) as exc:
        raise SystemExit(main(args))
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == code and len(err) == 1 and says in err[0] and "Traceback" not in err[0]


def test_m5_below_zero_is_in_the_table_and_the_headline(tmp_path, capsys):
    # a logger calibrated with M5 = 0.9 m s / T - 1 m walking 1 s steps: M5 = -0.1 m on every step, stored as 0;
    # the table's derived M5 row counts them all, as the kernel does
    t = np.arange(2000) / 50.0
    acc = np.zeros((t.size, 3))
    acc[:, 2] = 1 - 0.03 * (2 * np.pi) ** 2 * np.cos(2 * np.pi * t) / STANDARD_GRAVITY_M_S2
    cfg = StepConfig(step_format=1, calibrated=True, leg_length_m=0.9, foot_length_m=0.2, k_m1=1.0, k_m2=1.0,
                     k_m4=1.0, k1_m5_m_s=0.9, k2_m5_m=-1.0)
    logger = Logger(device_id=7, step_config=cfg)
    logger.record(Motion(acc_g=acc, sampling_rate_hz=50.0), start_time_s=1_700_000_000)
    path = tmp_path / "slow.glimg"
    logger.save_image(path)
    assert main(["ranges", str(path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    row = {r["variable"]: r for r in doc["rows"]}["K1 fs / N + K2 (M5)"]
    assert doc["n_steps"] > 30 and row["saturations"] == doc["kernel_saturations"] == doc["saturated_records"] > 30
    assert row["min_real"] == pytest.approx(-0.1, abs=0.06) and "K1 fs / N + K2 (M5) (STEP_Q)" in doc["headline"]
    assert main(["ranges", str(path)]) == 0
    assert "at the limit: K1 fs / N + K2 (M5)" in capsys.readouterr().out
