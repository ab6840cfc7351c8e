"""The report's condition x method section (``ndp report --study NAME`` for a study with
conditions, such as ``release-conditions``).

A condition maps each method to one arm (run label) of the study; arms are shared between
conditions where their settings coincide (:class:`ndp.experiments.studies.Condition`). For
every condition and method this section gives:

- per task: success area, final success at any step and at the final step, each as the mean
  over seeds with a 95% percentile-bootstrap interval;
- over the tasks where every cell has every seed: the IQM of each number over all runs with a
  95% stratified-bootstrap interval, and the probability that NDP beats each other method
  (:mod:`ndp.experiments.stats`, the rliable protocol), with the paper's ordering
  (NDP > PPO-multi > PPO) checked on the IQM of the success area.

Conditions with ``unequal=True`` (the release's unequal goals) carry "UNEQUAL" in every table
and figure.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ndp.experiments import stats

METRICS = (
    ("area", "success area"),
    ("final", "final success (any step)"),
    ("final_last", "final success (final step)"),
)
"""(cell number key, heading) of the numbers each table gives."""
ORDER = ("ndp", "ppo-multi", "ppo")
"""The paper's ordering of the methods, best first."""


def _name(cond: Any) -> str:
    return f"{cond.name} (UNEQUAL)" if cond.unequal else cond.name


def _ci(v: Sequence[float], lo: float, hi: float) -> str:
    return "-" if not len(v) else f"{np.mean(v):.2f} [{lo:.2f}, {hi:.2f}]"


def _values(cell: Any, key: str, seeds: Sequence[int]) -> list[float]:
    out = []
    for s in seeds:
        n = cell.numbers.get(s) if cell is not None else None
        if n is not None and not math.isnan(n[key]):
            out.append(float(n[key]))
    return out


def conditions_section(
    cells: Sequence[Any],
    conditions: Sequence[Any],
    seeds: Sequence[int],
    out: Path,
    foot: str,
    plots: bool = True,
) -> tuple[list[str], list[dict[str, Any]], list[Path]]:
    """(Markdown lines, CSV rows, figures) of the conditions of a study (see the module doc).

    Args:
        cells: the report's RL cells (``task``, ``label``, ``numbers`` per seed).
        conditions: :class:`ndp.experiments.studies.Condition` objects.
        seeds: the seeds every cell should have.
        out: the report's output stem (the figure is ``<out>-conditions.png``).
        foot: provenance line for the figure.
        plots: write the figure.
    """
    by = {(c.task, c.label): c for c in cells}
    tasks = list(dict.fromkeys(c.task for c in cells))
    methods = list(dict.fromkeys(m for cond in conditions for m, _ in cond.methods))
    md = [
        "## Conditions",
        "",
        "Each condition maps every method to one arm of the study (runs shared where settings "
        "coincide). UNEQUAL: the methods do not see the same task distribution on purpose (the "
        "2021 release's condition, reproduced to explain the paper's curves; not a fair "
        "comparison). Per task: mean over seeds [95% percentile-bootstrap interval].",
        "",
    ]
    for cond in conditions:
        md.append(f"- **{_name(cond)}**: {cond.note}; arms: "
                  + ", ".join(f"{m} = `{lb}`" for m, lb in cond.methods))  # fmt: skip
    md.append("")
    rows: list[dict[str, Any]] = []
    for task in tasks:
        md += [
            f"### {task}",
            "",
            "| condition | method | arm | n | " + " | ".join(h for _, h in METRICS) + " |",
            "|---" * (4 + len(METRICS)) + "|",
        ]
        for cond in conditions:
            for m, lb in cond.methods:
                cell = by.get((task, lb))
                vals = []
                row: dict[str, Any] = {"condition": cond.name, "unequal": cond.unequal,
                                       "task": task, "method": m, "arm": lb}  # fmt: skip
                n = 0
                for key, _ in METRICS:
                    v = _values(cell, key, seeds)
                    n = max(n, len(v))
                    lo, hi = stats.bootstrap_ci(v) if v else (math.nan, math.nan)
                    vals.append(_ci(v, lo, hi))
                    row.update({f"{key}_mean": np.mean(v) if v else math.nan,
                                f"{key}_ci_low": lo, f"{key}_ci_high": hi})  # fmt: skip
                row["n_seeds"] = n
                rows.append(row)
                md.append(f"| {_name(cond)} | {m} | `{lb}` | {n} | " + " | ".join(vals) + " |")
        md.append("")
    full = [
        t
        for t in tasks
        if all(
            len(_values(by.get((t, lb)), "final", seeds)) == len(seeds)
            for cond in conditions
            for _, lb in cond.methods
        )
    ]
    over, over_rows = _over_tasks(by, conditions, methods, full, seeds)
    md += over
    rows += over_rows
    pngs = [_plot(over_rows, conditions, out, foot)] if plots and over_rows else []
    md += [f"![{p.stem}]({p.name})" for p in pngs]
    md.append("")
    return md, rows, pngs


def _matrix(
    by: dict[tuple[str, str], Any], label: str, key: str, tasks: Sequence[str], seeds: Sequence[int]
) -> np.ndarray:
    return np.array([[by[(t, label)].numbers[s][key] for t in tasks] for s in seeds], float)


def _over_tasks(
    by: dict[tuple[str, str], Any], conditions: Sequence[Any], methods: Sequence[str],
    full: Sequence[str], seeds: Sequence[int],
) -> tuple[list[str], list[dict[str, Any]]]:  # fmt: skip
    if not full:
        return ["Over tasks: no task has every seed in every cell yet.", ""], []
    md = [
        f"### Over tasks ({len(full)} tasks: {', '.join(full)}; {len(seeds)} seeds each)",
        "",
        "IQM over all runs (tasks x seeds) [95% stratified-bootstrap interval]:",
        "",
        "| condition | method | " + " | ".join(f"IQM {h}" for _, h in METRICS) + " |",
        "|---" * (2 + len(METRICS)) + "|",
    ]
    rows: list[dict[str, Any]] = []
    iqm_area: dict[tuple[str, str], float] = {}
    for cond in conditions:
        for m, lb in cond.methods:
            vals = []
            row: dict[str, Any] = {"condition": cond.name, "unequal": cond.unequal,
                                   "task": "IQM over tasks", "method": m, "arm": lb,
                                   "n_seeds": len(seeds)}  # fmt: skip
            for key, _ in METRICS:
                x = _matrix(by, lb, key, full, seeds)
                point = stats.iqm(x)
                lo, hi = stats.stratified_bootstrap_ci(x, stats.iqm)
                vals.append(f"{point:.2f} [{lo:.2f}, {hi:.2f}]")
                row.update({f"{key}_mean": point, f"{key}_ci_low": lo, f"{key}_ci_high": hi})
                if key == "area":
                    iqm_area[(cond.name, m)] = point
            rows.append(row)
            md.append(f"| {_name(cond)} | {m} | " + " | ".join(vals) + " |")
    md.append("")
    others = [m for m in methods if m != "ndp"]
    if "ndp" in methods and others:
        heads = [f"P(NDP > {o}), {h}" for o in others for k, h in METRICS if k != "final_last"]
        md += [
            "Probability that an NDP run beats a run of the other method on the same task "
            "(ties count half; averaged over tasks) [95% stratified-bootstrap interval]; "
            "0.5 = neither is better. Paper's ordering: NDP > PPO-multi > PPO in the IQM of "
            "the success area.",
            "",
            "| condition | " + " | ".join(heads) + " | paper's ordering |",
            "|---" * (2 + len(heads)) + "|",
        ]
        for cond in conditions:
            lab = dict(cond.methods)
            if "ndp" not in lab:
                continue
            vals = []
            for o in others:
                if o not in lab:
                    vals += ["-", "-"]
                    continue
                for key, _ in METRICS:
                    if key == "final_last":
                        continue
                    x = _matrix(by, lab["ndp"], key, full, seeds)
                    y = _matrix(by, lab[o], key, full, seeds)
                    p = stats.probability_of_improvement(x, y)
                    lo, hi = stats.probability_of_improvement_ci(x, y)
                    vals.append(f"{p:.2f} [{lo:.2f}, {hi:.2f}]")
                    rows.append({"condition": cond.name, "unequal": cond.unequal,
                                 "task": "P(NDP > other)", "method": f"ndp > {o}",
                                 "arm": f"{lab['ndp']} > {lab[o]}", "metric": key,
                                 "p_mean": p, "p_ci_low": lo, "p_ci_high": hi})  # fmt: skip
            ordered = [m for m in ORDER if m in lab]
            holds = all(
                iqm_area[(cond.name, a)] > iqm_area[(cond.name, b)]
                for a, b in itertools.pairwise(ordered)
            )
            md.append(f"| {_name(cond)} | " + " | ".join(vals) + f" | {'yes' if holds else 'no'} |")
        md.append("")
    return md, rows


def _plot(rows: Sequence[dict[str, Any]], conditions: Sequence[Any], out: Path, foot: str) -> Path:
    """``<out>-conditions.png``: IQM with its interval per condition and method, one panel per
    number."""
    import matplotlib

    matplotlib.use("Agg")
    import textwrap

    import matplotlib.pyplot as plt

    iq = [r for r in rows if r["task"] == "IQM over tasks"]
    methods = list(dict.fromkeys(r["method"] for r in iq))
    names = [c.name for c in conditions]
    fig, axes = plt.subplots(1, len(METRICS), figsize=(4.0 * len(METRICS), 1.2 + 0.55 * len(names)),
                             sharey=True, squeeze=False)  # fmt: skip
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (key, head) in zip(axes[0], METRICS, strict=True):
        for j, m in enumerate(methods):
            for i, cname in enumerate(names):
                r = next((r for r in iq if r["condition"] == cname and r["method"] == m), None)
                if r is None:
                    continue
                y = len(names) - 1 - i + (len(methods) / 2 - j - 0.5) * 0.22
                ax.plot([r[f"{key}_ci_low"], r[f"{key}_ci_high"]], [y, y], color=colors[j], lw=2.5)
                ax.plot([r[f"{key}_mean"]], [y], "o", color=colors[j], ms=4,
                        label=m if i == 0 else None)  # fmt: skip
        ax.set_title(f"IQM {head}", fontsize=9)
        ax.set_xlim(-0.02, 1.02)
        ax.grid(alpha=0.3, axis="x")
    labels = [f"{c.name}\n(UNEQUAL)" if c.unequal else c.name for c in conditions]
    axes[0][0].set_yticks(range(len(names))[::-1], labels, fontsize=8)
    # one legend above the panels, where it cannot cover a point near 1.0
    handles, names_ = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, names_, loc="upper center", ncol=max(1, len(methods)), fontsize=7,
               frameon=False)  # fmt: skip
    top = 1.0 - 0.28 / fig.get_figheight()
    lines = textwrap.wrap(foot, 170) or [""]
    fig.text(0.01, 0.005, "\n".join(lines), fontsize=5, color="0.35", ha="left", va="bottom")
    fig.tight_layout(rect=(0, 0.02 + 0.02 * len(lines), 1, top))
    path = out.with_name(f"{out.name}-conditions.png")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
