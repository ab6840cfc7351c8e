"""Every ```python snippet of README.md and docs/*.md runs as written.

A snippet that cannot run on its own says so on its first line, ``# not run: <reason>``, and is
only compiled. Each runs in a fresh namespace: README.md's from an empty temporary directory
outside the checkout, against the installed package (what a user who installed it meets); the
docs' with the repository root as working directory.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)
NOT_RUN = re.compile(r"#\s*not run:\s*(\S.*)")


def snippets() -> list[tuple[str, str]]:
    out = []
    for doc in DOCS:
        text = doc.read_text()
        for m in FENCE.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            out.append((f"{doc.relative_to(ROOT)}:{line}", m.group(1)))
    return out


SNIPPETS = snippets()


def test_the_docs_have_python_snippets():
    names = {s.split(":")[0] for s, _ in SNIPPETS}
    assert {"README.md", "docs/envs.md"} <= names, names
    assert len(SNIPPETS) >= 4


@pytest.mark.parametrize("where,code", SNIPPETS, ids=[s for s, _ in SNIPPETS])
def test_snippet_runs(where, code, monkeypatch, tmp_path):
    first = code.splitlines()[0] if code.strip() else ""
    compiled = compile(code, where, "exec")
    skip = NOT_RUN.search(first)
    if skip:
        pytest.skip(f"marked not run: {skip.group(1)}")
    monkeypatch.chdir(tmp_path if where.startswith("README.md") else ROOT)
    monkeypatch.setenv("MUJOCO_GL", os.environ.get("MUJOCO_GL", "egl"))
    exec(compiled, {"__name__": "__snippet__"})
