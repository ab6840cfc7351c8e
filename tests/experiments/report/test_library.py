"""The report as a library: docs/architecture.md's "your own table in a few lines" on fixture
runs (the same numbers as ``ndp report``'s table)."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

from ndp.experiments.report import fmt_stat, load_cells
from ndp.experiments.report.cells import split_tables
from ndp.experiments.report.family import family_section, parse_pairs
from ndp.experiments.report.markdown import success_table

DOC = Path(__file__).resolve().parents[3] / "docs" / "architecture.md"


def _run(root: Path, task: str, label: str, seed: int, success: float) -> None:
    run = root / f"{task}-{label}-s{seed}"
    run.mkdir(parents=True)
    with (run / "metrics.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["update", "global_step", "charts/success_any", "charts/episode_return"])
        for i in range(10):
            w.writerow([i + 1, (i + 1) * 100, success, -1.0])
    arm = {"label": label, "algo": "ppo", "args": [], "note": "", "steps": 1000,
           "task": task, "seed": seed, "kind": "rl"}  # fmt: skip
    (run / "arm.json").write_text(json.dumps(arm))
    (run / "done.json").write_text("{}")


def test_your_own_table_in_a_few_lines(tmp_path):
    for task in ("push-v3", "throw"):
        for seed in (0, 1, 2):
            _run(tmp_path, task, "ndp-k5", seed, 0.5 + 0.1 * seed)
            _run(tmp_path, task, "ppo", seed, 0.2)
    cells, seeds = load_cells([tmp_path], budgets=[500, 1000])
    assert seeds == [0, 1, 2]
    rl = split_tables(cells)["success"]
    assert {(c.task, c.label) for c in rl} == {
        (t, m) for t in ("push-v3", "throw") for m in ("ndp-k5", "ppo")
    }
    ndp = next(c for c in rl if c.task == "throw" and c.label == "ndp-k5")
    assert fmt_stat(*ndp.stat("final")) == "0.60 +- 0.08"
    md, rows = family_section(rl, seeds, parse_pairs(["ndp-k5:ppo"]))
    assert {r["task"] for r in rows} == {"push-v3", "throw"}  # one test per task
    assert any("ndp-k5" in line for line in md)
    table = success_table(rl, [500, 1000])
    assert any(line.startswith("| throw | ndp-k5 | 3 |") for line in table)


def test_the_documented_example_uses_these_names():
    text = DOC.read_text()
    pattern = (
        r"```python\n(?:# not run:[^\n]*\n)?"  # the snippet's "not run" line (it needs runs)
        r"(from ndp\.experiments\.report import fmt_stat.*?)```"
    )
    block = re.search(pattern, text, re.S)
    assert block is not None
    for name in ("load_cells", "split_tables", "family_section", "parse_pairs", "fmt_stat"):
        assert name in block.group(1)
