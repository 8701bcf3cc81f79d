"""Every shell block of the README and of the documentation runs as written: the documentation test.

The rule:

- The pages are README.md and every ``.md`` file under ``docs/`` (the generated ``_build`` and
  ``_autosummary`` folders aside), so a page added under ``docs/topics/`` is tested without editing this file.
- One page is one test, run in a fresh, empty folder whose parent holds a ``shared`` link to the real
  recordings, as a fresh clone beside ``../shared`` would be.
- The page's ```` ```sh ```` blocks run in the page's order, line by line, in one bash shell (so ``&`` jobs and
  ``kill %1`` work); each ```` ```python ```` block runs as one ``python - <<EOF`` script at its place.
- Each command must exit 0, except a command whose comment says ``(exit 1)``.
- A block is left out only by an explicit marker, an HTML comment on the line before its fence (blank lines
  between are allowed), which the rendered pages do not show::

      <!-- not run by the documentation test: REASON -->

  with the reason (the install and the test command themselves, which CI runs; benchmarks; minutes-long
  studies). Nothing else is skipped, but: when the recordings are absent (``$GAITLOG_DATA_DIR``, else
  ``../shared/data``), a page with a command that reads ``../shared`` is skipped whole, with the reason, as
  the tests that need the data are (its later commands read what those made).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.conftest import DATA_DIR

#: The pages that start a background job (a server on a fixed TCP port, a Dask scheduler, each followed by a
#: ``sleep`` that waits for it) run one after another on one worker (pytest-xdist); the other pages, each in its
#: own folder, spread over the workers.
SERVER_PAGES_GROUP = "documentation_servers"

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
#: The comment that leaves the next block out of the documentation test; it must give a reason.
SKIP_MARKER = re.compile(r"<!--\s*not run by the documentation test:\s*(?P<reason>[^>]*?)\s*-->")
#: The README's size limit: a front page, not a manual.
README_MAX_BYTES = 12 * 1024


@dataclass(frozen=True)
class Block:
    """A fenced code block of a page: its language, its text and, when marked, why it does not run."""

    kind: str
    text: str
    skip_reason: str | None


def pages() -> list[Path]:
    """README.md, then every Markdown page of ``docs/`` in path order."""
    found = [p for p in DOCS.rglob("*.md") if not {"_build", "_autosummary"} & set(p.relative_to(DOCS).parts)]
    return [README, *sorted(found)]


def page_id(page: Path) -> str:
    return str(page.relative_to(ROOT))


def blocks(page: Path) -> list[Block]:
    """The ``sh`` and ``python`` blocks of a page, in order, each with the reason of its marker (or None)."""
    text = page.read_text(encoding="utf-8")
    out = []
    for m in re.finditer(r"^```(sh|python)[ \t]*\n(.*?)^```[ \t]*$", text, flags=re.S | re.M):
        before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        marker = SKIP_MARKER.search(before)
        out.append(Block(m.group(1), m.group(2), marker.group("reason") if marker else None))
    return out


def page_commands(page: Path) -> list[str]:
    """The command lines of a page's blocks that run (comment lines and blank lines dropped), and each
    ``python`` block as one ``python - <<EOF`` command, in the page's order."""
    lines = []
    for block in blocks(page):
        if block.skip_reason is not None:
            continue
        if block.kind == "python":
            lines.append(f"python - <<'DOCS_PYTHON'\n{block.text}DOCS_PYTHON")
            continue
        lines += [ln for ln in block.text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    return lines


def starts_a_background_job(page: Path) -> bool:
    """Whether a command of the page runs in the background (``&`` not part of ``&&``)."""
    return any(re.search(r"(?<![&>])&(?!&)", ln) for ln in page_commands(page))


def page_params() -> list:
    """Each page, those with a background job in one ``xdist_group``."""
    return [pytest.param(p, marks=pytest.mark.xdist_group(SERVER_PAGES_GROUP)) if starts_a_background_job(p) else p
            for p in pages()]


def expected_exit(line: str) -> int:
    """1 when the page's comment says the command exits 1, else 0."""
    return 1 if "(exit 1)" in line else 0


def test_the_pages_have_commands() -> None:
    everything = [ln for page in pages() for ln in page_commands(page)]
    assert len(everything) >= 40
    assert any(ln.startswith("gaitlog record") for ln in everything)
    assert any("kill %1" in ln for ln in everything)
    assert any(ln.startswith("python - <<") for ln in everything)
    assert len(page_commands(README)) >= 5, "the README's quick starts run"


def test_every_marker_gives_a_reason_and_marks_a_block() -> None:
    """A marker must say why, and must stand right before a block (else it silently marks nothing)."""
    for page in pages():
        text = page.read_text(encoding="utf-8")
        n_markers = len(SKIP_MARKER.findall(text))
        marked = [b for b in blocks(page) if b.skip_reason is not None]
        assert n_markers == len(marked), f"{page_id(page)}: a marker stands before no sh/python block"
        assert all(b.skip_reason for b in marked), f"{page_id(page)}: a marker without a reason"


def test_the_readme_is_a_front_page() -> None:
    size = len(README.read_bytes())
    assert size <= README_MAX_BYTES, f"README.md is {size} bytes, more than {README_MAX_BYTES}: move text to docs/"
    first = next(b for b in blocks(README) if b.kind == "sh")
    assert "pip install . && gaitlog demo" in first.text and "python -m pytest -q" in first.text


@pytest.mark.parametrize("page", page_params(), ids=page_id)
def test_every_command_of_the_page_runs_as_written(page: Path, tmp_path: Path) -> None:
    lines = page_commands(page)
    if not lines:
        pytest.skip(f"{page_id(page)} shows no command that runs")
    if shutil.which("gaitlog") is None:
        pytest.fail("the gaitlog command is not installed (pip install -e '.[test]')")
    work = tmp_path / "clone"
    work.mkdir()
    if DATA_DIR.is_dir():
        (tmp_path / "shared").symlink_to(DATA_DIR.parent, target_is_directory=True)
    elif any("../shared" in line for line in lines):
        pytest.skip(f"{page_id(page)} reads ../shared: real recordings not found at {DATA_DIR} "
                    "(set GAITLOG_DATA_DIR)")
    script, expected = ["set +e"], {}
    for i, line in enumerate(lines):
        expected[i] = expected_exit(line)
        script.append(line)
        script.append(f'printf "\\n__rc {i} %d\\n" $?')  # on a line of its own after output without a newline
    script.append("kill %1 2>/dev/null; wait 2>/dev/null; true")
    run = subprocess.run(["bash", "-c", "\n".join(script)], cwd=work, capture_output=True, text=True,
                         timeout=1200)
    codes = {int(m.group(1)): int(m.group(2)) for m in re.finditer(r"^__rc (\d+) (\d+)$", run.stdout, re.M)}
    failed = [f"{lines[i]!r}: exit {codes.get(i)} (expected {want})" for i, want in expected.items()
              if codes.get(i) != want]
    assert not failed, f"{page_id(page)}:\n" + "\n".join(failed) + "\n--- stderr ---\n" + run.stderr[-3000:]


def test_the_pages_with_a_background_job_are_one_group() -> None:
    """The decode tutorial's server (a fixed port) and the quantisation tutorial's scheduler are found, and a
    page without a job is not grouped."""
    grouped = {page_id(p) for p in pages() if starts_a_background_job(p)}
    assert {"docs/tutorials/decode.md", "docs/tutorials/quantisation.md"} <= grouped
    assert "README.md" not in grouped
