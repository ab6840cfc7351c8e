"""The README answers first and stays short; findings.md keeps each claim short (issue "the
answer at a glance"). Limits: README <= 1,500 words, the answer and the forest plot in its first
30 lines, no table cell over 60 words in README.md or docs/findings.md, each findings section
<= 120 words of prose (its figure, command and link lines aside)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
FINDINGS = ROOT / "docs" / "findings.md"


def _words(text: str) -> int:
    return len(re.findall(r"\S+", text))


def test_readme_is_at_most_1500_words():
    assert _words(README.read_text()) <= 1500


def test_the_answer_and_the_forest_plot_come_first():
    head = README.read_text().splitlines()[:30]
    assert any(line.startswith("## The answer") for line in head)
    assert any("![" in line and "forest.png" in line for line in head)
    assert (ROOT / "docs" / "results" / "overview" / "forest.png").is_file()


@pytest.mark.parametrize("path", [README, FINDINGS], ids=lambda p: p.name)
def test_no_table_cell_over_60_words(path):
    long = []
    for line in path.read_text().splitlines():
        if line.startswith("|") and not set(line) <= set("|-: "):
            for cell in line.strip().strip("|").split("|"):
                if _words(cell) > 60:
                    long.append(cell.strip()[:80])
    assert not long, f"{path.name}: cells over 60 words: {long}"


def _sections(text: str) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    name = None
    for line in text.splitlines():
        if line.startswith("## "):
            name = line[3:]
            out[name] = []
        elif name is not None:
            out[name].append(line)
    return out


def test_each_findings_section_is_short_and_has_its_command():
    sections = _sections(FINDINGS.read_text())
    assert len(sections) >= 11  # the seven claims and the studies beyond the paper
    for name, lines in sections.items():
        prose = [
            ln for ln in lines
            if not ln.startswith(("Command:", "![", "(", "[")) and not ln.startswith("No figure")
        ]  # fmt: skip
        assert _words("\n".join(prose)) <= 120, name
        if name != "Performance profiles":
            assert any(ln.startswith("Command:") for ln in lines), name
            assert "**Verdict:" in "\n".join(lines), name
