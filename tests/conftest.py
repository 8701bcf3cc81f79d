"""Shared test fixtures: paths to the real recordings in ``../shared/data`` (tests skip when absent)."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

#: The compiled kernels (numba's cache, the ahead-of-time module) of this checkout's test runs: no run leans on
#: what another left in the user's cache folder. Set GAITLOG_CACHE_DIR to choose another place.
os.environ.setdefault("GAITLOG_CACHE_DIR", str(Path(__file__).resolve().parents[1] / ".pytest_cache" / "gaitlog"))

#: Root of the real recordings; override with GAITLOG_DATA_DIR.
DATA_DIR = Path(os.environ.get("GAITLOG_DATA_DIR", Path(__file__).resolve().parents[1].parent / "shared" / "data"))


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config: pytest.Config) -> None:
    """The suite runs on every core: ``-n auto --dist loadgroup`` when pytest-xdist is loaded and the command
    line gave no ``-n`` (``-n 0`` or ``-p no:xdist``: one process). ``loadgroup`` keeps the tests of one
    ``xdist_group`` on one worker, one after another, also under an explicit ``-n``."""
    if not config.pluginmanager.hasplugin("xdist"):
        return
    if hasattr(config, "workerinput"):          # a worker parses only the command line: told by the hook below
        config.option.loadgroup = config.workerinput.get("loadgroup", config.option.loadgroup)
        return
    if config.option.numprocesses is None:
        config.option.numprocesses = "auto"
    if config.option.dist == "no":
        config.option.dist = "loadgroup"


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node) -> None:
    """pytest-xdist, before a worker starts: whether the run groups by ``xdist_group`` (chosen above)."""
    node.workerinput["loadgroup"] = node.config.option.dist == "loadgroup"


#: A module of at most this many tests that share a module-scoped fixture runs on one worker (see below).
MODULE_GROUP_MAX_TESTS = 60


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """On a pytest-xdist worker: the tests of a module that share a module-scoped fixture (a simulated walk, an
    evaluation) form one ``xdist_group``, so the fixture is built once, not once per worker. A larger module (the
    bad-input matrix) stays spread over the workers. Runs before xdist reads the marks."""
    if not hasattr(config, "workerinput"):
        return
    per_module: dict[str, list[pytest.Item]] = {}
    for item in items:
        per_module.setdefault(item.nodeid.split("::")[0], []).append(item)
    for module, tests in per_module.items():
        if len(tests) <= MODULE_GROUP_MAX_TESTS and any(map(_uses_module_fixture, tests)):
            for item in tests:
                if item.get_closest_marker("xdist_group") is None:
                    item.add_marker(pytest.mark.xdist_group(module))


def _uses_module_fixture(item: pytest.Item) -> bool:
    info = getattr(item, "_fixtureinfo", None)
    return info is not None and any(defs and defs[-1].scope in ("module", "class", "package")
                                    for defs in info.name2fixturedefs.values())


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The ``shared/data`` folder; the test is skipped with a reason when it is absent."""
    if not DATA_DIR.is_dir():
        pytest.skip(f"real recordings not found at {DATA_DIR} (set GAITLOG_DATA_DIR)")
    return DATA_DIR


@pytest.fixture(scope="session")
def simulated_walk() -> tuple:
    """``(codes, subject)``: a simulated subject walking the paper's protocol, as the emulated logger stored
    it (10-bit codes at 50 Hz; the logger's default sensor unit)."""
    from gaitlog.firmware_sim.device import Logger
    from gaitlog.firmware_sim.world.subject import random_subjects
    from gaitlog.firmware_sim.world.walking import Walking

    subject = random_subjects(1, seed=3)[0]
    res = Logger(device_id=4).record(Walking(subject=subject, seed=3))
    return res.codes.astype("int64"), subject


class LrzszRx:
    """lrzsz's ``rx``, the independent XMODEM-1K/CRC receiver the device's XDUMP is tested against.

    Every caller goes through here: ``rx`` gets a bare file name and runs in the target's folder, because
    current lrzsz (Debian 0.12.21-10+deb12u1 and later) refuses any absolute name with "Security Violation".
    A failure names rx's stderr and the installed lrzsz, so a packaging change shows itself at once.
    """

    #: -X XMODEM, -c CRC-16 ('C' start), -b binary, -q quiet.
    OPTIONS = ("-X", "-c", "-b", "-q")

    def argv(self, target: Path) -> list[str]:
        return ["rx", *self.OPTIONS, target.name]

    def run(self, target: Path, fd: int, timeout_s: float = 120.0) -> subprocess.CompletedProcess:
        """Receive into ``target`` over ``fd`` (a pty: rx's stdin and stdout); assert it succeeded."""
        done = subprocess.run(self.argv(target), stdin=fd, stdout=fd, stderr=subprocess.PIPE, cwd=target.parent,
                              timeout=timeout_s)
        self.check(done.returncode, done.stderr)
        return done

    def popen(self, target: Path) -> subprocess.Popen:
        """``rx`` receiving into ``target`` with pipes on stdin and stdout (the caller plays the sender)."""
        return subprocess.Popen(self.argv(target), stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, cwd=target.parent)

    def check(self, returncode: int | None, stderr: bytes | None) -> None:
        assert returncode == 0, (f"rx exited {returncode}: {(stderr or b'').decode(errors='replace').strip()!r} "
                                 f"(installed: {self.version()})")

    @staticmethod
    def version() -> str:
        """The installed lrzsz: the Debian package version where dpkg knows it, else ``rx --version``."""
        for argv in (["dpkg-query", "-W", "-f", "lrzsz ${Version}", "lrzsz"], ["rx", "--version"]):
            try:
                out = subprocess.run(argv, capture_output=True, text=True, timeout=10)
            except OSError:
                continue
            if out.returncode == 0 and out.stdout.strip():
                return out.stdout.strip().splitlines()[0]
        return "unknown version"


@pytest.fixture(scope="session")
def lrzsz_rx() -> LrzszRx:
    """lrzsz's ``rx``; the test is skipped, with the reason, only where it is not installed."""
    if shutil.which("rx") is None:
        pytest.skip("lrzsz `rx` is not installed (apt-get install lrzsz)")
    return LrzszRx()


@pytest.fixture
def dask_scheduler_file(tmp_path: Path):
    """A Dask scheduler and one worker started apart, as a user would (port 0: no free port needed); yields the
    scheduler file, stops both after the test. Skips when distributed is absent or they do not come up."""
    pytest.importorskip("distributed")
    import json
    import sys
    import time

    from distributed import Client

    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    scheduler_file = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", "0", "--scheduler-file", str(scheduler_file), "--no-dashboard"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline, addr = time.monotonic() + 60, None
        while addr is None and time.monotonic() < deadline:
            try:
                addr = json.loads(scheduler_file.read_text())["address"]
            except (OSError, ValueError, KeyError):
                time.sleep(0.2)
        if addr is None:
            pytest.skip("a dask scheduler on 127.0.0.1 wrote no address within 60 s")
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", addr, "--nthreads", "1",
                                       "--nworkers", "1", "--no-dashboard"], env=env, cwd=tmp_path,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        try:
            with Client(addr, timeout="30s") as client:
                client.wait_for_workers(1, timeout=60)
        except (OSError, TimeoutError) as err:
            pytest.skip(f"could not start a scheduler and a worker on 127.0.0.1: {err}")
        yield scheduler_file
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
