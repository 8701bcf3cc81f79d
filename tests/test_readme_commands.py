"""Every command of the README runs as written, in order, in an empty folder with ``../shared`` beside it.

The ``sh`` blocks of README.md (and each ``python`` block, as a script) are run by one bash shell (so ``&`` jobs and ``kill %1`` work) in a scratch
folder whose parent holds a ``shared`` link to the real recordings, as a fresh clone beside ``../shared``
would be. Not run here: the first block (install and the test command itself: CI runs them) and the
benchmark block (minutes of timing; run by hand). A command that needs ``../shared/data`` is left out, with
the reason, when the recordings are absent. Each command must exit 0, except those whose README comment
says it exits 1.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.conftest import DATA_DIR

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def readme_commands() -> list[str]:
    """The command lines of the README's ``sh`` blocks, but the first (install, tests) and the benchmarks, and
    each ``python`` block as one ``python - <<EOF`` command, in the README's order."""
    text = README.read_text(encoding="utf-8")
    blocks = re.findall(r"```(sh|python)\n(.*?)```", text, flags=re.S)
    first_sh = next(i for i, (kind, _) in enumerate(blocks) if kind == "sh")
    lines = []
    for i, (kind, block) in enumerate(blocks):
        if i == first_sh or "benchmarks/bench_" in block:
            continue
        if kind == "python":
            lines.append(f"python - <<'README_PYTHON'\n{block}README_PYTHON")
            continue
        lines += [ln for ln in block.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    return lines


def expected_exit(line: str) -> int:
    """1 when the README's comment says the command exits 1, else 0."""
    return 1 if "(exit 1)" in line else 0


def test_the_readme_has_commands() -> None:
    lines = readme_commands()
    assert len(lines) >= 20
    assert any(ln.startswith("gaitlog record") for ln in lines) and any("kill %1" in ln for ln in lines)
    assert any(ln.startswith("python - <<") for ln in lines)


def test_every_readme_command_runs_as_written(tmp_path: Path) -> None:
    if shutil.which("gaitlog") is None:
        pytest.fail("the gaitlog command is not installed (pip install -e '.[test]')")
    work = tmp_path / "clone"
    work.mkdir()
    have_data = DATA_DIR.is_dir()
    if have_data:
        (tmp_path / "shared").symlink_to(DATA_DIR.parent, target_is_directory=True)
    script, expected = ["set +e"], {}
    for i, line in enumerate(readme_commands()):
        if not have_data and ("../shared" in line or line.startswith("python - <<")):
            continue    # the recordings are absent (the Python example reads what the real-data walkthrough made)
        expected[i] = expected_exit(line)
        script.append(line)
        script.append(f'echo "__rc {i} $?"')
    script.append("kill %1 2>/dev/null; wait 2>/dev/null; true")
    run = subprocess.run(["bash", "-c", "\n".join(script)], cwd=work, capture_output=True, text=True,
                         timeout=900)
    codes = {int(m.group(1)): int(m.group(2)) for m in re.finditer(r"^__rc (\d+) (\d+)$", run.stdout, re.M)}
    lines = readme_commands()
    failed = [f"{lines[i]!r}: exit {codes.get(i)} (expected {want})" for i, want in expected.items()
              if codes.get(i) != want]
    assert not failed, "\n".join(failed) + "\n--- stderr ---\n" + run.stderr[-3000:]
