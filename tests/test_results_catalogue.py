"""docs/results is a catalogue (issue "a user's first day, part 2", item 10): one folder per
study, superseded and smoke studies under archive/, every folder in the index with a status,
and the README's results linking only to studies that are not archived."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
INDEX = RESULTS / "README.md"
STATUSES = ("current", "interim", "benchmark", "superseded by", "smoke")


def _index_rows() -> dict[str, str]:
    """Study folder (relative to docs/results) -> its status, from the index's table."""
    rows = {}
    for line in INDEX.read_text().splitlines():
        m = re.match(r"\| \[[^\]]+\]\(([^)]+)\)", line)
        if m:
            folder = m.group(1).rstrip("/").rpartition("/")[0] or m.group(1).rstrip("/")
            rows[folder] = [c.strip() for c in line.split("|")][4]
    return rows


def _study_folders() -> set[str]:
    folders = set()
    for p in RESULTS.rglob("*"):
        if p.is_file() and p.name != "README.md":
            folders.add(str(p.parent.relative_to(RESULTS)))
    return folders


def test_every_result_lives_in_a_study_folder_listed_in_the_index():
    flat = [p.name for p in RESULTS.iterdir() if p.is_file() and p.name != "README.md"]
    assert not flat, f"result files outside a study folder: {flat}"
    rows = _index_rows()
    missing = _study_folders() - set(rows)
    assert not missing, f"study folders the index does not list: {sorted(missing)}"
    for folder, status in rows.items():
        assert (RESULTS / folder).is_dir(), f"the index lists {folder!r}, which does not exist"
        assert status.startswith(STATUSES), f"{folder}: status {status!r}"


def test_archived_studies_are_exactly_the_superseded_and_smoke_ones():
    for folder, status in _index_rows().items():
        archived = folder.startswith("archive/")
        retired = status.startswith(("superseded", "smoke"))
        assert archived == retired, f"{folder}: status {status!r}, archived {archived}"


def test_the_readme_results_link_no_archived_study():
    text = (ROOT / "README.md").read_text()
    assert "docs/results/archive/" not in text
