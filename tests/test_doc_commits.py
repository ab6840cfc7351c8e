"""Every commit hash the docs name is in the repository's history (issue "provenance"): a table
header's "Commit: 3f4e73b", "runs trained at commits: 7b7d5e4, f8ab6be", a doc's "pinned at
caf1ac1" or "(63 runs at 3f5ed03)" must be reachable by ``git log --all``, so that a reader can
check out the code that made a number. A hash that is not (a commit never pushed, or lost with
a machine) is allowed only where the text marks it so right after it: ``13bb841 (lost: ...)``,
the marker ``ndp report`` writes for such a commit.

Hash-like tokens: 7 to 40 hex digits with at least one digit and one letter, standing alone (not
inside a word, a path or a number), and not an abbreviated digest (``6066da6f...``)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TOKEN = re.compile(r"(?<![0-9A-Za-z_./#-])([0-9a-f]{7,40})(?![0-9A-Za-z_])(?!\.\.\.)")
LOST = re.compile(r"\s*\((?:[^)]*?\b)?lost\b")
"""The marker that may follow a hash the history lacks: ``(lost ...)``, ``(a lost commit ...)``."""


def _history() -> list[str]:
    try:
        shallow = subprocess.run(
            ["git", "rev-parse", "--is-shallow-repository"],
            cwd=ROOT, capture_output=True, text=True, check=True,
        ).stdout.strip()  # fmt: skip
        commits = subprocess.run(
            ["git", "rev-list", "--all"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    if shallow == "true":
        pytest.skip("a shallow clone lacks the history the docs name")
    return commits


def named_hashes(text: str) -> list[tuple[int, str, bool]]:
    """(line number, hash, marked lost) of every hash-like token of ``text``."""
    out = []
    for i, line in enumerate(text.splitlines(), 1):
        for m in TOKEN.finditer(line):
            h = m.group(1)
            if re.search(r"[0-9]", h) and re.search(r"[a-f]", h):
                out.append((i, h, bool(LOST.match(line, m.end()))))
    return out


def test_the_token_rule_on_examples():
    text = (
        "Commit: 3f4e73b, date: x; runs trained at commits: 7b7d5e4, 13bb841 (lost: not in "
        "this repository's history).\nat 1e38e6b, digests `6066da6f...`, 2026-12-05, "
        "runs/ndp_regimes_1m/x, p 1.5e-04, decade, abcdef0123456789abcdef0123456789abcdef01"
    )
    got = [(h, lost) for _, h, lost in named_hashes(text)]
    full = "abcdef0123456789abcdef0123456789abcdef01"
    assert got == [("3f4e73b", False), ("7b7d5e4", False), ("13bb841", True),
                   ("1e38e6b", False), (full, False)]  # fmt: skip


def test_every_commit_the_docs_name_is_in_the_history_or_marked_lost():
    known = _history()
    files = sorted(ROOT.glob("docs/*.md")) + sorted(ROOT.glob("docs/results/**/*.md"))
    bad, marked = [], set()
    for f in files:
        for line, h, lost in named_hashes(f.read_text(encoding="utf-8")):
            if any(c.startswith(h) for c in known):
                assert not lost, f"{f.relative_to(ROOT)}:{line}: {h} is in the history, not lost"
                continue
            if lost:
                marked.add(h)
            else:
                bad.append(f"{f.relative_to(ROOT)}:{line}: {h}")
    assert not bad, (
        "commits named in the docs that `git log --all` does not reach (restore them, correct "
        "the hash, or mark it '(lost: not in this repository's history)'): " + "; ".join(bad)
    )
    assert marked <= {"13bb841"}, f"newly lost commits, say why in the docs: {sorted(marked)}"
