"""A registered family of comparisons (``ndp report ... --compare A:B [C:D ...]``): the tests a
pre-registered reading names, each pair on each task (and, with ``pooled``, over the tasks),
Holm-adjusted over the whole family, with the paired sign-flip test beside the unpaired one.

A reading such as "live - stale for NDP and PPO-multi on each task; 4 tests" (docs/rl-release.md
part 3, reading 2) is ``--compare ndp-nostale:ndp-k5 ppo-multi-nostale:ppo-multi-k5`` over two
tasks. The pairwise table of a report without a study (every pair, Holm per task) answers a
different question; this section is the family the reading registered, so its Holm p is the one
to read.

Every number is the headline (the deterministic success area, ``det_area``) unless the runs lack
it, then the training-episode area. Runs must have every seed of the report (the report refuses
missing seeds unless ``--allow-missing``; a pair with a missing seed is left out and named).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ndp.experiments.report import paired
from ndp.experiments.report.cells import Cell, CsvRow
from ndp.experiments.report.conditions import (
    P_HEADS,
    SIGNIFICANCE_NOTE,
    _difference,
    metrics_of,
    pvalue_cells,
    with_holm,
)
from ndp.experiments.report.readings import ArmRuns, interval

__all__ = ["ALL_TASKS", "HOLM_OVER", "check_pairs", "family_section", "parse_pairs"]

ALL_TASKS = "all tasks"
"""The ``task`` of a pooled row."""


def parse_pairs(specs: Sequence[str]) -> list[tuple[str, str]]:
    """``["A:B", ...]`` -> ``[("A", "B"), ...]``: A minus B is tested.

    Raises:
        ValueError: a spec is not two non-empty labels joined by one ':', names the same label
            twice, or repeats a pair.
    """
    out: list[tuple[str, str]] = []
    for s in specs:
        a, sep, b = str(s).partition(":")
        if not sep or not a or not b or ":" in b or a == b:
            raise ValueError(
                f"compare: expected pairs 'A:B' of two different method labels, got {s!r}"
            )
        if (a, b) in out:
            raise ValueError(f"compare: the pair {s!r} is named twice")
        out.append((a, b))
    return out


def family_section(
    cells: Sequence[Cell],
    seeds: Sequence[int],
    pairs: Sequence[tuple[str, str]],
    pooled: bool = False,
    holm_over: str = "all",
) -> tuple[list[str], list[CsvRow]]:
    """The family of ``pairs`` on every task of ``cells`` (and over all tasks with ``pooled``).

    Per row: the mean difference A - B of the headline number, its Welch 95% t-interval, the
    permutation p (two-sided, exact up to ``stats.PERMUTATION_EXACT_LIMIT`` splits,
    stratified by task when pooled), Holm's adjustment over **every row of the family**, and
    the paired sign-flip p over the seeds both arms ran (:mod:`ndp.experiments.report.paired`),
    which is given beside the unpaired test and does not replace it.

    Args:
        cells: the report's RL cells (``task``, ``label``, ``numbers`` per seed).
        seeds: the report's seeds (every pair's arms need all of them).
        pairs: ``(A, B)`` labels; A - B is tested.
        pooled: add one row per pair over all tasks to the family.
        holm_over: which rows the registered family holds, the others being descriptions
            (their tests given, no Holm p, no verdict word): 'all', 'pooled' (the rows over all
            tasks; per-task rows described) or 'tasks'.

    Returns:
        (markdown lines, CSV rows); no pair with runs: a markdown line saying so, no rows.
    """
    metrics, key = metrics_of(cells)
    names = dict(metrics)
    runs = ArmRuns(cells, seeds)
    tasks = list(dict.fromkeys(c.task for c in cells))
    family = [r for a, b in pairs for r in _pair_rows(runs, tasks, a, b, key, pooled)]
    missing = sorted(runs.waiting)
    if not family:
        return [f"Family: no pair has runs of every seed ({', '.join(missing) or 'none'}).", ""], []
    if holm_over not in HOLM_OVER:
        raise ValueError(f"holm_over: expected one of {', '.join(HOLM_OVER)}, got {holm_over!r}")
    tested = [r for r in family if _in_family(r, holm_over)]
    if not tested:
        raise ValueError(
            f"holm_over: {holm_over!r} leaves no row in the family (pooled rows need "
            "--compare-pooled and two tasks or more)"
        )
    with_holm(tested)
    for r in family:
        if not _in_family(r, holm_over):
            r.update({"p_holm": math.nan, "holm_m": 0, "significant": False})
    return _markdown(family, names, missing, pooled, holm_over), family


def _pair_rows(
    runs: ArmRuns, tasks: Sequence[str], a: str, b: str, key: str, pooled: bool
) -> list[CsvRow]:
    """The rows of the pair ``a`` - ``b``: one per task where both arms have every seed, and
    with ``pooled`` one over all tasks where that is every task (two or more)."""
    rows = []
    per_task: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for task in tasks:
        x, y = runs.values(task, a, key), runs.values(task, b, key)
        if x is None or y is None:
            continue
        per_task[task] = (x, y)
        row = _row(task, a, b, x[:, None], y[:, None], key)
        row.update(_paired_cols(paired.paired_sign_flip(x, y) if len(x) >= 2 else None))
        rows.append(row)
    if pooled and len(per_task) >= 2 and len(per_task) == len(tasks):
        xs = np.stack([v[0] for v in per_task.values()], axis=1)  # [seeds, tasks]
        ys = np.stack([v[1] for v in per_task.values()], axis=1)
        row = _row(ALL_TASKS, a, b, xs, ys, key)
        row.update(_paired_cols(paired.paired_pooled(per_task)))
        rows.append(row)
    return rows


HOLM_OVER = ("all", "pooled", "tasks")
"""Values of ``family_section(holm_over=...)`` / ``ndp report --compare-holm``."""


def _in_family(row: CsvRow, holm_over: str) -> bool:
    pooled = row["task"] == ALL_TASKS
    return holm_over == "all" or (holm_over == "pooled") == pooled


def _row(task: str, a: str, b: str, x: np.ndarray, y: np.ndarray, key: str) -> CsvRow:
    """One test: runs ``x`` [n, tasks] of ``a`` against ``y`` [n, tasks] of ``b``."""
    return {"task": task, "metric": key, "method": f"{a} vs {b}", "a": a, "b": b,
            "n_a": len(x), "n_b": len(y), "mean_a": float(x.mean(0).mean()),
            "mean_b": float(y.mean(0).mean()), **_difference(x, y)}  # fmt: skip


def _paired_cols(r: paired.PairedResult | None) -> CsvRow:
    """The paired test's columns (None: one seed, no paired test: NaN)."""
    if r is None:
        return {"p_paired": math.nan, "paired_pairs": 1, "paired_method": "one seed: none"}
    return {"p_paired": r.p, "paired_pairs": r.n_pairs, "paired_method": r.method}


def _markdown(
    family: Sequence[CsvRow],
    names: dict[str, str],
    missing: Sequence[str],
    pooled: bool,
    holm_over: str = "all",
) -> list[str]:
    m = sum(_in_family(r, holm_over) for r in family)
    scope = {
        "all": "each pair on each task" + (" and over all tasks" if pooled else ""),
        "pooled": "each pair over all tasks; the per-task rows are descriptions (no Holm p)",
        "tasks": "each pair on each task; the rows over all tasks are descriptions (no Holm p)",
    }[holm_over]
    which = f"all {m} rows of this table" if m == len(family) else f"the {m} tested rows"
    metric = names.get(str(family[0]["metric"]), "the area")
    md = [
        f"Registered family ({m} tests: {scope}): {metric}, "
        "A - B with its Welch 95% t-interval; unpaired permutation test over runs (labels "
        "exchanged between the two arms' runs, stratified by task over all tasks); the paired "
        "sign-flip p over the seeds both arms ran is beside it and does not replace it. "
        + SIGNIFICANCE_NOTE.format(family=which, floor=""),
        "",
        f"| task | A vs B | runs | mean A | mean B | A - B | 95% t-interval | {P_HEADS} "
        "| paired p (sign-flip) |",
        "|---" * (7 + P_HEADS.count("|") + 1 + 1) + "|",
    ]
    for r in family:
        md.append(
            f"| {r['task']} | {r['method']} | {r['n_a']} + {r['n_b']} | {r['mean_a']:.3f} "
            f"| {r['mean_b']:.3f} | {r['diff_mean']:+.3f} "
            f"| {interval(float(r['diff_t_low']), float(r['diff_t_high']))} "
            f"| {pvalue_cells(r) if r['holm_m'] else _described(r)} "
            f"| {r['p_paired']:.3g} ({r['paired_method']}) |"
        )
    md.append("")
    if missing:
        md += [f"Left out of the family (a seed missing): {', '.join(missing)}.", ""]
    return md


def _described(r: CsvRow) -> str:
    """The p columns of a row outside the family: its tests, no Holm p and no verdict."""
    return (f"{r['p_two_sided']:.3g} | - (description) | - | {r['p_a_greater']:.3g} "
            f"| {r['p_b_greater']:.3g} | {r['p_method']}")  # fmt: skip


def check_pairs(pairs: Sequence[tuple[str, str]], labels: Sequence[str]) -> None:
    """Every label of ``pairs`` is one of the report's methods.

    Raises:
        ValueError: naming ``compare``, the unknown labels and the known ones.
    """
    known = set(labels)
    unknown = sorted({x for p in pairs for x in p if x not in known})
    if unknown:
        raise ValueError(
            f"compare: {', '.join(unknown)} is not a method of this report "
            f"(its methods: {', '.join(sorted(known)) or 'none'})"
        )
