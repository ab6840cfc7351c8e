"""A report's CSV: one row per cell (:func:`csv_rows`), written with the provenance columns
last in every row (:func:`write_csv`, also used by the sections' CSVs)."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path

from ndp.experiments.report.cells import Cell, CsvRow
from ndp.experiments.report.provenance import ReportProvenance, stamp
from ndp.experiments.run_kinds import run_kind
from ndp.io import atomic_write_text


def csv_rows(
    rl_cells: Sequence[Cell],
    il_cells: Sequence[Cell],
    budgets: Sequence[int],
    expected: Sequence[int],
    prov: ReportProvenance,
) -> list[CsvRow]:
    rows = []
    for c in [*rl_cells, *il_cells]:
        r: CsvRow = {
            "task": c.task,
            "method": c.label,
            "algo": c.algo,
            "kind": c.kind,
            "n_seeds": len(c.runs),
            "seeds": " ".join(map(str, sorted(c.runs))),
            "missing_seeds": " ".join(map(str, c.missing)),
            "budget": " ".join(sorted({str(i.steps) for i in c.runs.values()})),
        }
        keys = run_kind(c.kind).report.columns(budgets)
        for name, key in keys:
            m, s, _ = c.stat(key)
            r[f"{name}_mean"], r[f"{name}_std"] = m, s
        rows.append({**r, **stamp(prov)})
    return rows


def write_csv(path: Path, rows: Sequence[CsvRow]) -> None:
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    # provenance last, in every row
    cols = [c for c in cols if c not in ("command", "commit", "date")] + [
        "command",
        "commit",
        "date",
    ]
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=cols)
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if isinstance(v, float) and math.isnan(v) else v) for k, v in r.items()})
    atomic_write_text(path, buf.getvalue())  # a report redone over an old one never half-writes
