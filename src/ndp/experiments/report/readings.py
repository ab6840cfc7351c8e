"""Shared parts of the pre-registered readings a study's report applies by code
(``regimes``, ``offpolicy``): the runs of the report's seeds per arm, the seeds x tasks matrix a
stratified test takes, the line naming the arms a reading still waits for.

A reading reads one number per run (by default the **deterministic success area**,
``det_area``) and needs every seed of the report: an arm missing a seed gives no numbers, and is
noted as waited for, so that a reading says what it waits for instead of a verdict.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence

import numpy as np

from ndp.experiments.report import stats
from ndp.experiments.report.cells import Cell

HEAD = "det_area"
"""The number the readings read, unless a reading names another."""


class ArmRuns:
    """The report's cells as ``(task, label) -> [seeds]`` of one number, all seeds or none.

    ``conditional``: arms that belong to a pool only once they have runs (see :meth:`pool`).
    """

    def __init__(
        self, cells: Sequence[Cell], seeds: Sequence[int], conditional: Collection[str] = ()
    ) -> None:
        self.by = {(c.task, c.label): c for c in cells}
        self.labels = {c.label for c in cells if c.numbers}
        self.seeds = list(seeds)
        self.conditional = frozenset(conditional)
        self.waiting: set[str] = set()

    def values(self, task: str, label: str, key: str = HEAD) -> np.ndarray | None:
        """The seeds' numbers [n] of an arm on a task; None (and the arm noted as waited for)
        when a seed is missing or lacks the number."""
        c = self.by.get((task, label))
        out = []
        for s in self.seeds:
            n = c.numbers.get(s) if c is not None else None
            if n is None or math.isnan(n.get(key, math.nan)):
                self.waiting.add(label)
                return None
            out.append(float(n[key]))
        return np.array(out)

    def mean(self, task: str, label: str, key: str = HEAD) -> float:
        """The mean over seeds of an arm on a task; NaN while a seed is missing."""
        v = self.values(task, label, key)
        return math.nan if v is None else float(v.mean())

    def pool(self, labels: Sequence[str]) -> list[str]:
        """A pool's arms: the required ones and the conditional ones that have runs."""
        return [lb for lb in labels if lb not in self.conditional or lb in self.labels]

    def matrix(
        self, tasks: Sequence[str], labels: Sequence[str], key: str = HEAD
    ) -> np.ndarray | None:
        """[seeds, tasks]: on each task the arm named for it; None if any is incomplete."""
        cols = [self.values(t, lb, key) for t, lb in zip(tasks, labels, strict=True)]
        if any(c is None for c in cols):
            return None
        return np.stack([c for c in cols if c is not None], axis=1)

    def waiting_line(self, who: str) -> list[str]:
        """The markdown line naming the arms a reading waits for (none waited for: no line)."""
        if not self.waiting:
            return []
        arms = ", ".join(sorted(self.waiting))
        return [f"Arms {who} for (seeds missing in this report): {arms}.", ""]


def compare(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Two arms' [seeds, tasks] matrices: (the mean over tasks of x - y, the stratified
    permutation p of x > y, and of y > x; both one-sided, as the readings were registered)."""
    d, test = compare_test(x, y)
    return d, test.greater, test.less


def compare_test(x: np.ndarray, y: np.ndarray) -> tuple[float, stats.PermutationResult]:
    """Two arms' [seeds, tasks] matrices: (the mean over tasks of x - y, the stratified
    permutation test: both one-sided p, the two-sided p and how they were computed)."""
    d = float((x.mean(0) - y.mean(0)).mean())
    return d, stats.permutation_tests(x, y)


def one_sided(a: str, b: str) -> str:
    """The heading of a one-sided p that names its direction: ``one-sided p(a > b)``."""
    return f"one-sided p({a} > {b})"


def interval(lo: float, hi: float) -> str:
    """A 95% interval as ``[lo, hi]`` (signed, three decimals); ``n/a (one run)`` where a side
    has a single run and the interval is undefined (NaN)."""
    if math.isnan(lo) or math.isnan(hi):
        return "n/a (one run)"
    return f"[{lo:+.3f}, {hi:+.3f}]"


def fmt(x: float, signed: bool = False) -> str:
    """A reading's number to two decimals; NaN as ``-``."""
    return "-" if math.isnan(x) else (f"{x:+.2f}" if signed else f"{x:.2f}")
