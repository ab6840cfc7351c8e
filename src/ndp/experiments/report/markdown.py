"""A report's Markdown: the header (command, commits, environments), the RL success table, the
imitation and behaviour-cloning tables, and the summary over tasks; each a function of cells
returning lines (:func:`markdown` puts them together)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ndp.experiments.report.cells import Cell, fmt_stat
from ndp.experiments.report.conditions import metrics_of
from ndp.experiments.report.fresh import NO_FRESH_EVAL, PERIODIC_EVAL_EPISODES, FreshEval
from ndp.experiments.report.paths import with_ext
from ndp.experiments.report.provenance import ReportProvenance, commits_text, provenance_lines
from ndp.experiments.rows import DET_KEYS, has_det
from ndp.rl.config import EVAL_SEED


def short_of_budget(cells: Sequence[Cell]) -> list[str]:
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


def markdown(
    title: str,
    rl_cells: Sequence[Cell],
    il_cells: Sequence[Cell],
    budgets: Sequence[int],
    expected: Sequence[int],
    prov: ReportProvenance,
    pngs: Sequence[Path],
    out: Path,
    fresh: FreshEval = NO_FRESH_EVAL,
) -> list[str]:
    """The report's Markdown lines: header, success table and summary over tasks (RL cells),
    imitation table, figures and the CSV's name (the sections go in later); ``fresh``: the
    report's own deterministic evaluation (a column where it has episodes)."""
    md = header_lines(title, prov, expected, [*rl_cells, *il_cells])
    md += short_of_budget(rl_cells)
    if rl_cells:
        md += success_table(rl_cells, budgets, fresh)
        md += over_tasks(rl_cells)
    if il_cells:
        md += imitation_table(il_cells)
    md += [f"![{p.stem}]({p.name})" for p in pngs]
    md += ["", f"CSV: `{with_ext(out, '.csv').name}`."]
    return md


def header_lines(
    title: str, prov: ReportProvenance, expected: Sequence[int], cells: Sequence[Cell]
) -> list[str]:
    """Title, command, commits, environments and seeds; a WARNING when ``cells`` lack seeds."""
    md = [
        f"# {title}",
        "",
        f"Command: `{prov['command']}`  ",
        f"Commit: {prov['commit']}, date: {prov['date']}; runs trained at commits: "
        f"{commits_text(prov['run_commits'])}.  ",
        *provenance_lines(prov),
        f"Seeds per cell: {list(expected)}; mean +- std over seeds (population std).",
        "",
    ]
    missing = [c for c in cells if c.missing]
    if missing:
        md += [
            f"**WARNING: seeds are missing from {len(missing)} cells (marked MISSING below); "
            "their numbers are over fewer seeds.**",
            "",
        ]
    return md


def _det_note(rl_cells: Sequence[Cell]) -> list[str]:
    """What the deterministic columns are (headline or not), or nothing without them."""
    if not has_det(rl_cells):
        return []
    headline = metrics_of(rl_cells)[1] == "det_area"
    return [
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


def fresh_seeds_note(fresh: FreshEval) -> str:
    """The seeds of the report's own evaluation and whether they overlap the periodic
    evaluation's fixed ones (``seeds 20,000 to 20,099, disjoint from ...``)."""
    periodic = f"{EVAL_SEED:,} to {EVAL_SEED + PERIODIC_EVAL_EPISODES - 1:,}"
    return f"seeds {fresh.seed:,} to {fresh.last_seed:,}, " + (
        f"overlapping the periodic evaluation's fixed seeds ({periodic} by default)"
        if fresh.overlaps_periodic()
        else f"disjoint from the periodic evaluation's fixed seeds ({periodic} by default)"
    )


def _success_note(fresh: FreshEval) -> str:
    """What the success columns are."""
    return (
        "Success: `charts/success_any` of the training episodes. Success @ b: mean over the "
        "updates in the last 10% of [0, b] (`-`: no update logged by b, or b past the "
        "budget); area: the success curve averaged over the "
        "budget; final: last 10% of updates; final (final step): the same for "
        "`charts/success_final`, success at the episode's last step (the release's metric); "
        "live return: `charts/episode_return_live` over the last 10% of updates."
        + (_fresh_note(fresh) if fresh.episodes else "")
    )


def _fresh_note(fresh: FreshEval) -> str:
    """What the report's own deterministic column is, on which seeds."""
    sb3 = (
        "their own evaluation at the end of training, the same seeds, `ndp.sb3.runs`"
        if fresh.seed == EVAL_SEED
        else f"`-` (they evaluate themselves on seeds from {EVAL_SEED:,} only, `ndp.sb3.runs`)"
    )
    return (
        f" Deterministic: success (any step) of the trained policy's mode over "
        f"{fresh.episodes} fresh episodes per run (`ndp rl eval`, {fresh_seeds_note(fresh)}; "
        f"Stable-Baselines3 runs: {sb3})."
    )


def success_table(
    rl_cells: Sequence[Cell], budgets: Sequence[int], fresh: FreshEval = NO_FRESH_EVAL
) -> list[str]:
    """The RL table: one row per task x method, success at each budget, area, final success,
    live return (and the deterministic columns where runs have them), with its notes."""
    heads = [f"success @ {b:,}" for b in budgets]
    det = has_det(rl_cells)
    md = _det_note(rl_cells)
    md += [
        _success_note(fresh),
        "",
        "| task | method | n | "
        + ("det. area | det. final | det. final (final step) | " if det else "")
        + " | ".join(heads)
        + " | success area | final success | final success (final step) | final live return |"
        + (" deterministic success |" if fresh.episodes else ""),
        "|---" * (7 + 3 * det + len(heads) + bool(fresh.episodes)) + "|",
    ]
    for c in rl_cells:
        vals = [fmt_stat(*c.stat(k)) for k in DET_KEYS] if det else []
        vals += [fmt_stat(*c.stat(f"at:{b}")) for b in budgets]
        vals += [fmt_stat(*c.stat(k)) for k in ("area", "final", "final_last")]
        vals += [fmt_stat(*c.stat("return"), 1)]
        vals += [fmt_stat(*c.stat("det"))] if fresh.episodes else []
        n = c.n_seeds_cell()
        md.append(f"| {c.task} | {c.label} | {n} | " + " | ".join(vals) + " |")
    md.append("")
    return md


def imitation_table(il_cells: Sequence[Cell]) -> list[str]:
    """The imitation table: test MSE and DTW per data set x model."""
    md = [
        "Imitation: test MSE (px^2) and DTW distance (px) of each run's evaluation.",
        "",
        "| data | model | n | test MSE px^2 | test DTW px |",
        "|---|---|---|---|---|",
    ]
    for c in il_cells:
        n = c.n_seeds_cell()
        mse, dtw = fmt_stat(*c.stat("mse")), fmt_stat(*c.stat("dtw"))
        md.append(f"| {c.task} | {c.label} | {n} | {mse} | {dtw} |")
    md.append("")
    return md


def with_bc_table(md: list[str], bc_cells: Sequence[Cell]) -> None:
    """Insert the behaviour-cloning table into ``md`` after the header (nothing without
    cloning cells)."""
    if bc_cells:
        at = md.index("", md.index(next(x for x in md if x.startswith("Seeds per cell")))) + 1
        md[at:at] = bc_markdown(bc_cells)


def bc_markdown(cells: Sequence[Cell]) -> list[str]:
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
            f"| {c.task} | {c.label} | {n} | {fmt_stat(*c.stat('success'))} | "
            + " | ".join("-" if math.isnan(v) else f"{v:.3g}" for v in (fit, jerk))
            + f" | {'-' if math.isnan(sparc) else f'{sparc:.2f}'} |"
        )
    return [*md, ""]


def task_grid(
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


def over_tasks(cells: Sequence[Cell]) -> list[str]:
    """Mean over tasks per method (tasks where every method has a value) and how many tasks
    NDP >= each other method (final success), the paper's MT50 summary, split into higher, equal
    (and how many of those are both at 0, where the count says nothing) and lower."""
    tasks, labels, by, full = task_grid(cells)
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
