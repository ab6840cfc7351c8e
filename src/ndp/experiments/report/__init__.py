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
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import math
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ndp.experiments.report import family
from ndp.experiments.report.conditions import conditions_section, metrics_of, pairwise_section
from ndp.experiments.report.selection import selection_section
from ndp.experiments.rows import (  # noqa: F401  # re-exported: the report's public names
    DET_EVAL_FILE,
    DET_KEYS,
    RunInfo,
    _json,
    bc_numbers,
    det_numbers,
    det_success,
    has_det,
    il_numbers,
    rl_numbers,
    success_at,
)
from ndp.experiments.run_kinds import RUN_KINDS, kind_of_algo, run_kind
from ndp.experiments.studies import get_study
from ndp.experiments.study import is_finished
from ndp.il.config import data_task_name
from ndp.io import atomic_savefig, atomic_write_text, check_output_path
from ndp.provenance import commit_in_history, fingerprint_text, git_commit
from ndp.rl.config import EVAL_SEED
from ndp.runs import metrics_path, read_metrics, run_commits, run_fingerprints
from ndp.runs.session import Manifest, read_manifest


class MissingSeedsError(ValueError):
    """Cells of the report lack seeds (the message names them)."""


# ----------------------------------------------------------------------------- finding runs


def _is_run(path: Path) -> bool:
    return (path / "arm.json").is_file() or metrics_path(path).is_file()


def find_run_dirs(paths: Sequence[str | Path]) -> list[Path]:
    """Run directories in ``paths`` (each a run, or holding runs up to two levels down).

    Raises:
        FileNotFoundError: a path does not exist.
    """
    out: list[Path] = []
    for p in map(Path, paths):
        if not p.exists():
            raise FileNotFoundError(f"report: no such directory {p}")
        if _is_run(p):
            out.append(p)
            continue
        for child in sorted(q for q in p.iterdir() if q.is_dir()):
            if _is_run(child):
                out.append(child)
            else:
                out += [g for g in sorted(q for q in child.iterdir() if q.is_dir()) if _is_run(g)]
    seen, uniq = set(), []
    for p in out:
        if p.resolve() not in seen:
            seen.add(p.resolve())
            uniq.append(p)
    return uniq


def _manifest(path: Path) -> Manifest | None:
    """The run's run.json, None when it has none (older runs) or it is unreadable (the other
    records then identify the run)."""
    try:
        return read_manifest(path)
    except ValueError:
        return None


def _kind_of_method(algo: str) -> str:
    """The run kind of a method named by an older run; "rl" for one no longer registered."""
    try:
        return kind_of_algo(algo).name
    except ValueError:
        return "rl"


def run_info(path: Path) -> RunInfo | None:
    """Identify a run (None: not enough to say which task / method / seed it is)."""
    arm = _json(path / "arm.json") or {}
    cfg = _json(path / "config.json") or {}
    algo = arm.get("algo") or cfg.get("algo") or cfg.get("method")  # method: an SB3 run's
    label = arm.get("label") or algo
    is_il = "model" in cfg and "data" in cfg
    if is_il and not algo:
        algo = "il-" + str(cfg["model"].get("kind", "ndp"))
        label = str(cfg["model"].get("kind", "ndp"))
    if not label or not algo:
        return None
    manifest = _manifest(path)
    kind = arm.get("kind") or (manifest.kind if manifest is not None else None)
    if kind not in RUN_KINDS:  # older runs, or a cloning run ("bc": an RL run once cloned)
        kind = "il" if is_il else _kind_of_method(str(algo))
    task, seed = arm.get("task"), arm.get("seed")
    if (task is None or seed is None) and manifest is not None:
        task, seed = manifest.task, manifest.seed  # what the run says it is (run.json)
    if task is None or seed is None:  # runs written before run.json
        m = re.fullmatch(rf"(.+)-{re.escape(str(label))}-s(\d+)", path.name)
        if m:
            task, seed = m.group(1), int(m.group(2))
        elif run_kind(kind).task_is_dataset and cfg:
            task, seed = data_task_name(cfg.get("data", {})), cfg.get("seed")
        elif cfg:
            task, seed = cfg.get("task"), cfg.get("seed")
    if task is None or seed is None:
        return None
    steps = arm.get("steps") or cfg.get(run_kind(kind).budget_key)
    if not steps:
        return None
    info = RunInfo(path, str(task), str(label), str(algo), int(seed), int(steps), kind,
                   manifest=manifest)  # fmt: skip
    info.finished = _finished(info)
    info.commits = run_commits(path)
    info.fingerprints = run_fingerprints(path)
    return info


def _record_reaches_budget(info: RunInfo) -> bool:
    """The run's metrics.csv reaches its budget (RL: the last row's ``global_step`` >= the
    budget; imitation: the last ``epoch``); a file cut short records less than ran."""
    kind = run_kind(info.kind)
    log = info.path / kind.metrics_file if kind.metrics_file else metrics_path(info.path)
    if not log.is_file():
        return False
    rows = read_metrics(log)
    col = kind.progress_column
    last = rows[-1].get(col, 0) if rows else 0
    target = info.steps
    manifest = info.manifest
    if (
        manifest is not None
        and manifest.finished
        and manifest.unit == "env_steps"
        and 0 < manifest.done < target
        and manifest.budget >= target
    ):
        # the run trained every planned update but executed fewer env steps than its slots
        # (decisions cut by an episode's end): its record must reach what it executed
        target = info.executed = int(manifest.done)
    done = _json(info.path / "done.json") or {}
    if done.get("reason") == "early stop" and isinstance(done.get("epoch"), int):
        target = done["epoch"]  # stopped on its validation split before the maximum
    if not (rows and last >= target):
        unit = kind.unit.removesuffix("s")
        info.problem = f"{log.name} ends at {unit} {last:,.0f} of {info.steps:,}"
        return False
    return True


def _finished(info: RunInfo) -> bool:
    path = info.path
    if (path / "done.json").is_file() or (path / "checkpoint.pt").is_file():
        if not (path / "done.json").is_file():
            try:
                if not is_finished(path, kind=info.kind):
                    return False
            except Exception:  # an unreadable checkpoint: not a finished run
                info.problem = "its checkpoint is unreadable"
                return False
        # finished by its own account; the record must say so too (a cut metrics.csv does not)
        return _record_reaches_budget(info)
    if run_kind(info.kind).needs_eval and not (path / "eval.json").is_file():
        return False
    return _record_reaches_budget(info)


# ----------------------------------------------------------------------------- the report


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


def _fmt(m: float, s: float, n: int, digits: int = 2) -> str:
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


def _missing_message(cells: Sequence[Cell], expected: Sequence[int]) -> str:
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


def report_stem(out: str | Path) -> Path:
    """The report's stem: ``--out`` as given, without a trailing ``.md`` / ``.csv`` (so
    ``--out r.md`` writes ``r.md``, as before); a dot inside a name is kept (``--out v1.2``
    writes ``v1.2.md`` and ``v1.2-<task>.png``, not ``v1.md`` beside ``v1.2-*.png``)."""
    out = Path(out)
    return out.with_suffix("") if out.suffix in (".md", ".csv") else out


def _ext(stem: Path, ext: str) -> Path:
    """``<stem><ext>``: the extension appended to the stem's name, never replacing a part of
    it."""
    return stem.with_name(stem.name + ext)


def _is_generated_md(head: str) -> bool:
    """The package's generated markdown: a ``Command: `...``` line, then ``Commit: ...``, in
    its first 10 lines (``ndp report``, ``ndp sweep --report``, the benchmarks' tables)."""
    from itertools import pairwise

    return any(
        a.startswith("Command: `") and b.startswith("Commit: ")
        for a, b in pairwise(head.splitlines()[:10])
    )


def _is_generated_csv(head: str) -> bool:
    """The package's generated CSV: a ``command`` column in its header."""
    return bool(head) and "command" in head.splitlines()[0].split(",")


def check_report_stem(out: Path) -> None:
    """A report replaces an earlier generated table of the same stem (the regeneration every
    committed table relies on) and nothing else: an existing ``<out>.md`` without the
    ``Command:`` / ``Commit:`` lines, or ``<out>.csv`` without a ``command`` column, is
    refused (FileExistsError naming ``out``) before any run is read."""
    checks = ((_ext(out, ".md"), _is_generated_md),
              (_ext(out, ".csv"), _is_generated_csv))  # fmt: skip
    for path, is_report in checks:
        if not path.is_file():
            continue
        try:
            with open(path, encoding="utf-8", errors="replace") as f:
                head = f.read(4096)
        except OSError:
            head = ""
        if not is_report(head):
            raise FileExistsError(
                f"out: {path} exists and is not an ndp report; choose another --out (a report "
                f"replaces only an earlier report of the same stem)"
            )


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
) -> dict[str, Any]:
    """Write ``<out>.md``, ``<out>.csv`` and ``<out>-<task>.png`` (see the module doc).

    ``compare``: a registered family of tests, ``"A:B"`` pairs of method labels (A - B on each
    task, with ``compare_pooled`` also over all tasks), Holm-adjusted over the whole family
    (:mod:`ndp.experiments.report.family`; ``<out>-family.csv``).

    ``study``: a named study; where it has conditions (``release-conditions``), the report adds
    the condition x method section (:mod:`ndp.experiments.report.conditions`: bootstrap
    intervals, IQM, probability of improvement; ``<out>-conditions.csv`` and
    ``<out>-conditions.png``), and ``methods`` defaults to the study's arms that have runs
    (the others named); a study with ``readings`` (``ndp-regimes``) adds them after the
    conditions, or after the pairwise tests in a study without conditions (``sac-critic``),
    with ``<out>-readings.csv``, unless ``methods`` restricts its arms.

    ``budgets``: env steps at which to give the success (default: a quarter, half and all of
    the largest budget). ``eval_episodes`` > 0 adds the success of each finished RL run's
    deterministic policy over that many fresh episodes (:func:`det_success`, cached per run).
    Returns the numbers (and the paths written).

    Raises:
        MissingSeedsError: cells lack seeds and not ``allow_missing`` (nothing written).
        ValueError: no runs, or two runs of one cell and seed.
    """
    out = report_stem(out)
    check_report_stem(out)  # before reading any run
    _check_args(budgets, eval_episodes, seeds)
    pairs = family.parse_pairs(compare)
    sc = _scope(run_dirs, study, tasks, methods)
    cells, expected = build_cells(sc.infos, seeds, sc.tasks, sc.methods, sc.arm_tasks)
    family.check_pairs(pairs, [c.label for c in cells])
    if any(c.missing for c in cells) and not allow_missing:
        raise MissingSeedsError(_missing_message(cells, expected))
    tables: dict[str, list[Cell]] = {"success": [], "imitation": [], "cloning": []}
    for c in cells:
        tables[run_kind(c.kind).report.table].append(c)
    rl_cells, il_cells, bc_cells = tables["success"], tables["imitation"], tables["cloning"]
    at_steps = _budgets(budgets, rl_cells, eval_episodes)
    for c in cells:
        kind = run_kind(c.kind)
        c.numbers = {
            s_: kind.report.numbers(i, at_steps, eval_episodes, kind.evaluable)
            for s_, i in c.runs.items()
        }
    prov = {
        "command": command,
        "commit": git_commit(),
        "date": dt.datetime.now().strftime("%Y-%m-%d %H:%M"),
        "run_commits": sorted({x for c in cells for i in c.runs.values() for x in i.commits}),
        "run_environments": _environments([i for c in cells for i in c.runs.values()]),
        "n_runs": sum(len(c.runs) for c in cells),
        "runs_per_commit": _per_commit([i for c in cells for i in c.runs.values()]),
    }
    out = Path(out)
    check_output_path(out, "out")
    pngs = _plot_all(rl_cells, il_cells, out, prov) if plots else []
    rows = _csv_rows(rl_cells, [*il_cells, *bc_cells], at_steps, expected, prov)
    _write_csv(_ext(out, ".csv"), rows)
    md = _markdown(title, rl_cells, il_cells, at_steps, expected, prov, pngs, out, eval_episodes)
    if bc_cells:
        at = md.index("", md.index(next(x for x in md if x.startswith("Seeds per cell")))) + 1
        md[at:at] = _bc_markdown(bc_cells)
    pngs, extra_csv = _study_sections(md, pngs, tables, sc, expected, out, prov, plots)
    if pairs and rl_cells:
        fmd, frows = family.family_section(rl_cells, expected, pairs, compare_pooled)
        if frows:
            path = out.with_name(out.name + "-family.csv")
            _write_csv(path, [{**r, **{k: prov[k] for k in ("command", "commit", "date")}}
                              for r in frows])  # fmt: skip
            extra_csv.append(path)
        at = next((i for i, line in enumerate(md) if line.startswith("CSV:")), len(md))
        md[at:at] = fmd
    atomic_write_text(_ext(out, ".md"), "\n".join(md) + "\n")
    return {
        **prov,
        "seeds": expected,
        "budgets": at_steps,
        "rows": rows,
        "markdown": str(_ext(out, ".md")),
        "csv": str(_ext(out, ".csv")),
        "section_csv": [str(p) for p in extra_csv],
        "png": [str(p) for p in pngs],
        "missing": [(c.task, c.label, c.missing) for c in cells if c.missing],
    }


@dataclass(frozen=True)
class _Scope:
    """What a report reads (:func:`_scope`)."""

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


def _scope(
    run_dirs: Sequence[str | Path],
    study: str | None,
    tasks: Sequence[str] | None,
    methods: Sequence[str] | None,
) -> _Scope:
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
    return _Scope(conditions, selection, infos, tasks, methods, arm_tasks, readings, not_run)


def _budgets(
    budgets: Sequence[float] | None, rl_cells: Sequence[Cell], eval_episodes: int
) -> list[int]:
    """The env steps the success table reports at (``budgets``, else a quarter, half and all
    of the largest run's budget); ``budgets`` checked by :func:`_check_args`."""
    top = max((i.steps for c in rl_cells for i in c.runs.values()), default=0)
    return sorted({int(b) for b in (budgets or [top / 4, top / 2, top]) if b > 0})


def _check_args(
    budgets: Sequence[float] | None, eval_episodes: int, seeds: Sequence[int] | None
) -> None:
    """The report's own arguments, before any run is read (ValueError naming the argument)."""
    for b in budgets or ():
        if isinstance(b, bool) or not isinstance(b, (int, float)) or not math.isfinite(b) or b <= 0:
            raise ValueError(f"budgets: expected env steps > 0, got {b!r}")
    if isinstance(eval_episodes, bool) or not isinstance(eval_episodes, int) or eval_episodes < 0:
        raise ValueError(f"eval_episodes: expected an integer >= 0, got {eval_episodes!r}")
    bad = [x for x in seeds or () if isinstance(x, bool) or not isinstance(x, int) or x < 0]
    if bad:
        raise ValueError(f"seeds: expected integers >= 0, got {bad}")


def _study_sections(
    md: list[str],
    pngs: list[Path],
    tables: dict[str, list[Cell]],
    sc: _Scope,
    expected: Sequence[int],
    out: Path,
    prov: dict[str, Any],
    plots: bool,
) -> tuple[list[Path], list[Path]]:
    """A study's own sections, inserted into ``md`` in place: its conditions and readings
    (before the per-arm success table) and its selection (before the imitation table), each
    with its CSV; the study's arms without runs are named. Returns the figures (the sections'
    first) and the sections' CSV paths."""
    conditions, selection = sc.conditions, sc.selection
    extra_csv: list[Path] = []

    def write(suffix: str, rows: Sequence[dict[str, Any]]) -> None:
        path = out.with_name(out.name + suffix)
        _write_csv(path, [{**r, **{k: prov[k] for k in ("command", "commit", "date")}}
                          for r in rows])  # fmt: skip
        extra_csv.append(path)

    if conditions:
        foot = f"{prov['command']}  |  commit {prov['commit']}  |  {prov['date']}"
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


def _csv_rows(
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


def _write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
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


def _short_of_budget(cells: Sequence[Cell]) -> list[str]:
    """A note naming the cells whose runs executed fewer env steps than the budget (every
    planned update trained; decisions cut by an episode's end filled slots with sub-steps that
    never ran), with the executed steps over seeds; nothing when every run reached it."""
    short = []
    for c in cells:
        got = sorted(r.executed for r in c.runs.values() if r.executed is not None)
        if got:
            budget = next(iter(c.runs.values())).steps
            lo, hi = got[0], got[-1]
            span = f"{lo:,}" if lo == hi else f"{lo:,}-{hi:,}"
            short.append(
                f"{c.task} x `{c.label}`: {span} of {budget:,} ({lo / budget:.0%}"
                f"{'' if lo == hi else f'-{hi / budget:.0%}'}) in {len(got)} of {len(c.runs)} runs"
            )
    if not short:
        return []
    return [
        "**Executed env steps below the budget** (the run trained every planned update, but an "
        "episode that ends inside a decision leaves that decision's remaining sub-steps "
        "unexecuted while they count toward the update's slots, e.g. a 150-step episode is 7.5 "
        "decisions of k = 20): " + "; ".join(short) + ". These cells trained on fewer samples "
        "than the others; methods at the same k lose the same share.",
        "",
    ]


def _markdown(
    title: str,
    rl_cells: Sequence[Cell],
    il_cells: Sequence[Cell],
    budgets: Sequence[int],
    expected: Sequence[int],
    prov: dict[str, Any],
    pngs: Sequence[Path],
    out: Path,
    eval_episodes: int = 0,
) -> list[str]:
    md = [
        f"# {title}",
        "",
        f"Command: `{prov['command']}`  ",
        f"Commit: {prov['commit']}, date: {prov['date']}; runs trained at commits: "
        f"{_commits_text(prov['run_commits'])}.  ",
        *_provenance_lines(prov),
        f"Seeds per cell: {list(expected)}; mean +- std over seeds (population std).",
        "",
    ]
    missing = [c for c in [*rl_cells, *il_cells] if c.missing]
    if missing:
        md += [
            f"**WARNING: seeds are missing from {len(missing)} cells (marked MISSING below); "
            "their numbers are over fewer seeds.**",
            "",
        ]
    md += _short_of_budget(rl_cells)
    if rl_cells:
        heads = [f"success @ {b:,}" for b in budgets]
        det = has_det(rl_cells)
        if det:
            headline = metrics_of(rl_cells)[1] == "det_area"
            md += [
                (
                    "Deterministic (the headline): every run"
                    if headline
                    else "Deterministic (not the headline: some runs trained without it): a run"
                )
                + " evaluates its policy's mode on fixed "
                "evaluation seeds (from 10,000) during training (`eval/*`, ndp.rl.periodic_eval); "
                "det. area: the mean of `eval/success_any` over its evaluations; det. final: the "
                "last evaluation (the final policy), at any step and at the final step. `-`: a "
                "run trained without it.",
                "",
            ]
        md += [
            "Success: `charts/success_any` of the training episodes. Success @ b: mean over the "
            "updates in the last 10% of [0, b] (`-`: no update logged by b, or b past the "
            "budget); area: the success curve averaged over the "
            "budget; final: last 10% of updates; final (final step): the same for "
            "`charts/success_final`, success at the episode's last step (the release's metric); "
            "live return: `charts/episode_return_live` over the last 10% of updates."
            + (
                f" Deterministic: success (any step) of the trained policy's mode over "
                f"{eval_episodes} fresh episodes per run (`ndp rl eval`, seeds from {EVAL_SEED:,}; "
                "Stable-Baselines3 runs: their own evaluation at the end of training, the same "
                "seeds, `ndp.sb3.runs`)."
                if eval_episodes
                else ""
            ),
            "",
            "| task | method | n | "
            + ("det. area | det. final | det. final (final step) | " if det else "")
            + " | ".join(heads)
            + " | success area | final success | final success (final step) | final live return |"
            + (" deterministic success |" if eval_episodes else ""),
            "|---" * (7 + 3 * det + len(heads) + bool(eval_episodes)) + "|",
        ]
        for c in rl_cells:
            vals = [_fmt(*c.stat(k)) for k in DET_KEYS] if det else []
            vals += [_fmt(*c.stat(f"at:{b}")) for b in budgets]
            vals += [_fmt(*c.stat("area")), _fmt(*c.stat("final")), _fmt(*c.stat("final_last"))]
            vals += [_fmt(*c.stat("return"), 1)]
            vals += [_fmt(*c.stat("det"))] if eval_episodes else []
            n = c.n_seeds_cell()
            md.append(f"| {c.task} | {c.label} | {n} | " + " | ".join(vals) + " |")
        md.append("")
        md += _over_tasks(rl_cells)
    if il_cells:
        md += [
            "Imitation: test MSE (px^2) and DTW distance (px) of each run's evaluation.",
            "",
            "| data | model | n | test MSE px^2 | test DTW px |",
            "|---|---|---|---|---|",
        ]
        for c in il_cells:
            n = c.n_seeds_cell()
            md.append(
                f"| {c.task} | {c.label} | {n} | {_fmt(*c.stat('mse'))} | {_fmt(*c.stat('dtw'))} |"
            )
        md.append("")
    md += [f"![{p.stem}]({p.name})" for p in pngs]
    md += ["", f"CSV: `{_ext(out, '.csv').name}`."]
    return md


LOST = "lost: not in this repository's history"
"""How a table marks a run's commit that no ref of the repository reaches
(:func:`ndp.provenance.commit_in_history`)."""


def _commits_text(commits: Sequence[str]) -> str:
    """The runs' commits for a table's header, each one the repository's history lacks marked
    ``(lost: ...)``; ``not recorded`` for none."""
    if not commits:
        return "not recorded"
    return ", ".join(c + (f" ({LOST})" if commit_in_history(c) is False else "") for c in commits)


def _environments(infos: Sequence[RunInfo]) -> list[tuple[str, int]]:
    """The distinct environment fingerprints of the runs' sessions, each with how many runs
    have it (a run resumed under another fingerprint counts under both), most runs first."""
    count: dict[str, int] = {}
    for i in infos:
        for fp in {fingerprint_text(f) for f in i.fingerprints} or {"not recorded"}:
            count[fp] = count.get(fp, 0) + 1
    return sorted(count.items(), key=lambda kv: (-kv[1], kv[0]))


def _per_commit(infos: Sequence[RunInfo]) -> dict[str, int]:
    """How many runs have a session at each commit (a run resumed at another commit counts
    under both)."""
    count: dict[str, int] = {}
    for i in infos:
        for c in i.commits:
            count[c] = count.get(c, 0) + 1
    return dict(sorted(count.items()))


def _provenance_lines(prov: dict[str, Any]) -> list[str]:
    """The header's lines on the runs' environments, and a MIXED warning when the runs were
    trained at several commits or under several environment fingerprints."""
    envs: list[tuple[str, int]] = prov.get("run_environments", [])
    total = prov.get("n_runs", sum(n for _, n in envs))
    if len(envs) == 1:
        lines = [f"Runs' environment: {envs[0][0]} (every run).  "]
    else:
        each = (f"{fp} ({n} run{'' if n == 1 else 's'})" for fp, n in envs)
        lines = ["Runs' environments: " + "; ".join(each) + ".  "]
    mixed = []
    commits = prov.get("run_commits", [])
    if len(commits) > 1:
        per = prov.get("runs_per_commit", {})
        named = [
            f"{c}: {per[c]} run{'' if per[c] == 1 else 's'}" if c in per else c for c in commits
        ]
        mixed.append(f"{len(commits)} commits ({', '.join(named)})")
    if len(envs) > 1:
        mixed.append(f"{len(envs)} environment fingerprints (above)")
    if mixed:
        lines.append(
            f"**MIXED: the {total} runs of this table were trained at "
            + " and ".join(mixed)
            + ". Their differences can come from the code or the environment as well as the "
            "method; the per-run record is each run's provenance.json.**  "
        )
    return lines


def _bc_markdown(cells: Sequence[Cell]) -> list[str]:
    """The behaviour-cloning table: one row per task and arm (model and demonstration count)."""
    md = [
        "Behaviour cloning: closed-loop success (any step) of each cloned policy over its "
        "evaluation episodes (deterministic, one decision per k env steps, stale-world rule, "
        "reset seeds disjoint from the demonstrations'); fit: the cloning's last validation "
        "loss (MSE of the k actions on held-out demonstration episodes); jerk: mean squared "
        "jerk of the executed arm path (lower is smoother); SPARC (closer to 0 is smoother). "
        "Means over seeds (+- std for success).",
        "",
        "| task | method | n | success | fit | jerk | SPARC |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in cells:
        n = c.n_seeds_cell()
        fit, jerk, sparc = (c.stat(k)[0] for k in ("val_loss", "jerk", "sparc"))
        md.append(
            f"| {c.task} | {c.label} | {n} | {_fmt(*c.stat('success'))} | "
            + " | ".join("-" if math.isnan(v) else f"{v:.3g}" for v in (fit, jerk))
            + f" | {'-' if math.isnan(sparc) else f'{sparc:.2f}'} |"
        )
    return [*md, ""]


def _task_grid(
    cells: Sequence[Cell],
) -> tuple[list[str], list[str], dict[tuple[str, str], Cell], list[str]]:
    """Tasks and labels in table order (the labels with a cell on every task: a study's arm
    that runs on some tasks only is left out of the summaries over tasks), the cell of each
    (task, label), and the tasks where every such label has a final success (the ones the
    summaries over tasks average)."""
    tasks = list(dict.fromkeys(c.task for c in cells))
    by = {(c.task, c.label): c for c in cells}
    labels = [lb for lb in dict.fromkeys(c.label for c in cells)
              if all((t, lb) in by for t in tasks)]  # fmt: skip
    full = [t for t in tasks if all(by[(t, lb)].stat("final")[2] > 0 for lb in labels)]
    return tasks, labels, by, full


def _over_tasks(cells: Sequence[Cell]) -> list[str]:
    """Mean over tasks per method (tasks where every method has a value) and how many tasks
    NDP >= each other method (final success), the paper's MT50 summary, split into higher, equal
    (and how many of those are both at 0, where the count says nothing) and lower."""
    tasks, labels, by, full = _task_grid(cells)
    if len(tasks) < 2:
        return []
    det = any(not math.isnan(n.get("det", math.nan)) for c in cells for n in c.numbers.values())
    partial = [lb for lb in dict.fromkeys(c.label for c in cells) if lb not in labels]
    md = [
        f"Over tasks ({len(full)} of {len(tasks)} tasks where every method has runs"
        + (f"; not {', '.join(partial)}, which run on some tasks only" if partial else "")
        + "):",
        "",
        "| method | mean final success | mean success area |"
        + (" mean deterministic success |" if det else ""),
        "|---|---|---|" + ("---|" if det else ""),
    ]
    for lb in labels:
        f = [by[(t, lb)].stat("final")[0] for t in full]
        a = [by[(t, lb)].stat("area")[0] for t in full]
        fm = f"{np.mean(f):.3f}" if f else "-"
        am = f"{np.mean(a):.3f}" if a else "-"
        row = f"| {lb} | {fm} | {am} |"
        if det:
            d = [v for v in (by[(t, lb)].stat("det")[0] for t in full) if not math.isnan(v)]
            row += f" {np.mean(d):.3f} |" if len(d) == len(full) and d else " - |"
        md.append(row)
    md.append("")
    if "ndp" in labels and full:
        for lb in labels:
            if lb == "ndp":
                continue
            pairs = [(by[(t, "ndp")].stat("final")[0], by[(t, lb)].stat("final")[0]) for t in full]
            higher = sum(a > b for a, b in pairs)
            equal = sum(a == b for a, b in pairs)
            zero = sum(a == b == 0 for a, b in pairs)
            md.append(
                f"NDP >= {lb} (mean final success) on {higher + equal} of {len(full)} tasks: "
                f"higher on {higher}, equal on {equal} ({zero} with both at 0), "
                f"lower on {len(full) - higher - equal}.  "
            )
        md.append("")
    return md


def _plot_all(
    rl_cells: Sequence[Cell], il_cells: Sequence[Cell], out: Path, prov: dict[str, Any]
) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import textwrap

    import matplotlib.pyplot as plt

    foot = f"{prov['command']}  |  commit {prov['commit']}  |  {prov['date']}"
    foot_lines = textwrap.wrap(foot, 150) or [""]
    meta = {"Description": foot, "Software": "ndp report"}
    paths = []
    panels: list[tuple[Sequence[Cell], str, str, str]] = [
        (rl_cells, "env steps", "success (any step, training)", "curve"),
        (il_cells, "epoch", "test MSE (px^2)", "curve"),
    ]
    if has_det(rl_cells):
        panels.insert(
            0, (rl_cells, "env steps", "success (any step, deterministic evaluation)", "det_curve")
        )
    for cells, xlabel, ylabel, curve_key in panels:
        for task in dict.fromkeys(c.task for c in cells):
            fig, ax = plt.subplots(figsize=(6.4, 4.2 + 0.1 * len(foot_lines)))
            tcells = [c for c in cells if c.task == task]
            top = max((i.steps for c in tcells for i in c.runs.values()), default=1)
            grid = np.linspace(0, top, 101)
            drawn = 0
            for c in tcells:
                curves = []
                for n in c.numbers.values():
                    x, y = n[curve_key]
                    if len(x):
                        curves.append(np.interp(grid, x, y, left=np.nan, right=np.nan))
                if not curves:
                    continue
                drawn += 1
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    m, s = np.nanmean(curves, 0), np.nanstd(curves, 0)
                name = f"{c.label} (n={len(curves)})" + (f" {c.marker()}" if c.missing else "")
                (line,) = ax.plot(
                    grid,
                    m,
                    label=name,
                    lw=1.6 if not c.missing else 1.0,
                    ls="-" if not c.missing else "--",
                )
                ax.fill_between(grid, m - s, m + s, alpha=0.18, color=line.get_color(), lw=0)
            if not drawn:  # no run of this task has the curve (e.g. trained without evaluation)
                plt.close(fig)
                continue
            ax.set_title(task + ("  [MISSING SEEDS]" if any(c.missing for c in tcells) else ""))
            ax.set_xlim(0, top)
            ax.set_xlabel(xlabel)
            label = ylabel
            if cells is il_cells:  # the split the drawn curves score
                kinds = {n["curve_of"] for c in tcells for n in c.numbers.values()}
                if kinds == {"validation"}:
                    label = "validation MSE (px^2)"
                elif len(kinds) > 1:
                    label = "test MSE, or validation MSE where test is scored once (px^2)"
            ax.set_ylabel(label)
            if cells is rl_cells:
                ax.set_ylim(-0.02, 1.02)
            else:
                ax.set_yscale("log")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="best")
            fig.text(
                0.01, 0.005, "\n".join(foot_lines), fontsize=5, color="0.35", ha="left", va="bottom"
            )
            fig.tight_layout(rect=(0, 0.01 + 0.022 * len(foot_lines), 1, 1))
            safe = re.sub(r"[^A-Za-z0-9_.-]", "_", task)
            suffix = "-det" if curve_key == "det_curve" else ""
            path = out.with_name(f"{out.name}-{safe}{suffix}.png")
            atomic_savefig(fig, path, dpi=80, metadata=meta)
            plt.close(fig)
            paths.append(path)
    if len({c.task for c in rl_cells}) >= 3:
        paths.insert(0, _plot_over_tasks(rl_cells, out, foot_lines, meta))
    return paths


def _plot_over_tasks(
    cells: Sequence[Cell],
    out: Path,
    foot_lines: list[str],
    meta: dict[str, str],
) -> Path:
    """``<out>-over-tasks.png``: final success (mean +- std over seeds) per task, one bar per
    method, tasks top to bottom in the table's order (MT50's one-figure summary)."""
    import matplotlib.pyplot as plt

    tasks, labels, by, complete = _task_grid(cells)
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
