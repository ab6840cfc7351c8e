"""What a report reads and adds: the runs and the study's scope (:func:`scope`: its
conditions, selection, readings, tasks and arms), the report's own arguments
(:func:`check_args`), the budgets it reports at, and the study's sections
(:func:`study_sections`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ndp.experiments.report.cells import Cell, CsvRow
from ndp.experiments.report.conditions import conditions_section, pairwise_section
from ndp.experiments.report.csvs import write_csv
from ndp.experiments.report.fresh import FreshEval, fresh_eval
from ndp.experiments.report.provenance import ReportProvenance, figure_foot, stamp
from ndp.experiments.report.runs import find_run_dirs, run_info
from ndp.experiments.report.selection import selection_section
from ndp.experiments.rows import RunInfo
from ndp.experiments.studies import get_study


@dataclass(frozen=True)
class Scope:
    """What a report reads (:func:`scope`)."""

    conditions: tuple[Any, ...]
    selection: tuple[Any, ...]
    infos: list[RunInfo]
    tasks: Sequence[str] | None
    methods: Sequence[str] | None
    arm_tasks: dict[str, tuple[str, ...]]
    readings: Any = None
    """The study's :data:`ndp.experiments.studies.Readings`, or None."""
    not_run: tuple[str, ...] = ()
    """The study's arms (named by default) with no run in these directories yet."""


def scope(
    run_dirs: Sequence[str | Path],
    study: str | None,
    tasks: Sequence[str] | None,
    methods: Sequence[str] | None,
) -> Scope:
    """The runs a report reads and its scope: the study's conditions, selection and readings
    (empty without a study), the runs found under ``run_dirs``, the tasks and methods (a study
    with sections defaults them to its own arms that have runs, in its order, leaving out tasks
    without runs yet, and names the arms left out), and the study's arms that run on some tasks
    only, with those tasks."""
    conditions: tuple[Any, ...] = ()
    selection: tuple[Any, ...] = ()
    readings = None
    arm_tasks: dict[str, tuple[str, ...]] = {}
    study_arms: list[str] | None = None
    if study is not None:
        st = get_study(study)
        conditions, selection = st.conditions, st.selection
        readings = st.readings_fn() if methods is None else None  # need the study's arms
        arm_tasks = {a.label: tuple(a.tasks) for a in st.arm_specs() if a.tasks}
        if methods is None and (conditions or selection):
            # the study's arms, then the arms its conditions take from other studies' runs
            study_arms = [a.label for a in st.arm_specs()]
            study_arms = list(
                dict.fromkeys(  # each once (ppo is in several conditions)
                    [*study_arms, *(lb for c in conditions for _, lb in c.methods)]
                )
            )
    study_tasks = tasks is None and (conditions or selection)
    if study_tasks:
        tasks = list(st.task_list())
    dirs = find_run_dirs(run_dirs)
    infos = [i for i in (run_info(d) for d in dirs) if i is not None]
    if not infos:
        raise ValueError(f"report: no runs found in {', '.join(map(str, run_dirs))}")
    if study_tasks and tasks is not None:  # the study's order; tasks without runs yet left out
        found = {i.task for i in infos}
        tasks = [t for t in tasks if t in found]
    not_run: tuple[str, ...] = ()
    if study_arms is not None:  # the study's arms with runs; the others named in the report
        have = {i.label for i in infos if not tasks or i.task in tasks}
        methods = [lb for lb in study_arms if lb in have]
        not_run = tuple(lb for lb in study_arms if lb not in have)
    return Scope(conditions, selection, infos, tasks, methods, arm_tasks, readings, not_run)


def report_budgets(budgets: Sequence[float] | None, rl_cells: Sequence[Cell]) -> list[int]:
    """The env steps the success table reports at (``budgets``, else a quarter, half and all
    of the largest run's budget); ``budgets`` checked by :func:`check_args`."""
    top = max((i.steps for c in rl_cells for i in c.runs.values()), default=0)
    return sorted({int(b) for b in (budgets or [top / 4, top / 2, top]) if b > 0})


def check_args(
    budgets: Sequence[float] | None,
    eval_episodes: int,
    seeds: Sequence[int] | None,
    eval_seed: int | None = None,
) -> FreshEval:
    """The report's own arguments, before any run is read (ValueError naming the argument);
    returns its deterministic evaluation (:func:`ndp.experiments.report.fresh.fresh_eval`)."""
    for b in budgets or ():
        if isinstance(b, bool) or not isinstance(b, (int, float)) or not math.isfinite(b) or b <= 0:
            raise ValueError(f"budgets: expected env steps > 0, got {b!r}")
    fresh = fresh_eval(eval_episodes, eval_seed)
    bad = [x for x in seeds or () if isinstance(x, bool) or not isinstance(x, int) or x < 0]
    if bad:
        raise ValueError(f"seeds: expected integers >= 0, got {bad}")
    return fresh


def study_sections(
    md: list[str],
    pngs: list[Path],
    tables: dict[str, list[Cell]],
    sc: Scope,
    expected: Sequence[int],
    out: Path,
    prov: ReportProvenance,
    plots: bool,
) -> tuple[list[Path], list[Path]]:
    """A study's own sections, inserted into ``md`` in place: its conditions and readings
    (before the per-arm success table) and its selection (before the imitation table), each
    with its CSV; the study's arms without runs are named. Returns the figures (the sections'
    first) and the sections' CSV paths."""
    conditions, selection = sc.conditions, sc.selection
    extra_csv: list[Path] = []

    def write(suffix: str, rows: Sequence[CsvRow]) -> None:
        path = out.with_name(out.name + suffix)
        write_csv(path, [{**r, **stamp(prov)}
                          for r in rows])  # fmt: skip
        extra_csv.append(path)

    if conditions:
        foot = figure_foot(prov)
        cmd, crows, cpngs = conditions_section(
            tables["success"], conditions, expected, out, foot, plots
        )
        write("-conditions.csv", crows)
        if sc.readings is not None and tables["success"]:
            rmd, rrows = sc.readings(tables["success"], expected)
            write("-readings.csv", rrows)
            cmd = [*cmd, *rmd]
        if sc.not_run:
            cmd = [*cmd, f"Arms of the study with no runs here (left out): "
                   f"{', '.join(sc.not_run)}.", ""]  # fmt: skip
        at = next((i for i, line in enumerate(md) if line.startswith("Success:")), len(md))
        md[at:at] = cmd
        pngs = [*cpngs, *pngs]
    elif tables["success"]:  # no conditions: every pair of methods on a task, tested
        pmd, prows = pairwise_section(tables["success"])
        if prows:
            write("-pairwise.csv", prows)
        if sc.readings is not None:  # a study's readings follow its pairwise tests
            rmd, rrows = sc.readings(tables["success"], expected)
            write("-readings.csv", rrows)
            pmd = [*pmd, "", *rmd]
        at = next((i for i, line in enumerate(md) if line.startswith("CSV:")), len(md))
        md[at:at] = pmd
    if selection and tables["imitation"]:
        smd, srows = selection_section(tables["imitation"], selection, expected, floor=plots)
        write("-selection.csv", srows)
        at = next((i for i, line in enumerate(md) if line.startswith("Imitation:")), len(md))
        md[at:at] = smd
    return pngs, extra_csv
