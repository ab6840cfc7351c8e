"""A report's CSV: one row per cell (:func:`csv_rows`), written with the provenance columns
last in every row (:func:`write_csv`, also used by the sections' CSVs)."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ndp.experiments.report.cells import Cell
from ndp.experiments.run_kinds import run_kind
from ndp.io import atomic_write_text


def csv_rows(
    rl_cells: Sequence[Cell],
    il_cells: Sequence[Cell],
    budgets: Sequence[int],
    expected: Sequence[int],
    prov: dict[str, Any],
) -> list[dict[str, Any]]:
    rows = []
    for c in [*rl_cells, *il_cells]:
        r: dict[str, Any] = {
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
        rows.append(
            {**r, "command": prov["command"], "commit": prov["commit"], "date": prov["date"]}
        )
    return rows


def write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
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
