"""Every ``python`` code block of the README and of the docs pages names only what it defines or
imports: copied into a file as written, none stops on a ``NameError``. A block whose first line is
``# (continued from the block above)`` is checked with the page's blocks before it, in order."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
CONTINUED = "# (continued from the block above)"
_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})[ \t]*(?P<info>[^\n]*)$")


def pages() -> list[Path]:
    """The README and the docs' hand-written pages (not the generated ones)."""
    return [ROOT / "README.md", *sorted(p for p in DOCS.rglob("*.md") if "_generated" not in p.relative_to(DOCS).parts)]


def python_blocks(text: str) -> list[tuple[int, str]]:
    """The page's ``python`` fenced blocks: (line of the block's first line, 1-based; its text)."""
    blocks, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        start = _FENCE.match(lines[i])
        if not start:
            i += 1
            continue
        fence, indent = start["fence"], len(start["indent"])
        j = i + 1
        while j < len(lines) and not re.match(rf"^[ \t]*{fence[0]}{{{len(fence)},}}[ \t]*$", lines[j]):
            j += 1
        if start["info"].strip().strip("{}").split(" ")[0] in ("python", "py", "python3"):
            blocks.append((i + 2, "\n".join(line[indent:] for line in lines[i + 1 : j]) + "\n"))
        i = j + 1
    return blocks


def checked_code() -> list[tuple[str, str]]:
    """(label, code) for each block; a continued block's code is the page's blocks up to it."""
    out = []
    for page in pages():
        so_far = ""
        for line, code in python_blocks(page.read_text()):
            continued = code.lstrip().startswith(CONTINUED)
            assert not continued or so_far, f"{page.relative_to(ROOT)}:{line} continues no block"
            so_far = (so_far + "\n" + code) if continued else code
            out.append((f"{page.relative_to(ROOT)}:{line}", so_far))
    return out


def ruff() -> list[str]:
    beside = Path(sys.executable).with_name("ruff")
    if beside.exists():
        return [str(beside)]
    if shutil.which("ruff"):
        return [str(shutil.which("ruff"))]
    pytest.importorskip("ruff", reason="ruff checks the blocks (the dev extra)")
    return [sys.executable, "-m", "ruff"]


def test_the_pages_hold_python_blocks():
    assert len(checked_code()) >= 10
    assert any(label.startswith("README.md:") for label, _ in checked_code())


def test_every_python_block_names_only_what_it_defines_or_imports(tmp_path):
    files = {}
    for n, (label, code) in enumerate(checked_code()):
        path = tmp_path / f"block_{n:03d}.py"
        path.write_text(code)
        files[path.name] = label
    run = subprocess.run(
        [*ruff(), "check", "--isolated", "--select", "F821", "--output-format", "concise", "--no-cache", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    reports = [line for line in run.stdout.splitlines() if line.startswith(str(tmp_path))]
    named = [f"{files[Path(line.split(':', 1)[0]).name]} (as checked, {line.split(':', 1)[1].strip()})" for line in reports]
    assert run.returncode == 0 and not named, "blocks that would stop on a NameError or do not parse:\n" + "\n".join(
        named or [run.stdout, run.stderr]
    )
