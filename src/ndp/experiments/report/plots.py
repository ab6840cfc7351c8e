"""A report's figures: one learning-curve figure per task and curve (mean +- std band over
seeds; :func:`plot_all`) and the final success over tasks (:func:`plot_over_tasks`)."""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ndp.experiments.report.cells import Cell
from ndp.experiments.report.markdown import task_grid
from ndp.experiments.report.provenance import ReportProvenance, figure_foot
from ndp.experiments.rows import has_det
from ndp.io import atomic_savefig


def plot_all(
    rl_cells: Sequence[Cell], il_cells: Sequence[Cell], out: Path, prov: ReportProvenance
) -> list[Path]:
    """Every figure of a report: per task its deterministic-evaluation curves (where runs have
    them), its training-success curves (RL) or test-MSE curves (imitation), each
    ``<out>-<task>[-det].png``; with 3 tasks or more first ``<out>-over-tasks.png``. Each
    figure carries ``prov``'s command, commit and date."""
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    foot = figure_foot(prov)
    foot_lines = textwrap.wrap(foot, 150) or [""]
    meta = {"Description": foot, "Software": "ndp report"}
    panels: list[tuple[Sequence[Cell], str, str, str]] = [
        (rl_cells, "env steps", "success (any step, training)", "curve"),
        (il_cells, "epoch", "test MSE (px^2)", "curve"),
    ]
    if has_det(rl_cells):
        panels.insert(
            0, (rl_cells, "env steps", "success (any step, deterministic evaluation)", "det_curve")
        )
    paths = []
    for cells, xlabel, ylabel, curve_key in panels:
        for task in dict.fromkeys(c.task for c in cells):
            tcells = [c for c in cells if c.task == task]
            axes = (xlabel, ylabel, curve_key, cells is rl_cells)
            path = _task_figure(task, tcells, axes, out, foot_lines, meta)
            if path is not None:
                paths.append(path)
    if len({c.task for c in rl_cells}) >= 3:
        paths.insert(0, plot_over_tasks(rl_cells, out, foot_lines, meta))
    return paths


def _curves(
    tcells: Sequence[Cell], curve_key: str, grid: np.ndarray
) -> list[tuple[Cell, list[np.ndarray]]]:
    """Per cell with the curve: (the cell, its runs' curves interpolated on ``grid``)."""
    out = []
    for c in tcells:
        curves = []
        for n in c.numbers.values():
            x, y = n[curve_key]
            if len(x):
                curves.append(np.interp(grid, x, y, left=np.nan, right=np.nan))
        if curves:
            out.append((c, curves))
    return out


def _y_label(ylabel: str, tcells: Sequence[Cell], is_rl: bool) -> str:
    """The y label; for imitation, the split the drawn curves score."""
    if is_rl:
        return ylabel
    kinds = {n["curve_of"] for c in tcells for n in c.numbers.values()}
    if kinds == {"validation"}:
        return "validation MSE (px^2)"
    if len(kinds) > 1:
        return "test MSE, or validation MSE where test is scored once (px^2)"
    return ylabel


def _task_figure(
    task: str,
    tcells: Sequence[Cell],
    axes: tuple[str, str, str, bool],
    out: Path,
    foot_lines: list[str],
    meta: dict[str, str],
) -> Path | None:
    """One task's figure: one line per method (mean +- std band over seeds), dashed where
    seeds are missing; ``axes`` is (x label, y label, curve key, RL cells?). None (nothing
    written) when no run of the task has the curve."""
    import matplotlib.pyplot as plt

    xlabel, ylabel, curve_key, is_rl = axes
    top = max((i.steps for c in tcells for i in c.runs.values()), default=1)
    grid = np.linspace(0, top, 101)
    drawn = _curves(tcells, curve_key, grid)
    if not drawn:  # no run of this task has the curve (e.g. trained without evaluation)
        return None
    fig, ax = plt.subplots(figsize=(6.4, 4.2 + 0.1 * len(foot_lines)))
    for c, curves in drawn:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m, s = np.nanmean(curves, 0), np.nanstd(curves, 0)
        name = f"{c.label} (n={len(curves)})" + (f" {c.marker()}" if c.missing else "")
        lw, ls = (1.6, "-") if not c.missing else (1.0, "--")
        (line,) = ax.plot(grid, m, label=name, lw=lw, ls=ls)
        ax.fill_between(grid, m - s, m + s, alpha=0.18, color=line.get_color(), lw=0)
    ax.set_title(task + ("  [MISSING SEEDS]" if any(c.missing for c in tcells) else ""))
    ax.set_xlim(0, top)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(_y_label(ylabel, tcells, is_rl))
    if is_rl:
        ax.set_ylim(-0.02, 1.02)
    else:
        ax.set_yscale("log")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.text(0.01, 0.005, "\n".join(foot_lines), fontsize=5, color="0.35", ha="left", va="bottom")
    fig.tight_layout(rect=(0, 0.01 + 0.022 * len(foot_lines), 1, 1))
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", task)
    suffix = "-det" if curve_key == "det_curve" else ""
    path = out.with_name(f"{out.name}-{safe}{suffix}.png")
    atomic_savefig(fig, path, dpi=80, metadata=meta)
    plt.close(fig)
    return path


def plot_over_tasks(
    cells: Sequence[Cell],
    out: Path,
    foot_lines: list[str],
    meta: dict[str, str],
) -> Path:
    """``<out>-over-tasks.png``: final success (mean +- std over seeds) per task, one bar per
    method, tasks top to bottom in the table's order (MT50's one-figure summary)."""
    import matplotlib.pyplot as plt

    tasks, labels, by, complete = task_grid(cells)
    full = np.array([t in complete for t in tasks])
    height = 0.8 / len(labels)
    fig, ax = plt.subplots(figsize=(6.4, 1.2 + 0.22 * len(tasks) * max(1, len(labels) / 2)))
    y0 = np.arange(len(tasks))[::-1]
    for i, lb in enumerate(labels):
        stats = [by[(t, lb)].stat("final") for t in tasks]
        m = np.array([st[0] for st in stats], float)
        sd = np.nan_to_num(np.array([st[1] for st in stats], float))
        n = max((st[2] for st in stats), default=0)
        ax.barh(
            y0 + (len(labels) / 2 - i - 0.5) * height,
            m,
            height=height,
            xerr=sd,
            error_kw={"lw": 0.6},
            label=f"{lb} (mean over tasks {np.mean(m[full]) if full.any() else np.nan:.3f}; "
            f"{n} seed{'s' if n != 1 else ''})",
        )
    ax.set_yticks(y0, tasks, fontsize=6)
    ax.set_ylim(-0.6, len(tasks) - 0.4)
    ax.set_xlim(0, 1.02)
    ax.set_xlabel("final success (last 10% of training updates)")
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=7, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=min(2, len(labels)))
    fig.suptitle(f"final success over {len(tasks)} tasks", fontsize=10)
    fig.text(0.01, 0.002, "\n".join(foot_lines), fontsize=5, color="0.35", ha="left", va="bottom")
    fig.tight_layout(rect=(0, 0.004 + 0.012 * len(foot_lines), 1, 1))
    path = out.with_name(f"{out.name}-over-tasks.png")
    atomic_savefig(fig, path, dpi=80, metadata=meta)
    plt.close(fig)
    return path
