"""Cells: the runs of one task x method label, one per seed (:func:`build_cells`), with the
numbers of each run (:meth:`Cell.stat`: mean, population std and count over seeds).

Every cell must hold the same seeds; :func:`missing_message` names the cells that do not.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ndp.experiments.report.fresh import FreshEval
from ndp.experiments.rows import RunInfo
from ndp.experiments.run_kinds import run_kind

CsvRow = dict[str, str | float]
"""One row of a report's CSV (:func:`ndp.experiments.report.csvs.write_csv`): column -> text or a
number (an int or a bool is a number here too)."""


class MissingSeedsError(ValueError):
    """Cells of the report lack seeds (the message names them)."""


@dataclass
class Cell:
    task: str
    label: str
    kind: str
    algo: str
    runs: dict[int, RunInfo] = field(default_factory=dict)
    unfinished: dict[int, RunInfo] = field(default_factory=dict)
    missing: list[int] = field(default_factory=list)
    numbers: dict[int, dict[str, Any]] = field(default_factory=dict)

    def stat(self, key: str) -> tuple[float, float, int]:
        v = np.array([n[key] for n in self.numbers.values() if not math.isnan(n[key])])
        if len(v) == 0:
            return math.nan, math.nan, 0
        return float(v.mean()), float(v.std()), len(v)

    def marker(self) -> str:
        return f"MISSING seeds {' '.join(map(str, self.missing))}" if self.missing else ""

    def n_seeds_cell(self) -> str:
        """The table's ``n`` cell: seeds that ran, and the missing ones in bold."""
        return f"{len(self.runs)}" + (f" **{self.marker()}**" if self.missing else "")


def seed_values(cell: Cell | None, key: str, seeds: Sequence[int]) -> list[float]:
    """The number ``key`` of each of ``seeds`` that ``cell`` has and that is not NaN (none
    without a cell)."""
    out = []
    for s in seeds:
        n = cell.numbers.get(s) if cell is not None else None
        if n is not None and not math.isnan(float(n[key])):
            out.append(float(n[key]))
    return out


def fmt_stat(m: float, s: float, n: int, digits: int = 2) -> str:
    return "-" if n == 0 or math.isnan(m) else f"{m:.{digits}f} +- {s:.{digits}f}"


def build_cells(
    infos: Sequence[RunInfo],
    seeds: Sequence[int] | None,
    tasks: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    arm_tasks: Mapping[str, Sequence[str]] | None = None,
) -> tuple[list[Cell], list[int]]:
    """Cells (task x label, every task with every label of its kind; in the order of ``tasks``
    and ``methods`` when given), the expected seeds. ``arm_tasks``: labels that run on some
    tasks only (a study's arms with ``tasks``) get no cell, so no missing seeds, elsewhere."""
    only = arm_tasks or {}
    # each filter against every run found (a wrong --methods is named as such, not as tasks)
    for what, asked, found in (
        ("tasks", tasks, {i.task for i in infos}),
        ("methods", methods, {i.label for i in infos}),
    ):
        unknown = sorted(set(asked or ()) - found)
        if unknown:
            raise ValueError(
                f"report: no runs of the {what} {unknown} in these directories (found: "
                f"{', '.join(sorted(found)) or 'none'})"
            )
    infos = [
        i for i in infos if (not tasks or i.task in tasks) and (not methods or i.label in methods)
    ]
    expected = sorted(set(seeds) if seeds else {i.seed for i in infos})
    cells: dict[tuple[str, str], Cell] = {}
    by_kind: dict[str, list[RunInfo]] = {}
    for i in infos:
        by_kind.setdefault(run_kind(i.kind).report.table, []).append(i)
    for group in by_kind.values():
        # the order given (--tasks, --methods), else the order the runs were found in
        task_order = list(dict.fromkeys(i.task for i in group))
        label_order = list(dict.fromkeys(i.label for i in group))
        if tasks:
            task_order = [t for t in tasks if t in task_order]
        if methods:
            label_order = [m for m in methods if m in label_order]
        algo_of = {i.label: i.algo for i in group}
        kind_of = {i.label: i.kind for i in group}
        for t in task_order:
            for lb in label_order:
                cells[(t, lb)] = Cell(t, lb, kind_of[lb], algo_of[lb])
        for i in group:
            c = cells[(i.task, i.label)]
            if i.seed not in expected:
                continue
            if i.seed in c.runs or i.seed in c.unfinished:
                other = (c.runs.get(i.seed) or c.unfinished[i.seed]).path
                raise ValueError(
                    f"report: two runs of {i.task} x {i.label} seed {i.seed}: {other} and {i.path}"
                )
            (c.runs if i.finished else c.unfinished)[i.seed] = i
    for key, c in list(cells.items()):  # an arm's task it does not run on: no cell at all
        if c.label in only and c.task not in only[c.label] and not (c.runs or c.unfinished):
            del cells[key]
    for c in cells.values():
        c.missing = [s for s in expected if s not in c.runs]
    return list(cells.values()), expected


def missing_message(cells: Sequence[Cell], expected: Sequence[int]) -> str:
    bad = [c for c in cells if c.missing]
    parts = []
    for c in bad[:10]:
        unf = [s for s in c.missing if s in c.unfinished]
        extra = f" ({len(unf)} unfinished: seeds {unf})" if unf else ""
        why = [f"seed {s}: {c.unfinished[s].problem}" for s in unf if c.unfinished[s].problem]
        extra += f" [{'; '.join(why)}]" if why else ""
        parts.append(f"{c.task} x {c.label}: seeds {c.missing} missing{extra}")
    more = f"; and {len(bad) - 10} more cells" if len(bad) > 10 else ""
    return (
        f"report: seeds missing from {len(bad)} of {len(cells)} cells (every cell needs seeds "
        f"{list(expected)}): "
        + "; ".join(parts)
        + more
        + ". Refused: finish those runs (ndp sweep continues them), narrow --seeds / --tasks / "
        "--methods, or pass --allow-missing to mark the cells instead."
    )


def split_tables(cells: Sequence[Cell]) -> dict[str, list[Cell]]:
    """The cells by the report table of their run kind: ``success`` (RL), ``imitation``,
    ``cloning``, each in the cells' order."""
    tables: dict[str, list[Cell]] = {"success": [], "imitation": [], "cloning": []}
    for c in cells:
        tables[run_kind(c.kind).report.table].append(c)
    return tables


def compute_numbers(
    cells: Sequence[Cell], budgets: Sequence[int], eval_episodes: int | FreshEval = 0
) -> None:
    """Fill each cell's :attr:`Cell.numbers`: per finished run, the numbers of its kind's
    report row (RL: success at each of ``budgets`` env steps, area, final, ...; with
    ``eval_episodes`` the deterministic success of its final policy: a :class:`FreshEval`, or
    a number of episodes from the default seed, as before; 0: none)."""
    fresh = eval_episodes if isinstance(eval_episodes, FreshEval) else FreshEval(eval_episodes)
    for c in cells:
        kind = run_kind(c.kind)
        c.numbers = {
            s: kind.report.numbers(i, budgets, fresh, kind.evaluable) for s, i in c.runs.items()
        }
