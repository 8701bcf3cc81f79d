"""Small hostile files that claim a lot: each is a one-line error naming the file, in bounded memory.

Each file is read by ``gaitlog estimate`` in a child process whose peak resident memory (``VmHWM``) is
measured; the bound is 500 MB (issue 13: a 68-byte CSV with a 2 x 10^5 s gap reached 5.4 GB, a 3 MB NPZ zip
bomb 3.1 GB, a ``.npy`` header claiming terabytes raised MemoryError). The child also has a 2 GB address
space limit, so a regression fails the test instead of the machine.
"""

from __future__ import annotations

import io
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

#: Peak resident memory allowed while refusing a hostile file, MB.
PEAK_RSS_LIMIT_MB = 500

_CHILD = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
from gaitlog.host.cli import main
code = main(sys.argv[1:])
# VmHWM, the peak of this process's own memory (ru_maxrss would keep the parent's peak across fork + exec)
hwm_kb = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM:"))
print(hwm_kb // 1024, file=sys.stdout)
sys.exit(code)
"""


def _npy_header(shape: tuple[int, ...], dtype: str = "<u2") -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buf.getvalue()


def _zip_bomb(path: Path) -> None:
    """A genuine-looking recording NPZ whose ``codes`` inflate to 3 GB of zeros (about 3 MB on disk)."""
    n = 500_000_000
    meta = json.dumps({"format_version": 1})
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=9) as zf:
        with zf.open("codes.npy", "w", force_zip64=True) as fh:
            fh.write(_npy_header((n, 3)))
            chunk = bytes(1 << 24)
            for _ in range(n * 6 // len(chunk)):
                fh.write(chunk)
        buf = io.BytesIO()
        np.save(buf, np.array(meta))
        zf.writestr("metadata_json.npy", buf.getvalue())


def _hostile(folder: Path) -> dict[str, Path]:
    files = {}

    def put(name: str, data: bytes) -> None:
        files[name] = folder / name
        files[name].write_bytes(data)

    put("gap.csv", b"time_s,x_g,y_g,z_g\n0,0,0,1\n0.001,0,0,1\n0.002,0,0,1\n200000,0,0,1\n")  # 68 bytes
    put("7-1_lb.txt", b"Acquisition frequency: 100 Hz\nPacketCounter\tAcc_X\tAcc_Y\tAcc_Z\n"
                               b"0\t0\t0\t9.8\n1\t0\t0\t9.8\n900000000000\t0\t0\t9.8\n")
    (folder / "7-1.json").write_text(json.dumps({"TrialBoundaries": [0, 1]}))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("codes.npy", _npy_header((1 << 40, 3)))
    put("terabyte_header.npz", buf.getvalue())
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("metadata_json.npy", _npy_header((1 << 28,), "<U1000"))
    put("terabyte_string.npz", buf.getvalue())
    put("nested.json", b"[" * 10_000_000)
    return files


@pytest.fixture(scope="module")
def hostile(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("hostile")
    files = _hostile(folder)
    _zip_bomb(folder / "zip_bomb.npz")
    files["zip_bomb.npz"] = folder / "zip_bomb.npz"
    return files


def peak_rss_mb(argv: list[str]) -> tuple[int, str, int]:
    """Run ``gaitlog argv`` in a child; return its exit code, stderr and peak RSS in MB."""
    root = Path(__file__).resolve().parents[3]
    proc = subprocess.run([sys.executable, "-c", _CHILD, *argv], capture_output=True, text=True, timeout=300,
                          cwd=root, env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"})
    lines = proc.stdout.strip().splitlines()
    return proc.returncode, proc.stderr, int(lines[-1]) if lines and lines[-1].isdigit() else -1


@pytest.mark.parametrize("name, argv", [
    ("gap.csv", ["estimate", "{}"]),
    ("7-1_lb.txt", ["estimate", "{}"]),
    ("terabyte_header.npz", ["estimate", "{}"]),
    ("terabyte_string.npz", ["estimate", "{}"]),
    ("zip_bomb.npz", ["estimate", "{}"]),
    ("nested.json", ["estimate", "{gap}", "--rate", "50", "--k-file", "{}"]),
])
def test_hostile_file_is_one_error_line_in_bounded_memory(hostile, name, argv):
    path = hostile[name]
    args = [a.replace("{}", str(path)).replace("{gap}", str(hostile["gap.csv"])) for a in argv]
    code, err, peak_mb = peak_rss_mb(args)
    assert code == 1, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert name in err
    assert 0 < peak_mb <= PEAK_RSS_LIMIT_MB, (peak_mb, err)
