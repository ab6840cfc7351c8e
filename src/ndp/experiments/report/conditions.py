"""The report's condition x method section (``ndp report --study NAME`` for a study with
conditions, such as ``release-conditions``).

A condition maps each method to one arm (run label) of the study; arms are shared between
conditions where their settings coincide (:class:`ndp.experiments.studies.Condition`). For
every condition and method this section gives:

- per task: success area, final success at any step and at the final step, each as the mean
  over seeds with a 95% percentile-bootstrap interval;
- over the tasks where every cell has every seed: the IQM of each number over all runs with a
  95% stratified-bootstrap interval, and the probability that NDP beats each other method
  (:mod:`ndp.experiments.report.stats`, the rliable protocol), with the paper's ordering
  (NDP > PPO-multi > PPO) checked on the IQM of the success area.

Where the runs have a periodic deterministic evaluation (``eval/*``, ndp.rl.periodic_eval), its
numbers come first and the **headline** is the deterministic success area; else the training
episodes' success area. For the headline the section adds the t-interval beside the bootstrap
(with :data:`ndp.experiments.report.stats.COVERAGE_NOTE`), the optimality gap over tasks (rliable),
permutation p-values for every pair of methods in a condition (per task and stratified over the
tasks; two-sided with Holm's correction within the condition's rows of each table, the one-sided
p of each direction beside them, each labelled exact or Monte Carlo: the convention of
docs/metrics.md), and a performance-profile figure per study (``<out>-profiles.png``).

Conditions with ``unequal=True`` (the release's unequal goals) carry "UNEQUAL" in every table
and figure.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ndp.experiments.report import stats
from ndp.experiments.report.cells import Cell, CsvRow, seed_values
from ndp.experiments.report.readings import interval
from ndp.io import atomic_savefig

if TYPE_CHECKING:
    from ndp.experiments.studies.base import Condition

METRICS = (
    ("area", "success area"),
    ("final", "final success (any step)"),
    ("final_last", "final success (final step)"),
)
"""(cell number key, heading) of the training-episode numbers each table gives."""
DET_METRICS = (
    ("det_area", "det. success area"),
    ("det_final", "det. final success (any step)"),
    ("det_final_last", "det. final success (final step)"),
)
"""The periodic deterministic evaluation's numbers, first where the runs have them."""


def metrics_of(cells: Sequence[Cell]) -> tuple[tuple[tuple[str, str], ...], str]:
    """(the numbers the tables give, the headline key): the deterministic ones first where any
    run has them; the deterministic area is the headline only where every run has it (a study
    whose older runs trained without periodic evaluation keeps the training-episode area as
    its headline, so its comparisons still cover every run), else the training-episode area."""
    has = [not math.isnan(n.get("det_area", math.nan)) for c in cells for n in c.numbers.values()]
    if not any(has):
        return METRICS, "area"
    return (*DET_METRICS, *METRICS), ("det_area" if all(has) else "area")


ORDER = ("ndp", "ppo-multi", "ppo")
"""The paper's ordering of the methods, best first."""


def _name(cond: Condition) -> str:
    return f"{cond.name} (UNEQUAL)" if cond.unequal else cond.name


def _with_overrides(
    cond: Condition, by: dict[tuple[str, str], Cell], tasks: Sequence[str]
) -> Condition:
    """A condition whose arm differs per task (``Condition.overrides``) as one with a combined
    label per overridden method, e.g. ``ppo-v1 / faucet-open-v3: ppo-v1-fixed``, entered in
    ``by`` for every task (the tables then need no per-task lookup)."""
    import dataclasses

    if not getattr(cond, "overrides", ()):
        return cond
    methods = []
    for m, lb in cond.methods:
        per = {t: o for t, mm, o in cond.overrides if mm == m}
        if not per:
            methods.append((m, lb))
            continue
        name = lb + " / " + ", ".join(f"{t}: {o}" for t, o in per.items())
        for t in tasks:
            cell = by.get((t, per.get(t, lb)))
            if cell is not None:
                by[(t, name)] = cell
        methods.append((m, name))
    return dataclasses.replace(cond, methods=tuple(methods), overrides=())


def _ci(v: Sequence[float], lo: float, hi: float) -> str:
    return "-" if not len(v) else f"{np.mean(v):.2f} [{lo:.2f}, {hi:.2f}]"


def conditions_section(
    cells: Sequence[Cell],
    conditions: Sequence[Condition],
    seeds: Sequence[int],
    out: Path,
    foot: str,
    plots: bool = True,
) -> tuple[list[str], list[CsvRow], list[Path]]:
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
    conditions = [_with_overrides(cond, by, tasks) for cond in conditions]
    metrics, head = metrics_of(cells)
    md = _intro(conditions, dict(metrics)[head])
    rows: list[CsvRow] = []
    waiting: dict[str, list[str]] = {}
    for task in tasks:
        tmd, trows = _task_section(task, by, conditions, seeds, metrics, head, waiting)
        md += tmd
        rows += trows
    if waiting:
        md += [
            "Conditions left out where some of their arms have no runs in this report: "
            + "; ".join(f"{c} ({', '.join(ts)})" for c, ts in waiting.items())
            + ".",
            "",
        ]
    groups = _full_groups(by, conditions, tasks, seeds, head)
    omd, over_rows = _over_groups(by, groups, conditions, seeds, metrics, head)
    md += omd
    rows += over_rows
    pngs = []
    iq = [r for r in over_rows if r["task"] == "IQM over tasks"]
    if plots and iq:
        pngs.append(_plot(iq, conditions, out, foot, metrics))
        pngs.append(_profiles(by, groups, seeds, head, dict(metrics)[head], out, foot))
    md += [f"![{p.stem}]({p.name})" for p in pngs]
    md.append("")
    return md, rows, pngs


def _intro(conditions: Sequence[Condition], head_name: str) -> list[str]:
    """The section's title, what a condition is, and each condition with its arms."""
    md = [
        "## Conditions",
        "",
        "Each condition maps every method to one arm of the study (runs shared where settings "
        "coincide). UNEQUAL: the methods do not see the same task distribution on purpose (the "
        "2021 release's condition, reproduced to explain the paper's curves; not a fair "
        "comparison). Per task: mean over seeds [95% percentile-bootstrap interval]; for the "
        f"headline ({head_name}) also the 95% t-interval. {stats.COVERAGE_NOTE}",
        "",
    ]
    for cond in conditions:
        md.append(f"- **{_name(cond)}**: {cond.note}; arms: "
                  + ", ".join(f"{m} = `{lb}`" for m, lb in cond.methods))  # fmt: skip
    md.append("")
    return md


def _task_section(
    task: str, by: dict[tuple[str, str], Cell], conditions: Sequence[Condition],
    seeds: Sequence[int], metrics: Sequence[tuple[str, str]], head: str,
    waiting: dict[str, list[str]],
) -> tuple[list[str], list[CsvRow]]:  # fmt: skip
    """One task's condition x method table and its permutation tests (conditions with every
    arm on the task); the conditions with only some arms there are added to ``waiting``."""
    present = [cond for cond in conditions if all((task, lb) in by for _, lb in cond.methods)]
    for cond in conditions:  # some of its arms have runs on the task, not all of them yet
        if cond not in present and any((task, lb) in by for _, lb in cond.methods):
            waiting.setdefault(_name(cond), []).append(task)
    if not present:
        return [], []
    head_name = dict(metrics)[head]
    md = [
        f"### {task}",
        "",
        "| condition | method | arm | n | "
        + " | ".join(h for _, h in metrics)
        + f" | {head_name}: t-interval |",
        "|---" * (5 + len(metrics)) + "|",
    ]
    rows: list[CsvRow] = []
    for cond in present:
        for m, lb in cond.methods:
            line, row = _task_row(task, cond, m, lb, by.get((task, lb)), seeds, metrics, head)
            md.append(line)
            rows.append(row)
    md.append("")
    prows = _pairwise(by, present, [task], seeds, head)
    md += _pairwise_md(prows, f"{task}: permutation tests of {head_name}")
    return md, rows + prows


def _task_row(
    task: str, cond: Condition, m: str, lb: str, cell: Cell | None, seeds: Sequence[int],
    metrics: Sequence[tuple[str, str]], head: str,
) -> tuple[str, CsvRow]:  # fmt: skip
    """One method's row of a task table (Markdown line, CSV row): each metric's mean and
    bootstrap interval, and the headline's t-interval."""
    vals = []
    row: CsvRow = {"condition": cond.name, "unequal": cond.unequal,
                           "task": task, "method": m, "arm": lb}  # fmt: skip
    n = 0
    for key, _ in metrics:
        v = seed_values(cell, key, seeds)
        n = max(n, len(v))
        lo, hi = stats.bootstrap_ci(v) if v else (math.nan, math.nan)
        vals.append(_ci(v, lo, hi))
        row.update({f"{key}_mean": float(np.mean(v)) if v else math.nan,
                    f"{key}_ci_low": lo, f"{key}_ci_high": hi})  # fmt: skip
    v = seed_values(cell, head, seeds)
    tlo, thi = stats.t_interval(v) if v else (math.nan, math.nan)
    vals.append("-" if not v else f"[{tlo:.2f}, {thi:.2f}]")
    row.update({f"{head}_t_low": tlo, f"{head}_t_high": thi})
    row["n_seeds"] = n
    return f"| {_name(cond)} | {m} | `{lb}` | {n} | " + " | ".join(vals) + " |", row


def _full_groups(
    by: dict[tuple[str, str], Cell], conditions: Sequence[Condition], tasks: Sequence[str],
    seeds: Sequence[int], head: str,
) -> dict[tuple[str, ...], list[Condition]]:  # fmt: skip
    """The conditions whose every arm has every seed on the same tasks (two or more), grouped
    by those tasks (each group is read over its own full tasks)."""
    groups: dict[tuple[str, ...], list[Condition]] = {}
    for cond in conditions:
        full = tuple(
            t
            for t in tasks
            if all(
                len(seed_values(by.get((t, lb)), head, seeds)) == len(seeds)
                for _, lb in cond.methods
            )
        )
        if len(full) >= 2:
            groups.setdefault(full, []).append(cond)
    return groups


def _over_groups(
    by: dict[tuple[str, str], Cell], groups: dict[tuple[str, ...], list[Condition]],
    conditions: Sequence[Condition], seeds: Sequence[int], metrics: Sequence[tuple[str, str]],
    head: str,
) -> tuple[list[str], list[CsvRow]]:  # fmt: skip
    """Per group of :func:`_full_groups`: the summary over its tasks and the stratified
    permutation tests (Markdown lines, CSV rows)."""
    if not groups:
        return ["Over tasks: no condition has every seed of every arm on two tasks yet.", ""], []
    methods = list(dict.fromkeys(m for cond in conditions for m, _ in cond.methods))
    head_name = dict(metrics)[head]
    md: list[str] = []
    rows: list[CsvRow] = []
    for full, conds in groups.items():
        over, rows_g = _over_tasks(by, conds, methods, list(full), seeds, metrics, head)
        md += over
        prows = _pairwise(by, conds, list(full), seeds, head)
        md += _pairwise_md(prows, f"over {', '.join(full)}: stratified permutation tests "
                           f"of {head_name}")  # fmt: skip
        rows += rows_g + prows
    return md, rows


def _matrix(
    by: dict[tuple[str, str], Cell],
    label: str,
    key: str,
    tasks: Sequence[str],
    seeds: Sequence[int],
) -> np.ndarray:
    return np.array([[by[(t, label)].numbers[s][key] for t in tasks] for s in seeds], float)


def _over_tasks(
    by: dict[tuple[str, str], Cell], conditions: Sequence[Condition], methods: Sequence[str],
    full: Sequence[str], seeds: Sequence[int], metrics: Sequence[tuple[str, str]] = METRICS,
    head: str = "area",
) -> tuple[list[str], list[CsvRow]]:  # fmt: skip
    """The summary of ``conditions`` over the tasks ``full``: per condition and method the IQM
    of each metric and the optimality gap, then the probability of improvement of NDP over
    each other method and whether the paper's ordering holds (Markdown lines, CSV rows)."""
    head_name = dict(metrics)[head]
    md = [
        f"### Over tasks ({len(full)} tasks: {', '.join(full)}; {len(seeds)} seeds each)",
        "",
        "IQM over all runs (tasks x seeds) [95% stratified-bootstrap interval]; optimality gap "
        f"of the {head_name} (rliable: mean of max(1 - score, 0) over runs; lower is better):",
        "",
        "| condition | method | "
        + " | ".join(f"IQM {h}" for _, h in metrics)
        + f" | optimality gap, {head_name} |",
        "|---" * (3 + len(metrics)) + "|",
    ]
    rows: list[CsvRow] = []
    iqm_head: dict[tuple[str, str], float] = {}
    for cond in conditions:
        for m, lb in cond.methods:
            line, row = _iqm_row(by, cond, m, lb, full, seeds, metrics, head, iqm_head)
            md.append(line)
            rows.append(row)
    md.append("")
    # the methods some condition puts beside NDP (a method only in conditions without NDP, e.g.
    # the off-policy study's critic-input arms, would be a column of '-' in every row)
    with_ndp = [dict(c.methods) for c in conditions if "ndp" in dict(c.methods)]
    others = [m for m in methods if m != "ndp" and any(m in lab for lab in with_ndp)]
    if "ndp" in methods and others:
        pmd, prows = _improvement(by, conditions, others, full, seeds, metrics, head, iqm_head)
        md += pmd
        rows += prows
    return md, rows


def _iqm_row(
    by: dict[tuple[str, str], Cell], cond: Condition, m: str, lb: str, full: Sequence[str],
    seeds: Sequence[int], metrics: Sequence[tuple[str, str]], head: str,
    iqm_head: dict[tuple[str, str], float],
) -> tuple[str, CsvRow]:  # fmt: skip
    """One method's row over tasks (Markdown line, CSV row): each metric's IQM with its
    stratified-bootstrap interval and the headline's optimality gap; the headline's IQM is
    recorded in ``iqm_head``."""
    vals = []
    row: CsvRow = {"condition": cond.name, "unequal": cond.unequal,
                           "task": "IQM over tasks", "method": m, "arm": lb,
                           "n_seeds": len(seeds)}  # fmt: skip
    for key, _ in metrics:
        x = _matrix(by, lb, key, full, seeds)
        if not np.isfinite(x).all():  # a number some runs lack (trained without it)
            vals.append("-")
            row.update({f"{key}_mean": math.nan, f"{key}_ci_low": math.nan,
                        f"{key}_ci_high": math.nan})  # fmt: skip
            continue
        point = stats.iqm(x)
        lo, hi = stats.stratified_bootstrap_ci(x, stats.iqm)
        vals.append(f"{point:.2f} [{lo:.2f}, {hi:.2f}]")
        row.update({f"{key}_mean": point, f"{key}_ci_low": lo, f"{key}_ci_high": hi})
        if key == head:
            iqm_head[(cond.name, m)] = point
    x = _matrix(by, lb, head, full, seeds)
    gap = stats.optimality_gap(x)
    glo, ghi = stats.stratified_bootstrap_ci(x, stats.optimality_gap, reps=1000)
    vals.append(f"{gap:.2f} [{glo:.2f}, {ghi:.2f}]")
    row.update({"gap_mean": gap, "gap_ci_low": glo, "gap_ci_high": ghi})
    return f"| {_name(cond)} | {m} | " + " | ".join(vals) + " |", row


def _improvement(
    by: dict[tuple[str, str], Cell], conditions: Sequence[Condition], others: Sequence[str],
    full: Sequence[str], seeds: Sequence[int], metrics: Sequence[tuple[str, str]], head: str,
    iqm_head: dict[tuple[str, str], float],
) -> tuple[list[str], list[CsvRow]]:  # fmt: skip
    """P(NDP > other) per condition and shown metric, and whether the paper's ordering holds
    in the headline's IQM (Markdown lines, CSV rows)."""
    head_name = dict(metrics)[head]
    shown = [(k, h) for k, h in metrics if k in (head, "area", "final", "det_final")]
    heads = [f"P(NDP > {o}), {h}" for o in others for _, h in shown]
    md = [
        "Probability that an NDP run beats a run of the other method on the same task "
        "(ties count half; averaged over tasks) [95% stratified-bootstrap interval]; "
        "0.5 = neither is better. Paper's ordering: NDP > PPO-multi > PPO in the IQM of "
        f"the {head_name}.",
        "",
        "| condition | " + " | ".join(heads) + " | paper's ordering |",
        "|---" * (2 + len(heads)) + "|",
    ]
    rows: list[CsvRow] = []
    for cond in conditions:
        lab = dict(cond.methods)
        if "ndp" not in lab:
            continue
        vals = []
        for o in others:
            if o not in lab:
                vals += ["-"] * len(shown)
                continue
            for key, _ in shown:
                x = _matrix(by, lab["ndp"], key, full, seeds)
                y = _matrix(by, lab[o], key, full, seeds)
                if not (np.isfinite(x).all() and np.isfinite(y).all()):
                    vals.append("-")  # a number some of the runs lack
                    continue
                p = stats.probability_of_improvement(x, y)
                lo, hi = stats.probability_of_improvement_ci(x, y)
                vals.append(f"{p:.2f} [{lo:.2f}, {hi:.2f}]")
                rows.append({"condition": cond.name, "unequal": cond.unequal,
                             "task": "P(NDP > other)", "method": f"ndp > {o}",
                             "arm": f"{lab['ndp']} > {lab[o]}", "metric": key,
                             "p_mean": p, "p_ci_low": lo, "p_ci_high": hi})  # fmt: skip
        ordered = [m for m in ORDER if m in lab]
        holds = all(
            iqm_head[(cond.name, a)] > iqm_head[(cond.name, b)]
            for a, b in itertools.pairwise(ordered)
        )
        md.append(f"| {_name(cond)} | " + " | ".join(vals) + f" | {'yes' if holds else 'no'} |")
    md.append("")
    return md, rows


def _pairwise(
    by: dict[tuple[str, str], Cell], conditions: Sequence[Condition], tasks: Sequence[str],
    seeds: Sequence[int], head: str,
) -> list[CsvRow]:  # fmt: skip
    """For every condition and pair of its methods (table order) with every seed on ``tasks``:
    the mean difference of ``head`` over the tasks, its stratified permutation p-values
    (two-sided, and one-sided of "A > B" and "B > A"; :func:`stats.permutation_tests`) and the
    two-sided p Holm-adjusted within the condition's pairs (one family per condition and
    table: :func:`with_holm`)."""
    rows = []
    where = tasks[0] if len(tasks) == 1 else "over " + ", ".join(tasks)
    for cond in conditions:
        n = len(seeds)
        arms = [
            (m, lb)
            for m, lb in cond.methods
            if all(len(seed_values(by.get((t, lb)), head, seeds)) == n for t in tasks)
        ]
        family = []
        for (ma, la), (mb, lb) in itertools.combinations(arms, 2):
            x, y = _matrix(by, la, head, tasks, seeds), _matrix(by, lb, head, tasks, seeds)
            family.append({
                "condition": cond.name, "unequal": cond.unequal, "task": where,
                "method": f"{ma} vs {mb}", "arm": f"{la} vs {lb}", "metric": head,
                **_difference(x, y), "n_seeds": len(seeds),
            })  # fmt: skip
        rows += with_holm(family)
    return rows


def with_holm(family: list[CsvRow]) -> list[CsvRow]:
    """The rows of one family of pairwise tests (:func:`_difference` rows), each given its
    Holm-adjusted two-sided p (``p_holm``), the family's size (``holm_m``) and the
    convention's word (``significant``: Holm p <= :data:`stats.ALPHA`); returns ``family``."""
    adjusted = stats.holm([r["p_two_sided"] for r in family])
    for r, q in zip(family, adjusted, strict=True):
        r.update({"p_holm": float(q), "holm_m": len(family),
                  "significant": bool(q <= stats.ALPHA)})  # fmt: skip
    return family


def _p(p: float) -> str:
    """A p-value for a table: 3 decimals, or 2 significant digits below 0.001 (an exact test
    over 10 + 10 runs reaches 5.4e-06; '0.000' would read as impossible)."""
    return f"{p:.3f}" if p >= 0.001 else f"{p:.1e}"


SIGNIFICANCE_NOTE = (
    "p: two-sided; Holm p: adjusted by Holm's method within the family of {family} (m: its "
    "size); **significant** where Holm p <= 0.05, else not significant (the convention of "
    "docs/metrics.md). The one-sided p of each direction is kept beside them for the "
    "pre-registered readings stated on one-sided p (docs/rl-release.md, docs/rl-regimes.md): "
    "p(A > B) is the p of 'A above B', p(B > A) of 'B above A'. {floor}"
)
"""The legend of every pairwise table (``family``: what one family is there; ``floor``: the
smallest p the seeds allow)."""


def significance(r: CsvRow) -> str:
    """The convention's word for one pairwise row: ``**A > B**`` / ``**B > A**`` (names from
    its ``method``, "A vs B") where Holm p <= alpha, else ``not significant``."""
    if not r.get("significant"):
        return "not significant"
    a, b = str(r["method"]).split(" vs ", 1)
    return f"**{a} > {b}**" if float(r["diff_mean"]) > 0 else f"**{b} > {a}**"


def pvalue_cells(r: CsvRow) -> str:
    """The p columns of a pairwise row: two-sided p, Holm p (m), the convention's word, both
    one-sided p, the test."""
    keys = ("p_two_sided", "p_holm", "p_a_greater", "p_b_greater")
    two, holm, a_gt, b_gt = (_p(float(r[k])) for k in keys)
    return f"{two} | {holm} ({r['holm_m']}) | {significance(r)} | {a_gt} | {b_gt} | {r['p_method']}"


P_HEADS = ("p (two-sided) | Holm p (m) | Holm p <= 0.05 | one-sided p(A > B) | "
           "one-sided p(B > A) | test")  # fmt: skip
"""The headings of :func:`pvalue_cells`."""


def _pairwise_md(rows: Sequence[CsvRow], title: str) -> list[str]:
    if not rows:
        return []
    floor = "With 3 + 3 seeds on one task the smallest one-sided p is 0.05, two-sided 0.1."
    md = [
        f"{title} (labels exchanged within each task; test: exact over every split, or "
        "Monte Carlo where the splits are too many; A - B: the mean difference over tasks, with "
        "its Welch 95% t-interval stratified by task). "
        + SIGNIFICANCE_NOTE.format(family="one condition's rows of this table", floor=floor),
        "",
        f"| condition | A vs B | A - B | 95% t-interval | {P_HEADS} |",
        "|---" * (4 + P_HEADS.count("|") + 1) + "|",
    ]
    for r in rows:
        cond = f"{r['condition']} (UNEQUAL)" if r["unequal"] else r["condition"]
        ci = interval(float(r["diff_t_low"]), float(r["diff_t_high"]))
        md.append(f"| {cond} | {r['method']} | {r['diff_mean']:+.3f} | {ci} | {pvalue_cells(r)} |")
    return [*md, ""]


def _profiles(
    by: dict[tuple[str, str], Cell], groups: dict[tuple[str, ...], list[Condition]],
    seeds: Sequence[int], head: str, head_name: str, out: Path, foot: str,
) -> Path:  # fmt: skip
    """``<out>-profiles.png``: rliable performance profiles (the fraction of runs over the
    condition's tasks scoring above tau, with its stratified-bootstrap band) of the headline
    number, one panel per condition."""
    import matplotlib

    matplotlib.use("Agg")
    import textwrap

    import matplotlib.pyplot as plt

    panels = [(full, cond) for full, conds in groups.items() for cond in conds]
    cols = min(3, len(panels))
    nrows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.2 * nrows + 0.4),
                             squeeze=False)  # fmt: skip
    taus = np.linspace(0.0, 1.0, 51)
    for ax, (full, cond) in zip(axes.ravel(), panels, strict=False):
        scores = {m: _matrix(by, lb, head, full, seeds) for m, lb in cond.methods}
        prof, ci = stats.performance_profile(scores, taus)
        for m in scores:
            (line,) = ax.plot(taus, prof[m], label=m, lw=1.6)
            ax.fill_between(taus, ci[m][0], ci[m][1], color=line.get_color(), alpha=0.15, lw=0)
        ax.set_title(_name(cond) + f"\n({len(full)} tasks x {len(seeds)} seeds)", fontsize=8)
        ax.set_xlabel(f"{head_name} tau", fontsize=8)
        ax.set_ylabel("fraction of runs > tau", fontsize=8)
        ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes.ravel()[len(panels) :]:
        ax.axis("off")
    lines = textwrap.wrap(foot, 170) or [""]
    fig.text(0.01, 0.005, "\n".join(lines), fontsize=5, color="0.35", ha="left", va="bottom")
    fig.tight_layout(rect=(0, 0.02 + 0.02 * len(lines), 1, 1))
    path = out.with_name(f"{out.name}-profiles.png")
    atomic_savefig(fig, path, dpi=80)
    plt.close(fig)
    return path


def _plot(
    rows: Sequence[CsvRow], conditions: Sequence[Condition], out: Path, foot: str,
    metrics: Sequence[tuple[str, str]] = METRICS,
) -> Path:  # fmt: skip
    """``<out>-conditions.png``: IQM with its interval per condition and method, one panel per
    number."""
    import matplotlib

    matplotlib.use("Agg")
    import textwrap

    import matplotlib.pyplot as plt

    iq = [r for r in rows if r["task"] == "IQM over tasks"]
    methods = list(dict.fromkeys(r["method"] for r in iq))
    names = [c.name for c in conditions]
    fig, axes = plt.subplots(1, len(metrics), figsize=(4.0 * len(metrics), 1.2 + 0.55 * len(names)),
                             sharey=True, squeeze=False)  # fmt: skip
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (key, head) in zip(axes[0], metrics, strict=True):
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
    atomic_savefig(fig, path, dpi=90)
    plt.close(fig)
    return path


PAIRWISE_MAX_METHODS = 8
"""A task with more methods than this gets no pairwise table (28 pairs at 8; a study of 20 arms
would print 190 per task and number): the report says so and how to narrow it."""


def _difference(x: np.ndarray, y: np.ndarray) -> CsvRow:
    """Runs ``x`` [n_a, tasks] against ``y`` [n_b, tasks]: the mean difference over tasks, its
    Welch 95% t-interval (NaN with a single run on a side), the permutation p-values
    (two-sided, and one-sided of each direction; all stratified by task) and how they were
    computed (``p_method``: exact or Monte Carlo, with the count)."""
    lo, hi = stats.difference_t_interval(x, y) if min(len(x), len(y)) >= 2 else (math.nan, math.nan)
    test = stats.permutation_tests(x, y)
    return {
        "diff_mean": float((x.mean(0) - y.mean(0)).mean()), "diff_t_low": lo, "diff_t_high": hi,
        "p_two_sided": test.two_sided, "p_a_greater": test.greater, "p_b_greater": test.less,
        "p_method": test.method,
    }  # fmt: skip


def _pair_row(task: str, key: str, a: str, b: str, x: np.ndarray, y: np.ndarray) -> CsvRow:
    """One pairwise row: runs ``x`` [n_a, tasks] of method ``a`` against ``y`` [n_b, tasks]."""
    return {"task": task, "metric": key, "method": f"{a} vs {b}", "n_a": len(x), "n_b": len(y),
            **_difference(x, y)}  # fmt: skip


def pairwise_section(cells: Sequence[Cell]) -> tuple[list[str], list[CsvRow]]:
    """For a report without conditions: on every task, each pair of its methods (table order)
    with two runs or more each, the difference of the headline number (the deterministic
    success area where the runs have it, and the training-episode area always), its Welch
    95% t-interval (:func:`stats.difference_t_interval`) and the permutation p-values
    (:func:`stats.permutation_tests`, runs as the unit; the seeds of the two cells may differ):
    two-sided, Holm-adjusted within the pairs of one task and number (a family), and
    one-sided of each direction. With two tasks or more, each pair with runs of the same seeds
    on every task also gets a row over all of them: the mean difference over tasks, stratified
    by task (labels exchanged within each task; one family per number). Returns (markdown, CSV
    rows)."""
    metrics, headline = metrics_of(cells)
    keys = [headline] + (["area"] if headline != "area" else [])
    names = dict(metrics)
    rows: list[CsvRow] = []
    crowded: list[str] = []
    tasks = list(dict.fromkeys(c.task for c in cells))
    for task in tasks:
        here = [c for c in cells if c.task == task and c.numbers]  # methods with runs here
        if len(here) > PAIRWISE_MAX_METHODS:
            crowded.append(f"{task} ({len(here)} methods)")
            continue
        for key in keys:
            vals = {c.label: seed_values(c, key, sorted(c.numbers)) for c in here}
            usable = [c for c in here if len(vals[c.label]) >= 2]
            family = []
            for a, b in itertools.combinations(usable, 2):
                x = np.array(vals[a.label])[:, None]
                y = np.array(vals[b.label])[:, None]
                family.append(_pair_row(task, key, a.label, b.label, x, y))
            rows += with_holm(family)
    if len(tasks) >= 2 and not crowded:
        rows += _pooled_pairs(cells, tasks, keys)
    left_out = (
        [f"Pairwise tests left out on {', '.join(crowded)}: more than {PAIRWISE_MAX_METHODS} "
         "methods on a task; `--methods A B ...` narrows the report to the pairs to test.", ""]
        if crowded else []
    )  # fmt: skip
    if not rows:
        return left_out, []
    md = [*left_out, *_pairwise_head()]
    for r in rows:
        md.append(
            f"| {r['task']} | {names.get(str(r['metric']), r['metric'])} | {r['method']} "
            f"| {r['n_a']} + {r['n_b']} | {r['diff_mean']:+.3f} "
            f"| {interval(float(r['diff_t_low']), float(r['diff_t_high']))} | {pvalue_cells(r)} |"
        )
    return [*md, ""], rows


def _pairwise_head() -> list[str]:
    """The legend and table head of :func:`pairwise_section`."""
    floor = ("With 3 + 3 runs the smallest one-sided p is 0.05 (two-sided 0.1), with 10 + 10 "
             "about 5e-6.")  # fmt: skip
    return [
        "Pairwise: permutation tests over runs, per task (labels exchanged between the two "
        "methods' runs; A - B: the difference of the means, with its Welch 95% t-interval). "
        "'All tasks': the mean over tasks of the per-task difference, labels exchanged within "
        "each task, on the seeds each method has on every task. Test: exact over every split up "
        f"to {stats.PERMUTATION_EXACT_LIMIT:,} combined splits, else Monte Carlo over "
        f"{stats.PERMUTATION_SAMPLES:,} random ones (p >= 1 / {stats.PERMUTATION_SAMPLES + 1:,}). "
        + SIGNIFICANCE_NOTE.format(
            family="the pairs of one task (or of all tasks) and one number", floor=floor
        ),
        "",
        f"| task | number | A vs B | runs | A - B | 95% t-interval | {P_HEADS} |",
        "|---" * (6 + P_HEADS.count("|") + 1) + "|",
    ]


def _pooled_pairs(cells: Sequence[Cell], tasks: Sequence[str], keys: Sequence[str]) -> list[CsvRow]:
    """Rows over every task for each pair of methods present on all of ``tasks``: each
    method's runs are its seeds with a number on every task (2 or more)."""
    by = {(c.task, c.label): c for c in cells if c.numbers}
    labels = [lb for lb in dict.fromkeys(c.label for c in cells)
              if all((t, lb) in by for t in tasks)]  # fmt: skip
    where = "all tasks (" + ", ".join(tasks) + ")"
    rows = []
    for key in keys:
        common: dict[str, list[int]] = {}
        for lb in labels:
            seeds = sorted(set.intersection(*(
                {s for s, n in by[(t, lb)].numbers.items() if not math.isnan(n[key])}
                for t in tasks
            )))  # fmt: skip
            if len(seeds) >= 2:
                common[lb] = seeds
        family = []
        for a, b in itertools.combinations(list(common), 2):
            x = _matrix(by, a, key, tasks, common[a])
            y = _matrix(by, b, key, tasks, common[b])
            family.append(_pair_row(where, key, a, b, x, y))
        rows += with_holm(family)
    return rows
