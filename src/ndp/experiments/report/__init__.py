"""``ndp report RUN_DIRS...``: tables and learning curves from run directories.

Runs are found in the given directories (a run directory, or a directory of run directories,
two levels down at most) and grouped into cells (task x method label) with one run per seed.
The method label is the study arm's (``arm.json``) or, for a plain ``ndp rl train`` run, its
``--algo``. Only finished runs count (the budget reached: ``done.json``, or the checkpoint's
update count; an imitation run also evaluated).

Per RL run (``metrics.csv``, docs/metrics.md):

- **success at budget b**: the mean of ``charts/success_any`` over the updates in the last 10%
  of [0, b] (NaN when the run's budget is below b);
- **success area**: the success curve averaged over the run's budget (0 before the first
  logged update): the area under the curve divided by the budget;
- **final success**: the mean over the last 10% of the updates;
- **final live return**: the mean of ``charts/episode_return_live`` (the env's own reward at
  every sub-step; ``charts/episode_return`` for runs without it) over the last 10% of updates.

Per imitation run: the test MSE (px^2) and DTW distance of ``eval.json`` (the last logged
``test/mse_px2`` without it).

Cells give mean +- std (population std, over seeds). Every cell must hold the same seeds (the
``--seeds`` given, or every seed found in the report): a cell with seeds missing makes the
report refuse (naming the cells and seeds), or, with ``allow_missing``, carry a loud
``MISSING seeds ...`` marker in the tables, the CSV (``missing_seeds``) and the legend.

Outputs (``out`` stem): ``<out>.md`` (tables per task x method, and a summary over tasks:
the mean per method and on how many tasks NDP >= each other method), ``<out>.csv`` (one row per
cell), ``<out>-<task>.png`` (one line per method, mean +- std band over seeds, x in env steps).
Each carries the command, the commit and the date (and the commits the runs were trained at).

The report is a small library; :func:`report` puts its parts together:

- :mod:`ndp.experiments.report.runs`: finding runs (:func:`find_run_dirs`, :func:`run_info`);
- :mod:`ndp.experiments.report.cells`: cells and their numbers (:func:`build_cells`,
  :func:`compute_numbers`; :func:`load_cells` does both from run directories);
- :mod:`ndp.experiments.report.markdown`, :mod:`ndp.experiments.report.csvs`,
  :mod:`ndp.experiments.report.plots`: the tables, the CSV and the figures, from cells;
- :mod:`ndp.experiments.report.provenance`: command, commits and environments;
- :mod:`ndp.experiments.report.scope`: a study's scope and sections (conditions, readings,
  selection); :mod:`ndp.experiments.report.family`: a family of pairwise tests.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ndp.experiments.report import family
from ndp.experiments.report.cells import (
    Cell,
    MissingSeedsError,
    build_cells,
    compute_numbers,
    fmt_stat,
    missing_message,
    split_tables,
)
from ndp.experiments.report.csvs import csv_rows, write_csv
from ndp.experiments.report.fresh import FreshEval
from ndp.experiments.report.markdown import markdown, with_bc_table
from ndp.experiments.report.paths import check_report_stem, report_stem, with_ext
from ndp.experiments.report.plots import plot_all
from ndp.experiments.report.provenance import (
    LOST,
    ReportProvenance,
    ReportResult,
    provenance,
    stamp,
)
from ndp.experiments.report.runs import find_run_dirs, run_info
from ndp.experiments.report.scope import Scope, check_args, report_budgets, scope, study_sections
from ndp.experiments.rows import (
    DET_EVAL_FILE,
    DET_KEYS,
    RunInfo,
    bc_numbers,
    det_numbers,
    det_success,
    has_det,
    il_numbers,
    rl_numbers,
    success_at,
)
from ndp.io import atomic_write_text, check_output_path

__all__ = [
    "DET_EVAL_FILE",
    "DET_KEYS",
    "LOST",
    "Cell",
    "FreshEval",
    "MissingSeedsError",
    "RunInfo",
    "bc_numbers",
    "build_cells",
    "check_report_stem",
    "compute_numbers",
    "det_numbers",
    "det_success",
    "find_run_dirs",
    "fmt_stat",
    "has_det",
    "il_numbers",
    "load_cells",
    "report",
    "report_stem",
    "rl_numbers",
    "run_info",
    "split_tables",
    "success_at",
]


def load_cells(
    run_dirs: Sequence[str | Path],
    budgets: Sequence[int] = (),
    seeds: Sequence[int] | None = None,
    tasks: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    eval_episodes: int = 0,
    eval_seed: int | None = None,
) -> tuple[list[Cell], list[int]]:
    """The cells of the finished runs under ``run_dirs`` with their numbers (success at each
    of ``budgets`` env steps, area, final success, ...), and the seeds every cell should hold:
    the first steps of :func:`report`, for a table of one's own (docs/architecture.md);
    ``eval_episodes`` and ``eval_seed`` as :func:`report`'s."""
    fresh = check_args(budgets, eval_episodes, seeds, eval_seed)
    infos = [i for i in (run_info(d) for d in find_run_dirs(run_dirs)) if i is not None]
    if not infos:
        raise ValueError(f"run_dirs: no runs found in {', '.join(map(str, run_dirs))}")
    cells, expected = build_cells(infos, seeds, tasks, methods)
    compute_numbers(cells, [int(b) for b in budgets], fresh)
    return cells, expected


def report(
    run_dirs: Sequence[str | Path],
    out: str | Path,
    command: str,
    seeds: Sequence[int] | None = None,
    budgets: Sequence[float] | None = None,
    tasks: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    allow_missing: bool = False,
    title: str = "Report",
    plots: bool = True,
    eval_episodes: int = 0,
    study: str | None = None,
    compare: Sequence[str] = (),
    compare_pooled: bool = False,
    compare_holm: str = "all",
    eval_seed: int | None = None,
) -> ReportResult:
    """Write ``<out>.md``, ``<out>.csv`` and ``<out>-<task>.png`` (see the module doc).

    ``compare``: a registered family of tests, ``"A:B"`` pairs of method labels (A - B on each
    task, with ``compare_pooled`` also over all tasks), Holm-adjusted over the whole family
    (:mod:`ndp.experiments.report.family`; ``<out>-family.csv``); ``compare_holm``: which rows
    the family holds ('all', 'pooled': the rows over all tasks, per-task rows described;
    'tasks').

    ``study``: a named study; where it has conditions (``release-conditions``), the report adds
    the condition x method section (:mod:`ndp.experiments.report.conditions`: bootstrap
    intervals, IQM, probability of improvement; ``<out>-conditions.csv`` and
    ``<out>-conditions.png``), and ``methods`` defaults to the study's arms that have runs
    (the others named); a study with ``readings`` (``ndp-regimes``) adds them after the
    conditions, or after the pairwise tests in a study without conditions (``sac-critic``),
    with ``<out>-readings.csv``, unless ``methods`` restricts its arms.

    ``budgets``: env steps at which to give the success (default: a quarter, half and all of
    the largest budget). ``eval_episodes`` > 0 adds the success of each finished RL run's
    deterministic policy over that many fresh episodes (:func:`det_success`, cached per run),
    reset seeds ``eval_seed`` on (None: :data:`ndp.rl.config.EVAL_SEED`, the first of the
    periodic evaluation's fixed seeds; e.g. ``FRESH_EVAL_SEED`` = 20,000 re-scores final
    policies on seeds disjoint from them, in the file ``ndp rl eval --save`` writes).
    Returns the numbers (and the paths written).

    Raises:
        MissingSeedsError: cells lack seeds and not ``allow_missing`` (nothing written).
        ValueError: no runs, or two runs of one cell and seed.
    """
    out = report_stem(out)
    check_report_stem(out)  # before reading any run
    fresh = check_args(budgets, eval_episodes, seeds, eval_seed)
    pairs = family.parse_pairs(compare)
    sc = scope(run_dirs, study, tasks, methods)
    cells, expected = build_cells(sc.infos, seeds, sc.tasks, sc.methods, sc.arm_tasks)
    family.check_pairs(pairs, [c.label for c in cells])
    if any(c.missing for c in cells) and not allow_missing:
        raise MissingSeedsError(missing_message(cells, expected))
    return _write(cells, expected, sc, out, command, title, plots, fresh, budgets,
                  pairs, compare_pooled, compare_holm)  # fmt: skip


def _write(
    cells: list[Cell], expected: list[int], sc: Scope, out: Path, command: str, title: str,
    plots: bool, fresh: FreshEval, budgets: Sequence[float] | None,
    pairs: Sequence[tuple[str, str]], pooled: bool, holm_over: str = "all",
) -> ReportResult:  # fmt: skip
    """The numbers of the cells, then every output of :func:`report` (its return value)."""
    tables = split_tables(cells)
    rl_cells, il_cells, bc_cells = tables["success"], tables["imitation"], tables["cloning"]
    at_steps = report_budgets(budgets, rl_cells)
    compute_numbers(cells, at_steps, fresh)
    prov = provenance(command, [i for c in cells for i in c.runs.values()])
    check_output_path(out, "out")
    pngs = plot_all(rl_cells, il_cells, out, prov) if plots else []
    rows = csv_rows(rl_cells, [*il_cells, *bc_cells], at_steps, expected, prov)
    write_csv(with_ext(out, ".csv"), rows)
    md = markdown(title, rl_cells, il_cells, at_steps, expected, prov, pngs, out, fresh)
    with_bc_table(md, bc_cells)
    pngs, extra_csv = study_sections(md, pngs, tables, sc, expected, out, prov, plots)
    extra_csv += _family_section(md, rl_cells, expected, pairs, pooled, out, prov, holm_over)
    atomic_write_text(with_ext(out, ".md"), "\n".join(md) + "\n")
    return {
        **prov,
        "seeds": expected,
        "budgets": at_steps,
        "rows": rows,
        "markdown": str(with_ext(out, ".md")),
        "csv": str(with_ext(out, ".csv")),
        "section_csv": [str(p) for p in extra_csv],
        "png": [str(p) for p in pngs],
        "missing": [(c.task, c.label, c.missing) for c in cells if c.missing],
    }


def _family_section(
    md: list[str],
    rl_cells: Sequence[Cell],
    expected: Sequence[int],
    pairs: Sequence[tuple[str, str]],
    pooled: bool,
    out: Path,
    prov: ReportProvenance,
    holm_over: str = "all",
) -> list[Path]:
    """The registered family of pairwise tests, inserted into ``md`` before its CSV line, with
    ``<out>-family.csv``; returns the CSV written (none without pairs or RL cells)."""
    if not (pairs and rl_cells):
        return []
    fmd, frows = family.family_section(rl_cells, expected, pairs, pooled, holm_over)
    written = []
    if frows:
        path = out.with_name(out.name + "-family.csv")
        write_csv(path, [{**r, **stamp(prov)} for r in frows])
        written.append(path)
    at = next((i for i, line in enumerate(md) if line.startswith("CSV:")), len(md))
    md[at:at] = fmd
    return written
