"""The report row of each run kind: the numbers one run contributes to its table.

A run kind (:data:`ndp.experiments.run_kinds.RUN_KINDS`) names its :class:`ReportRow`: which
table of ``ndp report`` its runs join (runs of one table are compared with each other), the
numbers read from one run directory, and the CSV columns those numbers fill. The report itself
(:mod:`ndp.experiments.report`) has no branch per kind: a new kind of run is a new row here.

Rows:

- :data:`SUCCESS_ROW` (``ndp rl train``, the SB3 reference): success over env steps from the
  training episodes (area, at budgets, final), the periodic deterministic evaluation, and the
  report's own deterministic evaluation (``det``);
- :data:`IMITATION_ROW` (``ndp il train``): test MSE / DTW, best validation epoch, curve;
- :data:`CLONING_ROW` (behaviour cloning): closed-loop success, fit, jerk, SPARC.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ndp.io import atomic_write_text

if TYPE_CHECKING:
    from ndp.experiments.report.cells import Cell
    from ndp.experiments.report.fresh import FreshEval
    from ndp.runs.session import Manifest


@dataclass
class RunInfo:
    """One run directory, identified."""

    path: Path
    task: str
    label: str
    algo: str
    seed: int
    steps: int
    """Budget: env steps (RL), epochs (imitation)."""
    kind: str
    """Its run kind: a key of :data:`ndp.experiments.run_kinds.RUN_KINDS` (``"rl"``,
    ``"sb3"``, ``"il"``, ``"bc"``)."""
    finished: bool = False
    commits: list[str] = field(default_factory=list)
    fingerprints: list[dict[str, str]] = field(default_factory=list)
    """The environment fingerprints of its sessions (:func:`ndp.runs.run_fingerprints`)."""
    problem: str = ""
    """Why a run that says it is finished does not count (e.g. its metrics.csv was cut)."""
    executed: int | None = None
    """Env steps the simulator executed, where a finished RL run executed fewer than its budget
    (None otherwise): a chunked run whose episodes end mid-decision (e.g. 150-step episodes
    at k = 20) plans its updates in sub-step slots, and the cut decision's unexecuted sub-steps
    fill slots that no simulator step took."""
    manifest: Manifest | None = None
    """The run's run.json as read once when the run was identified (None: older runs, or
    unreadable)."""


def _json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None


# the curve statistics every success table uses (ndp.experiments.study re-exports them)


def smooth(y: np.ndarray, window: int) -> np.ndarray:
    """Trailing moving average over ``window`` points (fewer at the start)."""
    c = np.cumsum(np.insert(np.asarray(y, dtype=np.float64), 0, 0.0))
    i = np.arange(1, len(y) + 1)
    lo = np.maximum(0, i - window)
    return (c[i] - c[lo]) / (i - lo)


def success_area(x: np.ndarray, y: np.ndarray, steps: int, points: int = 101) -> float:
    """The success curve averaged over [0, steps] (0 before the first logged update)."""
    grid = np.linspace(0, steps, points)
    return float(np.trapezoid(np.interp(grid, x, y, left=0.0), grid) / steps)


def final_success(y: np.ndarray) -> float:
    """Mean of the last 10% of the updates (at least one)."""
    return float(np.mean(y[int(len(y) * 0.9) :])) if len(y) >= 10 else float(y[-1])


def _last_tenth(v: np.ndarray) -> float:
    v = v[~np.isnan(v)]
    if len(v) == 0:
        return math.nan
    return float(np.mean(v[int(len(v) * 0.9) :])) if len(v) >= 10 else float(v[-1])


def success_at(x: np.ndarray, y: np.ndarray, b: float, budget: int) -> float:
    """Mean success over the updates in the last 10% of [0, b] (NaN past the run's budget)."""
    if b > budget * (1 + 1e-9) or len(x) == 0:
        return math.nan
    hi = b if b < budget else math.inf
    sel = (x > 0.9 * b) & (x <= hi)
    if sel.any():
        return float(np.mean(y[sel]))
    before = x <= hi
    return float(y[before][-1]) if before.any() else math.nan


def rl_numbers(info: RunInfo, budgets: Sequence[float]) -> dict[str, Any]:
    """One RL run's numbers and its curve."""
    from ndp.runs import read_metrics  # (torch stays out of the run-kind table's import)

    rows = read_metrics(info.path)
    x = np.array([r.get("global_step", math.nan) for r in rows], dtype=np.float64)
    y = np.array([r.get("charts/success_any", math.nan) for r in rows], dtype=np.float64)
    y_last = np.array([r.get("charts/success_final", math.nan) for r in rows], dtype=np.float64)
    key = "charts/episode_return_live"
    if not rows or key not in rows[0]:
        key = "charts/episode_return"
    ret = np.array([r.get(key, math.nan) for r in rows], dtype=np.float64)
    keep = ~np.isnan(y)
    xs, ys = x[keep], y[keep]
    out: dict[str, Any] = {
        "area": success_area(xs, ys, info.steps) if len(xs) else math.nan,
        "final": final_success(ys) if len(ys) else math.nan,
        "final_last": _last_tenth(y_last),
        "return": _last_tenth(ret),
        "curve": (xs, smooth(ys, max(1, len(ys) // 20)) if len(ys) else ys),
    }
    for b in budgets:
        out[f"at:{int(b)}"] = success_at(xs, ys, b, info.steps)
    out.update(det_numbers(rows))
    return out


DET_KEYS = ("det_area", "det_final", "det_final_last")
"""The numbers of a run's periodic deterministic evaluation (:func:`det_numbers`)."""


def det_numbers(rows: Sequence[dict[str, float]]) -> dict[str, Any]:
    """A run's periodic deterministic evaluation (``eval/*`` columns, ndp.rl.periodic_eval):
    ``det_area`` the mean of ``eval/success_any`` over its evaluations (taken at about equal
    env-step intervals: the deterministic success area), ``det_final`` / ``det_final_last``
    the last evaluation's success at any step / at the final step (the final policy), and
    ``det_curve`` (env steps, success) of every evaluation; NaN and an empty curve for a run
    without evaluations (trained before the option, or with ``--eval-every 0``)."""
    x = np.array([r.get("global_step", math.nan) for r in rows], dtype=np.float64)
    y = np.array([r.get("eval/success_any", math.nan) for r in rows], dtype=np.float64)
    y_last = np.array([r.get("eval/success_final", math.nan) for r in rows], dtype=np.float64)
    keep = ~np.isnan(y)
    if not keep.any():
        return {**dict.fromkeys(DET_KEYS, math.nan), "det_curve": (x[keep], y[keep])}
    return {
        "det_area": float(np.mean(y[keep])),
        "det_final": float(y[keep][-1]),
        "det_final_last": float(y_last[keep][-1]),
        "det_curve": (x[keep], y[keep]),
    }


def has_det(cells: Sequence[Cell]) -> bool:
    """Whether any run of ``cells`` has a periodic deterministic evaluation."""
    return any(
        not math.isnan(n.get("det_area", math.nan)) for c in cells for n in c.numbers.values()
    )


def il_numbers(info: RunInfo) -> dict[str, Any]:
    """One imitation run's test MSE / DTW and its test-MSE curve (x: epochs)."""
    from ndp.runs import read_metrics

    rows = read_metrics(info.path)
    x = np.array([r.get("epoch", math.nan) for r in rows], dtype=np.float64)
    y = np.array([r.get("test/mse_px2", math.nan) for r in rows], dtype=np.float64)
    keep = ~np.isnan(y)
    v = np.array([r.get("val/mse_px2", math.nan) for r in rows], dtype=np.float64)
    ev = _json(info.path / "eval.json") or {}
    done = _json(info.path / "done.json") or {}
    last = float(y[keep][-1]) if keep.any() else math.nan
    mse = (ev.get("test_mse_px2") or {}).get("mean", last)
    dtw = (ev.get("test_dtw_px") or {}).get("mean", math.nan)
    has_val = bool((~np.isnan(v)).any())
    best = int(np.nanargmin(v)) if has_val else -1
    curve, curve_of = (x[keep], y[keep]), "test"
    if has_val and keep.sum() < 2:  # test scored once at the end: draw the validation curve
        curve, curve_of = (x[~np.isnan(v)], v[~np.isnan(v)]), "validation"
    wall = np.array([r.get("time/epoch_s", math.nan) for r in rows], dtype=np.float64)
    return {
        "mse": float(mse),
        "dtw": float(dtw),
        "val": float(v[best]) if has_val else math.nan,
        "best_epoch": float(x[best]) if has_val else math.nan,
        "epochs": float(x[-1]) if len(x) else math.nan,
        "wall_s": float(np.nansum(wall)) if len(wall) else math.nan,
        "stopped_early": done.get("reason") == "early stop",
        "curve": curve,
        "curve_of": curve_of,
    }


def bc_numbers(info: RunInfo) -> dict[str, Any]:
    """One behaviour-cloning run's closed-loop evaluation (``eval.json`` of
    :mod:`ndp.experiments.sweep.bc_job`): success, fit (last validation loss), jerk, SPARC."""
    ev = _json(info.path / "eval.json") or {}

    def num(key: str) -> float:
        v = ev.get(key)
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan

    return {k: num(k) for k in ("success", "val_loss", "jerk", "sparc")}


DET_EVAL_FILE = "eval-det-e{episodes}.json"
"""Per-run cache of the report's deterministic evaluation on the default seeds (``ndp rl eval``,
episode seeds from ``ndp.rl.config.EVAL_SEED``). On other seeds the report reads and writes the
file of ``ndp rl eval --mode deterministic --save`` (:data:`ndp.rl.evaluate.EVAL_FILE`)."""


def det_eval_name(episodes: int, seed: int) -> str:
    """The file in a run that holds its deterministic success over ``episodes`` episodes from
    reset seed ``seed``: :data:`DET_EVAL_FILE` on the default seed, else the file of ``ndp rl eval
    --mode deterministic --save`` (``eval-det-e<episodes>-s<seed>.json``)."""
    from ndp.rl.config import EVAL_SEED  # (the run-kind table loads no config)

    if seed == EVAL_SEED:
        return DET_EVAL_FILE.format(episodes=episodes)
    from ndp.rl.evaluate import EVAL_FILE  # (torch only where a run is evaluated)

    return EVAL_FILE.format(mode="det", episodes=episodes, seed=seed, exec_k="")


def det_success(path: Path, episodes: int, compute: bool = True, seed: int | None = None) -> float:
    """Success (any step) of the run's deterministic policy over ``episodes`` fresh episodes
    from reset seed ``seed`` (None: ``ndp.rl.config.EVAL_SEED``).

    Cached in the run (:func:`det_eval_name`, atomic), so a report is cheap to redo:
    ``eval-det-e<episodes>.json`` (:func:`ndp.rl.evaluate.evaluate`'s dict) on the default seed,
    else ``eval-det-e<episodes>-s<seed>.json`` as :func:`ndp.rl.evaluate.save_evaluation`
    writes it (``ndp rl eval --save``: one writer, so either command reads the other's). A run
    that ``ndp rl eval`` cannot act with (``compute`` False: the Stable-Baselines3 runs, which
    write ``eval-det-e<N>.json`` themselves when they evaluate, :mod:`ndp.sb3.runs`) gives NaN
    without the file.
    """
    from ndp.rl.config import EVAL_SEED

    first = EVAL_SEED if seed is None else seed
    cache = path / det_eval_name(episodes, first)
    data = _json(cache)
    if data is None and not compute:
        return math.nan
    if data is None:
        from ndp.rl.evaluate import evaluate, save_evaluation

        if first == EVAL_SEED:
            data = evaluate(path, episodes=episodes, deterministic=True)
            atomic_write_text(cache, json.dumps(data) + "\n")
        else:
            data = evaluate(path, episodes=episodes, deterministic=True, seed=first)
            save_evaluation(path, data, first)
    return float(data["success_any"])


@dataclass(frozen=True)
class ReportRow:
    """What one run of a kind contributes to ``ndp report``."""

    table: str
    """The table its runs join: ``"success"`` (RL), ``"imitation"`` or ``"cloning"``; runs of
    kinds with the same table are compared with each other (ours and the SB3 reference)."""
    numbers: Callable[[RunInfo, Sequence[int], FreshEval, bool], dict[str, Any]]
    """``(run, budgets in env steps, the report's deterministic evaluation, evaluable) ->
    numbers``
    (keys: the second element of :attr:`columns`' pairs, plus curves); ``evaluable``: whether
    ``ndp rl eval`` can act with the run (:attr:`ndp.experiments.run_kinds.RunKind.evaluable`)."""
    columns: Callable[[Sequence[int]], list[tuple[str, str]]] = field(default=lambda b: [])
    """``(budgets) -> [(CSV column stem, numbers key)]``: each becomes ``<stem>_mean`` and
    ``<stem>_std`` over the seeds of a cell."""


def _success_numbers(
    info: RunInfo, budgets: Sequence[int], fresh: FreshEval, evaluable: bool
) -> dict[str, Any]:
    out = rl_numbers(info, budgets)
    out["det"] = (
        det_success(info.path, fresh.episodes, evaluable, fresh.seed)
        if fresh.episodes
        else math.nan
    )
    return out


def _success_columns(budgets: Sequence[int]) -> list[tuple[str, str]]:
    return [
        *((f"success_at_{b}", f"at:{b}") for b in budgets),
        ("success_area", "area"),
        ("final_success", "final"),
        ("final_success_last_step", "final_last"),
        ("final_return_live", "return"),
        ("det_success", "det"),
        ("det_success_area", "det_area"),
        ("det_final_success", "det_final"),
        ("det_final_success_last_step", "det_final_last"),
    ]


SUCCESS_ROW = ReportRow("success", _success_numbers, _success_columns)
"""RL runs (ours and the SB3 reference): success over env steps."""

IMITATION_ROW = ReportRow(
    "imitation",
    lambda info, budgets, fresh, evaluable: il_numbers(info),
    lambda budgets: [("test_mse_px2", "mse"), ("test_dtw_px", "dtw")],
)
"""Digit-writing runs: test error."""

CLONING_ROW = ReportRow(
    "cloning",
    lambda info, budgets, fresh, evaluable: bc_numbers(info),
    lambda budgets: [
        ("success", "success"),
        ("fit_val_loss", "val_loss"),
        ("jerk", "jerk"),
        ("sparc", "sparc"),
    ],
)
"""Behaviour-cloning runs: closed-loop success, fit and smoothness."""
