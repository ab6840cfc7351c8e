"""The report's model-selection section (``ndp report --study NAME`` for a study with a
``selection``, such as ``digits-converged``).

A selection maps each model to its candidate arms (the same model at each learning rate of a
grid, every run stopped on its validation split). Per data set and model the candidate with
the lowest mean validation MSE over seeds is chosen (the test split plays no part in the
choice), and its test MSE is reported: the mean over seeds with a 95% percentile-bootstrap
interval, with the epochs to the best validation MSE, how many of its runs the patience rule
stopped (the others reached the epoch cap with the validation MSE still improving within the
patience window: not converged) and the training wall time. Below the
models, the DMP's floor of the data set (:mod:`ndp.il.floor`: least-squares DMP fits to every
test trajectory, per N) says how close any DMP-based model could get at all.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ndp.experiments.report import stats
from ndp.experiments.report.cells import Cell, CsvRow, seed_values
from ndp.experiments.run_kinds import il_data_args
from ndp.il.config import DataConfig

FLOOR_N = (10, 20, 30)
"""Numbers of basis functions of the floor rows (30: the models' DMP)."""


def data_config(task: str) -> DataConfig:
    """The ``DataConfig`` of an imitation study's "task" (a data set name, as
    :func:`ndp.experiments.run_kinds.il_data_args` reads it)."""
    args = il_data_args(task)
    opts = dict(zip(args[::2], args[1::2], strict=True))
    kw: dict[str, Any] = {"source": opts["--data"], "split": opts["--split"]}
    if "--n-train" in opts:
        kw["n_train"] = int(opts["--n-train"])
    return DataConfig(**kw)


def _capped(cell: Cell | None, seeds: Sequence[int]) -> str:
    """`` (cap k/n)`` where k of the cell's n seeds reached the epoch cap (not stopped by
    patience), else ``""``."""
    k = len(seeds) - int(sum(seed_values(cell, "stopped_early", seeds)))
    return f" (cap {k}/{len(seeds)})" if k else ""


def selection_section(
    cells: Sequence[Cell],
    selection: Sequence[tuple[str, tuple[str, ...]]],
    seeds: Sequence[int],
    floor: bool = True,
) -> tuple[list[str], list[CsvRow]]:
    """(Markdown lines, CSV rows) of the selection (see the module docstring).

    Args:
        cells: the report's imitation cells (``task``, ``label``, ``numbers`` per seed).
        selection: (model, candidate arm labels) pairs.
        seeds: the seeds every cell should have; each model's arms are compared on those of
            them that every arm has finished (fewer are marked MISSING in its row).
        floor: add the DMP floor rows (fits every test trajectory of each data set).
    """
    by = {(c.task, c.label): c for c in cells}
    tasks = list(dict.fromkeys(c.task for c in cells))
    md = list(_HEAD)
    rows: list[CsvRow] = []
    for task in tasks:
        for model, labels in selection:
            line, row = _selected(by, task, model, labels, list(seeds))
            md.append(line)
            rows += [row] if row is not None else []
        if floor:
            fmd, frows = _floor_rows(task)
            md += fmd
            rows += frows
    md.append("")
    return md, rows


_HEAD = (
    "## Selected on the validation split",
    "",
    "Per data set and model, the learning rate (arm) with the lowest mean validation MSE "
    "over seeds; its test MSE: mean over seeds [95% percentile-bootstrap interval]. The "
    "test split is scored once, at the end, on each run's best-validation weights. "
    "n: seeds, those every arm of the model has finished (the arms are compared on the "
    "same seeds). Epochs to best: the epoch of the lowest validation MSE (mean over seeds). "
    "Stopped: runs that the patience rule stopped, of n; the others reached the epoch cap "
    "still improving (not converged; an arm marked `(cap k/n)` among the other arms had k "
    "such runs). "
    "Floor: the test MSE of least-squares DMP fits to every test trajectory (`ndp il floor`), "
    "the closest any model using that DMP could get.",
    "",
    "| data | model | chosen arm | n | validation MSE px^2 | test MSE px^2 | epochs to best | "
    "stopped | wall s | other arms (validation MSE) |",
    "|---|---|---|---|---|---|---|---|---|---|",
)
"""The selection section's heading, legend and table head."""


def _selected(
    by: dict[tuple[str, str], Cell], task: str, model: str, labels: Sequence[str],
    expected: list[int],
) -> tuple[str, CsvRow | None]:  # fmt: skip
    """One model's row on one data set: the arm with the lowest mean validation MSE and its
    numbers (Markdown line, CSV row; no row when no seed has every arm finished)."""
    # The arms are compared on the seeds every one of them has finished (all of
    # `seeds` once the study is complete; fewer, marked MISSING, in a report with
    # --allow-missing), so no arm wins on a seed the others have not run.
    seeds = [s for s in expected if all(seed_values(by.get((task, lb)), "val", [s])
                                        for lb in labels)]  # fmt: skip
    if not seeds:
        return (f"| {task} | {model} | - | 0 | - | - | - | - | - | no seed that "
                "every arm has finished yet |"), None  # fmt: skip
    cands = [(float(np.mean(seed_values(by.get((task, lb)), "val", seeds))), lb)
             for lb in labels]  # fmt: skip
    gone = [s for s in expected if s not in seeds]
    n_cell = f"{len(seeds)}" + (f" **MISSING seeds {' '.join(map(str, gone))}**"
                                if gone else "")  # fmt: skip
    best_val, lb = min(cands)
    cell = by[(task, lb)]
    test = seed_values(cell, "mse", seeds)
    lo, hi = stats.bootstrap_ci(test) if test else (math.nan, math.nan)
    ep = seed_values(cell, "best_epoch", seeds)
    wall = seed_values(cell, "wall_s", seeds)
    stopped = int(sum(seed_values(cell, "stopped_early", seeds)))
    others = (
        ", ".join(
            f"`{b}` {a:.3g}{_capped(by[(task, b)], seeds)}" for a, b in sorted(cands) if b != lb
        )
        or "-"
    )
    line = (
        f"| {task} | {model} | `{lb}` | {n_cell} | {best_val:.3g} | "
        f"{np.mean(test):.3g} [{lo:.3g}, {hi:.3g}] | {np.mean(ep):.0f} | "
        f"{stopped}/{len(test)} | {np.mean(wall):.0f} | {others} |"
    )
    return line, {"task": task, "model": model, "arm": lb, "n_seeds": len(test),
                  "seeds": " ".join(map(str, seeds)),
                  "val_mse_px2": best_val, "test_mse_px2_mean": float(np.mean(test)),
                  "test_mse_px2_ci_low": lo, "test_mse_px2_ci_high": hi,
                  "epochs_to_best": float(np.mean(ep)),
                  "n_stopped_by_patience": stopped,
                  "wall_s": float(np.mean(wall))}  # fmt: skip


def _floor_rows(task: str) -> tuple[list[str], list[CsvRow]]:
    """The DMP floor rows of a data set (least-squares fits to every test trajectory)."""
    from ndp.il.floor import dmp_floor

    md: list[str] = []
    rows: list[CsvRow] = []
    for r in dmp_floor(data_config(task), FLOOR_N):
        m = r["mse_px2"]
        md.append(
            f"| {task} | DMP floor, N = {r['n_basis']} | least-squares fit | "
            f"{r['n_test']} test trajectories | - | {m['mean']:.3g} (median "
            f"{m['median']:.3g}) | - | - | {r['fit_s']:.0f} | - |"
        )
        rows.append({"task": task, "model": f"dmp-floor-n{r['n_basis']}",
                     "arm": "fit_dmp", "n_seeds": 0,
                     "test_mse_px2_mean": m["mean"]})  # fmt: skip
    return md, rows
