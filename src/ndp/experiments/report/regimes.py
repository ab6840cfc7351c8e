"""The pre-registered readings of ``ndp-regimes`` and ``ndp-regimes-1m`` (docs/rl-regimes.md),
applied by code so that a table states them as they were written before the runs.

Every reading uses the **deterministic success area** (``det_area``: the mean of
``eval/success_any`` over a run's periodic evaluations) and the runs of the report's seeds. A
reading whose arms lack seeds says what it waits for instead of a verdict. The arm pools and
rules are the registration's:

1. / 2. Per task, the best NDP arm (over k, noise and the stale rule), the best PPO-multi arm and
   the best PPO arm (white or AR(1)), each by mean area. NDP's structure **helps** if its best
   is above PPO-multi's best on every task, with the one-sided stratified permutation
   p(NDP > PPO-multi) < 0.05 over the tasks' runs, and not below PPO's best by more than 0.05
   on any task; it **does not help** if PPO-multi's best is at least NDP's on every task; else
   **mixed**.
3. The metric: NDP's det. area minus its training-episode area, against PPO-multi's, averaged
   over tasks and k.
4. Compression (and 8 at 1M): NDP's area at k = 10, 20 against k = 5 while PPO-multi's falls.
5. Exploration: parameter and AR(1) noise against white at the same k, per method.
6. The stale rule: the live-reward arms against k = 5 white, per method.
7. The best k for the AR(1) arms: the k with the highest NDP white-noise area over the tasks.

``mt50-attribution``: "the MT50 direction holds" if NDP is ahead of PPO over the study's tasks
(one-sided stratified permutation p(NDP > PPO) < 0.05 of the det. area; over 7 tasks the splits
are too many to enumerate, so the test is Monte Carlo and its table says so); the same test of
the final success (the metric of the MT50 claim) and against PPO-multi is given beside it, with
the two-sided p and Holm's correction of docs/metrics.md.

Every p a reading's rule uses is one-sided, as registered (docs/rl-regimes.md); the tables name
each one's direction, ``one-sided p(A > B)``, and label how it was computed (exact permutation
over all splits, or Monte Carlo).

Choosing the best arm on the runs that are then compared favours the side with more arms
(NDP's pool is larger than PPO-multi's): a "helps" would need that caveat, a "does not help"
is conservative.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ndp.experiments.report import stats
from ndp.experiments.report.cells import Cell, CsvRow
from ndp.experiments.report.readings import HEAD, ArmRuns, compare_test, fmt, interval

KS = (5, 10, 20)
"""The chunk sizes of the study."""
NDP_POOL = (
    *(f"ndp-k{k}" for k in KS),
    *(f"ndp-param-k{k}" for k in KS),
    *(f"ndp-ar1-k{k}" for k in KS),
    "ndp-nostale",
)
"""Reading 1's NDP arms (over k, noise, stale rule); an arm with no runs at all is left out."""
PPO_MULTI_POOL = (
    *(f"ppo-multi-k{k}" for k in KS),
    *(f"ppo-multi-ar1-k{k}" for k in KS),
    "ppo-multi-nostale",
)
"""Reading 1's PPO-multi arms."""
PPO_POOL = ("ppo", "ppo-ar1")
"""Reading 1's PPO arms (k = 1, white or AR(1))."""
CONDITIONAL = tuple(f"{m}-ar1-k{k}" for m in ("ndp", "ppo-multi") for k in KS[1:])
"""Pool arms that run only if reading 7 picks their k: in a pool only once they have runs; every
other pool arm is required (a reading waits for it)."""
MARGIN = 0.05
"""Reading 1: how far below PPO's best NDP's best may be on a task."""
ALPHA = 0.05
"""Reading 1: the stratified permutation p below which NDP's best is "above"."""


def _start(
    cells: Sequence[Cell], seeds: Sequence[int], title: str
) -> tuple[ArmRuns, list[str], list[str]]:
    """The readings' start: the arms' runs (the conditional arms optional), the tasks in the
    cells' order, and the section's first lines (``## <title> (docs/rl-regimes.md)``, blank)."""
    r = ArmRuns(cells, seeds, CONDITIONAL)
    return r, list(dict.fromkeys(c.task for c in cells)), [f"## {title} (docs/rl-regimes.md)", ""]


def regimes_readings(cells: Sequence[Cell], seeds: Sequence[int]) -> tuple[list[str], list[CsvRow]]:
    """(Markdown lines, CSV rows) of the readings of ``ndp-regimes`` (see the module doc).

    Args:
        cells: the report's RL cells (``task``, ``label``, ``numbers`` per seed).
        seeds: the seeds every arm should have.
    """
    r, tasks, md = _start(cells, seeds, "Pre-registered readings")
    md += [
        f"Applied by code (`ndp.experiments.report.regimes`) to the deterministic success area "
        f"of seeds {' '.join(map(str, seeds))} on {', '.join(tasks)}. A reading whose arms lack "
        "seeds waits for them.",
        "",
    ]
    rows: list[CsvRow] = []
    md += _best_arms(r, tasks, rows)
    md += _metric(r, tasks, rows)
    md += compression(r, tasks, rows, number="4")
    md += _changes(r, tasks, rows)
    md += _best_k(r, tasks, rows)
    return md + r.waiting_line("these readings wait"), rows


def regimes_1m_readings(
    cells: Sequence[Cell], seeds: Sequence[int]
) -> tuple[list[str], list[CsvRow]]:
    """(Markdown lines, CSV rows) of ``ndp-regimes-1m``'s reading 8: reading 4's rule at 1M
    env steps, and NDP against PPO-multi at each k (permutation p, one-sided of each direction
    and two-sided with Holm's correction over the three k)."""
    r, tasks, md = _start(cells, seeds, "Pre-registered reading 8")
    md += [
        f"Deterministic success area, seeds {' '.join(map(str, seeds))}, {', '.join(tasks)}."
        + (" One seed: a direction, not a result." if len(seeds) == 1 else ""),
        "",
    ]
    rows: list[CsvRow] = []
    md += compression(r, tasks, rows, number="8")
    md += [
        "NDP against PPO-multi at each k: the one-sided p of each direction (as registered), "
        "and the two-sided p with Holm's correction over the three k (docs/metrics.md: "
        "significant where Holm p <= 0.05).",
        "",
        "| k | NDP | PPO-multi | NDP - PPO-multi | one-sided p(NDP > PPO-multi) "
        "| one-sided p(PPO-multi > NDP) | p (two-sided) | Holm p | test |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    found: list[tuple[int, Any]] = []  # (k, (x, y, d, test) or None)
    for k in KS:
        x = r.matrix(tasks, [f"ndp-k{k}"] * len(tasks))
        y = r.matrix(tasks, [f"ppo-multi-k{k}"] * len(tasks))
        if x is None or y is None:
            found.append((k, None))
            continue
        d, test = compare_test(x, y)
        found.append((k, (x, y, d, test)))
    holm = iter(stats.holm([t[3].two_sided for _, t in found if t is not None]))
    for k, got in found:
        if got is None:
            md.append(f"| {k} | - | - | - | - | - | - | - | - |")
            continue
        x, y, d, test = got
        q = float(next(holm))
        md.append(f"| {k} | {x.mean():.2f} | {y.mean():.2f} | {d:+.2f} | {test.greater:.3f} "
                  f"| {test.less:.3f} | {test.two_sided:.3f} | {q:.3f} "
                  f"| {test.method} |")  # fmt: skip
        rows.append({"reading": "8", "item": f"ndp-k{k} vs ppo-multi-k{k}", "task": "all",
                     "value": d, "p_greater": test.greater, "p_less": test.less,
                     "p_two_sided": test.two_sided, "p_holm": q,
                     "p_method": test.method})  # fmt: skip
    md.append("")
    md += _k_ranking(r, tasks, rows)
    return md + r.waiting_line("this reading waits"), rows


def _k_ranking(r: ArmRuns, tasks: Sequence[str], rows: list[CsvRow]) -> list[str]:
    """Reading 8's ranking of k per method by mean area over ``tasks`` (to set beside the
    300k study's ranking, which lives in another runs directory)."""
    out = []
    for m, name in (("ndp", "NDP"), ("ppo-multi", "PPO-multi")):
        areas = {k: float(np.mean([r.mean(t, f"{m}-k{k}") for t in tasks])) for k in KS}
        if any(math.isnan(v) for v in areas.values()):
            continue
        order = sorted(KS, key=lambda k: (-areas[k], k))
        rank = " > ".join(f"k = {k} ({areas[k]:.2f})" for k in order)
        out.append(f"{name} {rank}")
        rows.append({"reading": "8", "item": f"{m} ranking of k", "task": "all",
                     "value": " > ".join(map(str, order))})  # fmt: skip
    if not out:
        return []
    return ["Ranking of k by mean area (compare with the 300k study's, `ndp-regimes`): "
            + "; ".join(out) + ".", ""]  # fmt: skip


def _best(r: ArmRuns, task: str, pool: Sequence[str]) -> tuple[str, float] | None:
    """The arm of ``pool`` with the highest mean area on ``task`` (ties: the first); None
    while any of the pool's arms lacks seeds."""
    means = {lb: r.mean(task, lb) for lb in r.pool(pool)}
    if not means or any(math.isnan(v) for v in means.values()):
        return None
    lb = max(means, key=lambda k: means[k])
    return lb, means[lb]


def _best_arms(r: ArmRuns, tasks: Sequence[str], rows: list[CsvRow]) -> list[str]:
    md = [
        "**1-2. Does NDP's structure help?** Per task the best arm of each method by mean area "
        "(NDP over k, noise and the stale rule; PPO-multi likewise; PPO white or AR(1)):",
        "",
        "| task | best NDP arm | area | best PPO-multi arm | area | best PPO arm | area |",
        "|---|---|---|---|---|---|---|",
    ]
    best: dict[str, list[tuple[str, float] | None]] = {}
    for t in tasks:
        b = [_best(r, t, p) for p in (NDP_POOL, PPO_MULTI_POOL, PPO_POOL)]
        best[t] = b
        shown = ("(waits) | -" if a is None else f"`{a[0]}` | {a[1]:.2f}" for a in b)
        md.append(f"| {t} | " + " | ".join(shown) + " |")
        for name, a in zip(("ndp", "ppo-multi", "ppo"), b, strict=True):
            if a is not None:
                rows.append({"reading": "1", "item": f"best {name} arm", "task": t,
                             "arm": a[0], "value": a[1]})  # fmt: skip
    md.append("")
    if any(x is None for b in best.values() for x in b):
        return [*md, "Verdict: waits for every arm of the pools.", ""]
    x = r.matrix(tasks, [best[t][0][0] for t in tasks])  # type: ignore[index]
    y = r.matrix(tasks, [best[t][1][0] for t in tasks])  # type: ignore[index]
    assert x is not None and y is not None  # every pool arm is complete
    d, test = compare_test(x, y)
    p = test.greater
    above = all(best[t][0][1] > best[t][1][1] for t in tasks)  # type: ignore[index]
    not_below_ppo = all(best[t][0][1] >= best[t][2][1] - MARGIN for t in tasks)  # type: ignore[index]
    at_most = all(best[t][1][1] >= best[t][0][1] for t in tasks)  # type: ignore[index]
    if above and p < ALPHA and not_below_ppo:
        verdict = "**helps** (reading 1)"
    elif at_most:
        verdict = "**does not help** (reading 2: PPO-multi's best is at least NDP's on every task)"
    else:
        verdict = "**mixed** (neither rule holds; read task by task)"
    md += [
        f"Best NDP - best PPO-multi, mean over tasks: {d:+.2f}; one-sided p(best NDP > best "
        f"PPO-multi) = {p:.3g} (the registered rule's test; two-sided p = {test.two_sided:.3g}; "
        f"{test.method}, stratified by task). NDP's best above PPO-multi's on every task: "
        f"{'yes' if above else 'no'}; not more than {MARGIN} below PPO's best on any task: "
        f"{'yes' if not_below_ppo else 'no'}. Verdict: {verdict}.",
        "(The best arm is chosen on the runs it is then compared on, which favours the side with "
        "more arms: NDP's.)",
        "",
    ]
    rows.append({"reading": "1-2", "item": "verdict", "task": "all", "value": d,
                 "p_greater": p, "p_two_sided": test.two_sided, "p_method": test.method,
                 "verdict": verdict.split("**")[1]})  # fmt: skip
    return md


def _metric(r: ArmRuns, tasks: Sequence[str], rows: list[CsvRow]) -> list[str]:
    gaps: dict[str, list[float]] = {"ndp": [], "ppo-multi": []}
    for m in gaps:
        for k in KS:
            for t in tasks:
                gaps[m].append(r.mean(t, f"{m}-k{k}") - r.mean(t, f"{m}-k{k}", "area"))
    if any(math.isnan(v) for g in gaps.values() for v in g):
        return ["**3. The metric**: waits for the white-noise k arms.", ""]
    g_n, g_m = float(np.mean(gaps["ndp"])), float(np.mean(gaps["ppo-multi"]))
    more = g_n > g_m
    rows.append({"reading": "3", "item": "det - training area, ndp minus ppo-multi",
                 "task": "all", "value": g_n - g_m})  # fmt: skip
    return [
        f"**3. The metric**: deterministic minus training-episode area, mean over tasks and k: "
        f"NDP {g_n:+.2f}, PPO-multi {g_m:+.2f}. "
        + (f"The stochastic tables under-rated NDP relative to PPO-multi by {g_n - g_m:.2f}."
           if more else "The stochastic tables did not under-rate NDP relative to PPO-multi."),
        "",
    ]  # fmt: skip


def compression(r: ArmRuns, tasks: Sequence[str], rows: list[CsvRow], number: str) -> list[str]:
    """Reading 4 (8 at 1M): per larger k, the change of NDP's and PPO-multi's area from k = 5
    (mean over ``tasks``, and per task)."""
    md = [
        f"**{number}. Compression**: change of the area from k = 5 (mean over "
        f"{', '.join(tasks)}{'; per task in brackets' if len(tasks) > 1 else ''}):",
        "",
        "| k | NDP | PPO-multi | reading |",
        "|---|---|---|---|",
    ]
    for k in KS[1:]:
        d: dict[str, list[float]] = {}
        for m in ("ndp", "ppo-multi"):
            d[m] = [r.mean(t, f"{m}-k{k}") - r.mean(t, f"{m}-k5") for t in tasks]
        if any(math.isnan(v) for v in (*d["ndp"], *d["ppo-multi"])):
            md.append(f"| {k} | (waits) | (waits) | - |")
            continue
        n, p = float(np.mean(d["ndp"])), float(np.mean(d["ppo-multi"]))
        if n > 0 and p < 0:
            what = "the DMP's compression pays off"
        elif n < 0 and p < 0:
            what = "both fall: the longer open-loop chunk costs more than compression gains"
        else:
            what = "neither rule (description only)"

        def cell(v: list[float], mean: float) -> str:
            per = " (" + ", ".join(f"{x:+.2f}" for x in v) + ")" if len(v) > 1 else ""
            return f"{mean:+.2f}{per}"

        md.append(f"| {k} | {cell(d['ndp'], n)} | {cell(d['ppo-multi'], p)} | {what} |")
        rows.append({"reading": number, "item": f"k{k} - k5", "task": "all", "value": n,
                     "value_ppo_multi": p, "verdict": what})  # fmt: skip
    return [*md, ""]


def _change(change: str, k: int, methods: Sequence[str], suffix: str) -> list[Change]:
    """One change at k for each of ``methods``: the arm ``<method>-<suffix>`` against the
    method's arm at that k (``<method>-k<k>``; PPO's at k = 1 is ``ppo``)."""
    return [(f"{change}, k = {k}", m, f"{m}-{suffix}", m if k == 1 else f"{m}-k{k}")
            for m in methods]  # fmt: skip


Change = tuple[str, str, str, str]
"""(change, method, arm, its reference arm)."""

CHANGES: tuple[Change, ...] = (
    *(c for k in (5, 10, 20) for c in _change("parameter noise", k, ("ndp",), f"param-k{k}")),
    *_change("AR(1)", 5, ("ndp", "ppo-multi"), "ar1-k5"),
    *_change("AR(1)", 1, ("ppo",), "ar1"),
    *(c for k in (10, 20) for c in _change("AR(1)", k, ("ndp", "ppo-multi"), f"ar1-k{k}")),
    *_change("live reward (no stale world)", 5, ("ndp", "ppo-multi"), "nostale"),
    *_change("N 10 (ndp-settings' winner; not in reading 1's pool)", 5, ("ndp",), "tuned"),
)
"""Readings 5 and 6 (and the tuned arm): (change, method, arm, its reference arm)."""


def _changes(r: ArmRuns, tasks: Sequence[str], rows: list[CsvRow]) -> list[str]:
    md = [
        "**5-6. Exploration and the stale rule**: change of the area against the same method's "
        "white-noise arm at the same k (arms not run are left out):",
        "",
        "| change | method | arm | " + " | ".join(tasks) + " | mean |",
        "|---|---|---|" + "---|" * (len(tasks) + 1),
    ]
    delta: dict[tuple[str, str], float] = {}
    for change, method, arm, ref in CHANGES:
        if arm not in r.labels:
            continue
        d = [r.mean(t, arm) - r.mean(t, ref) for t in tasks]
        mean = float(np.mean(d))
        delta[(change, method)] = mean
        md.append(f"| {change} | {method} | `{arm}` | " + " | ".join(fmt(x, True) for x in d)
                  + f" | {fmt(mean, True)} |")  # fmt: skip
        rows.append({"reading": "5-6", "item": f"{arm} - {ref}", "task": "all", "value": mean})
    md.append("")
    for change in dict.fromkeys(c for c, *_ in CHANGES):
        n, m = delta.get((change, "ndp"), math.nan), delta.get((change, "ppo-multi"), math.nan)
        if math.isnan(n) or math.isnan(m):
            continue
        if change.startswith("AR(1)"):
            md.append(f"- {change}: NDP {n:+.2f}, PPO-multi {m:+.2f}: " + (
                "structured exploration suits the DMP" if n > m
                else "NDP does not gain more than PPO-multi"))  # fmt: skip
        elif change.startswith("live"):
            md.append(f"- {change}: NDP {n:+.2f}, PPO-multi {m:+.2f}: " + (
                "the stale rule is not what held NDP back (NDP loses less to it)" if n < m
                else "the stale rule cost NDP at least as much as PPO-multi"))  # fmt: skip
    return [*md, ""]


def _best_k(r: ArmRuns, tasks: Sequence[str], rows: list[CsvRow]) -> list[str]:
    areas = {k: float(np.mean([r.mean(t, f"ndp-k{k}") for t in tasks])) for k in KS}
    if any(math.isnan(v) for v in areas.values()):
        return ["**7. Best k**: waits for NDP's white-noise k arms.", ""]
    best = max(areas, key=lambda k: (areas[k], -k))
    rows.append({"reading": "7", "item": "best k", "task": "all", "value": best})
    return [
        "**7. Best k** (NDP, white noise, mean area over tasks): "
        + ", ".join(f"k = {k}: {v:.2f}" for k, v in areas.items())
        + f". Best: k = {best}"
        + (" (no extra AR(1) arms)." if best == 5 else
           f" (the AR(1) arms at k = {best} run: `ndp-ar1-k{best}`, `ppo-multi-ar1-k{best}`)."),
        "",
    ]  # fmt: skip


def mt50_attribution_readings(
    cells: Sequence[Cell], seeds: Sequence[int]
) -> tuple[list[str], list[CsvRow]]:
    """(Markdown lines, CSV rows) of ``mt50-attribution``'s reading (see the module doc)."""
    r = ArmRuns(cells, seeds, CONDITIONAL)
    tasks = list(dict.fromkeys(c.task for c in cells))
    md = [
        "## Pre-registered reading (docs/rl-regimes.md, `mt50-attribution`)",
        "",
        "One-sided p of each direction (the registered rule reads p(NDP > PPO)); beside them "
        "the two-sided p with Holm's correction over this table's rows (docs/metrics.md: "
        "significant where Holm p <= 0.05).",
        "",
        "| number | NDP vs | NDP - other, mean over tasks | 95% t-interval | one-sided p(NDP > "
        "other) | one-sided p(other > NDP) | p (two-sided) | Holm p | test |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    rows: list[CsvRow] = []
    verdict = None
    found: list[tuple[str, str, Any]] = []  # (number, other, (d, lo, hi, test) or None)
    for key, name in ((HEAD, "det. success area"), ("final", "final success (any step)")):
        for other in ("ppo", "ppo-multi"):
            x = r.matrix(tasks, ["ndp"] * len(tasks), key)
            y = r.matrix(tasks, [other] * len(tasks), key)
            if x is None or y is None:
                found.append((name, other, None))
                continue
            d, test = compare_test(x, y)
            lo, hi = stats.difference_t_interval(x, y) if len(seeds) > 1 else (math.nan, math.nan)
            found.append((name, other, (d, lo, hi, test)))
            rows.append({"reading": "mt50", "item": f"ndp vs {other}", "metric": key,
                         "task": "all", "value": d, "p_greater": test.greater,
                         "p_less": test.less, "p_two_sided": test.two_sided,
                         "p_method": test.method})  # fmt: skip
            if key == HEAD and other == "ppo":
                verdict = test.greater < ALPHA
    adjusted = iter(stats.holm([got[3].two_sided for *_, got in found if got is not None]))
    done = iter(rows)
    for name, other, got in found:
        if got is None:
            md.append(f"| {name} | {other} | (waits) | - | - | - | - | - | - |")
            continue
        d, lo, hi, test = got
        q = float(next(adjusted))
        next(done)["p_holm"] = q
        md.append(f"| {name} | {other} | {d:+.3f} | {interval(lo, hi)} | {test.greater:.3g} | "
                  f"{test.less:.3g} | {test.two_sided:.3g} | {q:.3g} "
                  f"| {test.method} |")  # fmt: skip
    md.append("")
    if verdict is None:
        md.append("Verdict: waits for every seed of NDP and PPO on every task.")
    else:
        md.append(
            "Verdict: the MT50 direction (NDP ahead of PPO) "
            + ("**holds**" if verdict else "**does not hold**")
            + f" over these {len(tasks)} tasks (det. success area; the registered rule: one-sided "
            f"p(NDP > PPO) < {ALPHA})."
        )
    return [*md, "", *r.waiting_line("this reading waits")], rows
