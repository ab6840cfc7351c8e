"""The README's forest plot: read from the committed study CSVs (ndp.experiments.report.forest)."""

from __future__ import annotations

from pathlib import Path

import pytest

from ndp.experiments.report.forest import (
    FOREST_ROWS,
    ForestSpec,
    forest_markdown,
    forest_plot,
    read_forest,
)

ROOT = Path(__file__).resolve().parents[3] / "docs" / "results"


def test_every_forest_row_is_in_a_committed_csv_and_the_headline_comes_first():
    rows = read_forest(ROOT)
    assert len(rows) == len(FOREST_ROWS)
    first = rows[0]
    assert first.spec.group.startswith("headline, 10 seeds, one reward rule") and first.n == 10
    # the fair-live headline's push-v3 difference (docs/rl-release.md part 3: +0.01 [-0.12, +0.13])
    assert first.diff == pytest.approx(0.009, abs=1e-4)
    stale = rows[6]
    assert stale.spec.group.startswith("headline, 10 seeds, stale-world")
    # the stale-rule headline's push-v3 difference (-0.02 [-0.12, +0.07])
    assert stale.diff == pytest.approx(-0.0235, abs=1e-4)
    assert (stale.low, stale.high) == pytest.approx((-0.115, 0.068), abs=1e-3)
    assert all(r.low <= r.diff <= r.high for r in rows)


def test_a_spec_matching_no_row_is_refused_with_its_keys():
    spec = ForestSpec("g", "ndp_regimes/headline-conditions.csv", "white, k = 7", "push-v3",
                      "ndp vs ppo")  # fmt: skip
    with pytest.raises(ValueError, match=r"condition 'white, k = 7'.*found 0"):
        read_forest(ROOT, [spec])
    with pytest.raises(ValueError, match="csv: expected a committed conditions CSV"):
        read_forest(ROOT, [ForestSpec("g", "nope/x.csv", "c", "t", "a vs b")])


def test_forest_plot_and_table(tmp_path):
    rows = read_forest(ROOT, FOREST_ROWS[:4])
    png = forest_plot(rows, tmp_path / "f.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = forest_markdown(rows)
    assert md.count("\n") == 2 + 4
    assert "| below |" in md  # Throw vs PPO-multi's interval lies below zero
