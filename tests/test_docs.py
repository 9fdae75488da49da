"""Every Python code block of README.md and docs/*.md runs as written.

Each ```python block runs in a fresh interpreter (``sys.executable``) in an empty
temporary directory (so the installed package is imported, not the source tree), and
must exit with status 0 and print no traceback. Test ids are ``file:line`` of the
block's opening fence. Blocks in other languages (bash, output) are not run.

A block may be left out only by an HTML comment on the line before its fence,
``<!-- no-run: reason -->``: it is reported as skipped with that reason (``pytest -rs``
lists them), and ``test_no_run_markers_name_a_reason_and_a_python_block`` fails on a
marker without a reason or with no Python block after it.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FENCE = re.compile(r"^( {0,3})(`{3,}|~{3,})\s*([^\s`]*)")
NO_RUN = re.compile(r"^\s*<!--\s*no-run\s*:?(.*?)-->\s*$")
TIMEOUT = 600  # seconds per block


@dataclass
class Block:
    path: str  # relative to the checkout, e.g. "docs/testing.md"
    line: int  # 1-based line of the opening fence
    lang: str
    code: str
    no_run: str | None  # the reason of a no-run marker on the line before, else None

    @property
    def id(self) -> str:
        return f"{self.path}:{self.line}"


def markdown_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def blocks(path: Path) -> list[Block]:
    """The fenced code blocks of a markdown file, with their language and marker."""
    lines = path.read_text(encoding="utf-8").splitlines()
    rel = path.relative_to(ROOT).as_posix()
    out, k = [], 0
    while k < len(lines):
        m = FENCE.match(lines[k])
        if not m:
            k += 1
            continue
        indent, fence, lang = len(m.group(1)), m.group(2), m.group(3).lower()
        start, body = k, []
        k += 1
        while k < len(lines):
            close = FENCE.match(lines[k])
            if close and close.group(2)[0] == fence[0] and len(close.group(2)) >= len(fence) \
                    and not close.group(3):
                break
            line = lines[k]
            body.append(line[min(indent, len(line) - len(line.lstrip(" "))):])
            k += 1
        k += 1  # past the closing fence (or the end of an unclosed block)
        before = next((lines[j] for j in range(start - 1, -1, -1) if lines[j].strip()), "")
        marker = NO_RUN.match(before)
        out.append(Block(rel, start + 1, lang, "\n".join(body) + "\n",
                         marker.group(1).strip() if marker else None))
    return out


ALL_BLOCKS = [b for f in markdown_files() if f.exists() for b in blocks(f)]
PYTHON_BLOCKS = [b for b in ALL_BLOCKS if b.lang in ("python", "py", "python3")]


def test_the_readme_has_python_blocks():
    """The extraction finds the README's examples (a parser that found none would pass everything)."""
    assert any(b.path == "README.md" for b in PYTHON_BLOCKS)


def test_no_run_markers_name_a_reason_and_a_python_block():
    marked = [b for b in ALL_BLOCKS if b.no_run is not None]
    assert all(b.no_run for b in marked), [b.id for b in marked if not b.no_run]
    assert all(b in PYTHON_BLOCKS for b in marked), [b.id for b in marked if b not in PYTHON_BLOCKS]
    for f in markdown_files():
        if not f.exists():
            continue
        lines = f.read_text(encoding="utf-8").splitlines()
        rel = f.relative_to(ROOT).as_posix()
        for k, line in enumerate(lines):
            if NO_RUN.match(line):  # the next non-blank line must open a block that carries it
                nxt = next((j for j in range(k + 1, len(lines)) if lines[j].strip()), None)
                assert nxt is not None and any(b.path == rel and b.line == nxt + 1 for b in marked), \
                    f"{rel}:{k + 1}: a no-run marker with no code block after it"


@pytest.mark.parametrize("block", PYTHON_BLOCKS, ids=[b.id for b in PYTHON_BLOCKS])
def test_python_block_runs(block, tmp_path):
    if block.no_run is not None:
        pytest.skip(f"{block.id}: no-run: {block.no_run}")
    script = tmp_path / "block.py"
    script.write_text(block.code, encoding="utf-8")
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTHONPATH", None)  # the installed package, as a reader of the docs has it
    run = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=TIMEOUT)
    status = run.returncode
    out = f"--- {block.id}\n{block.code}--- stdout\n{run.stdout[-4000:]}\n--- stderr\n{run.stderr[-4000:]}"
    assert status == 0, f"exit status {status}\n{out}"
    assert "Traceback (most recent call last)" not in run.stdout + run.stderr, out
