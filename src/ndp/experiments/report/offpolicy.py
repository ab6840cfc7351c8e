"""The pre-registered readings of the ``off-policy`` study (docs/offpolicy.md), applied by code
so that its table states them as they were written before the runs (2026-12-04 for reading A,
2026-12-05 for B-D; no run of the study had started on either date).

Every reading uses the **deterministic success area** (``det_area``) of the report's seeds; a
reading whose arms lack seeds says which it waits for.

A. NDP-SAC's critic input (push-v3 only): keep the input whose arm has the higher mean area; if
   the two are within :data:`CRITIC_MARGIN`, keep ``params`` (``ndp-sac-k5``). The kept arm is
   "NDP-SAC" in B-D (``ndp-sac-act-k5`` then needs runs on every task: its arm, registered on
   push-v3 only, would be widened).
B. The DMP head under an off-policy learner: NDP-SAC against chunked SAC at the same k (same
   learner, same critic family, only the action parameterisation differs). It **helps** if
   NDP-SAC's mean is above chunked SAC's on every task with the one-sided stratified permutation
   p(NDP-SAC > chunked SAC) < :data:`ALPHA`; it **does not help** if chunked SAC's mean is at
   least NDP-SAC's on every task; else **mixed**.
C. Where NDP stands against every learner of the table: NDP-SAC against SAC, chunked SAC, NDP
   (PPO), PPO-multi and PPO; per pair the mean difference over tasks and the one-sided
   stratified permutation p of each direction; **ahead** where p(NDP-SAC > it) < :data:`ALPHA`,
   **behind** where p(it > NDP-SAC) < :data:`ALPHA` (the p of the other learner above NDP-SAC,
   not of NDP-SAC above it), else **level**. Beside the registered verdict, the convention of
   docs/metrics.md: the two-sided p, Holm-adjusted over the reading's five pairs.
D. Does the off-policy learner lift the DMP head more than the plain chunk (description only)?
   (NDP-SAC - NDP) - (chunked SAC - PPO-multi), mean over tasks.

E (post-hoc, written 2026-12-05 before its arms ran, after NDP-SAC's critic ran away on push-v3).
   The DMP head with LayerNorm critics, push-v3 only: ``ndp-sac-ln-k5`` against
   ``sac-chunk-ln-k5``. It **helps** if NDP-SAC's mean is above chunked SAC's with the exact
   one-sided permutation p(NDP-SAC > chunked SAC) <= :data:`ALPHA` (with 3 + 3 runs on one
   task the smallest p is 1/20 = 0.05: every NDP-SAC run above every chunked SAC run); it
   **does not help** if chunked SAC's mean is at least NDP-SAC's; else **mixed**. Beside it
   (description): what LayerNorm changes for each learner (LayerNorm arm minus plain arm).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ndp.experiments.report import stats
from ndp.experiments.report.cells import Cell, CsvRow
from ndp.experiments.report.readings import ArmRuns, compare_test
from ndp.rl.sac.health import Q_RUNAWAY, q_runaway
from ndp.runs import read_metrics

CRITIC_TASK = "push-v3"
"""Reading A's task."""
CRITIC_ARMS = {"params": "ndp-sac-k5", "actions": "ndp-sac-act-k5"}
"""NDP-SAC's two critic inputs and their arms."""
CRITIC_MARGIN = 0.05
"""Reading A: within this, ``params`` is kept."""
ALPHA = 0.05
"""Readings B and C: the stratified permutation p below which a difference is called."""
REGISTERED_SEEDS = (0, 1, 2)
"""The seeds the readings were registered on; a report over other seeds marks its verdicts as
interim."""
CHUNK = "sac-chunk-k5"
OTHERS = (("sac", "SAC (k = 1)"), (CHUNK, "chunked SAC (k = 5)"), ("ndp-k5", "NDP (PPO, k = 5)"),
          ("ppo-multi-k5", "PPO-multi (k = 5)"), ("ppo", "PPO (k = 1)"))  # fmt: skip
"""Reading C's opponents of NDP-SAC: (arm, name)."""


def _critic(r: ArmRuns, rows: list[CsvRow]) -> tuple[list[str], str | None]:
    """Reading A: (Markdown lines, the kept arm or None while it waits)."""
    means = {inp: r.mean(CRITIC_TASK, arm) for inp, arm in CRITIC_ARMS.items()}
    if any(math.isnan(v) for v in means.values()):
        return ["**A. NDP-SAC's critic input** (push-v3): waits for both critic arms.", ""], None
    diff = means["actions"] - means["params"]
    kept = "actions" if diff > CRITIC_MARGIN else "params"
    why = (f"`actions` is more than {CRITIC_MARGIN} above" if kept == "actions"
           else f"`actions` is not more than {CRITIC_MARGIN} above `params`")  # fmt: skip
    rows.append({"reading": "A", "item": "critic input kept", "task": CRITIC_TASK,
                 "value": diff, "verdict": kept})  # fmt: skip
    return [
        f"**A. NDP-SAC's critic input** (push-v3, mean det. area): `params` "
        f"(`{CRITIC_ARMS['params']}`) {means['params']:.2f}, `actions` "
        f"(`{CRITIC_ARMS['actions']}`) {means['actions']:.2f}; {why}: keep **{kept}** "
        f"(`{CRITIC_ARMS[kept]}` is NDP-SAC below).",
        "",
    ], CRITIC_ARMS[kept]


def _pair(
    r: ArmRuns, tasks: Sequence[str], a: str, b: str
) -> tuple[float, stats.PermutationResult] | None:
    """(mean over tasks of a - b, the stratified permutation test of a against b: ``greater``
    is p(a > b), ``less`` p(b > a)); None while either lacks seeds."""
    x, y = r.matrix(tasks, [a] * len(tasks)), r.matrix(tasks, [b] * len(tasks))
    if x is None or y is None:
        return None
    return compare_test(x, y)


def _head(r: ArmRuns, tasks: Sequence[str], ndp: str, rows: list[CsvRow]) -> list[str]:
    """Reading B: NDP-SAC against chunked SAC."""
    got = _pair(r, tasks, ndp, CHUNK)
    if got is None:
        return [f"**B. The DMP head, off-policy**: waits for `{ndp}` and `{CHUNK}`.", ""]
    d, test = got
    pg = test.greater
    per = {t: r.mean(t, ndp) - r.mean(t, CHUNK) for t in tasks}
    if all(v > 0 for v in per.values()) and pg < ALPHA:
        verdict = "helps"
    elif all(v <= 0 for v in per.values()):
        verdict = "does not help"
    else:
        verdict = "mixed"
    rows.append({"reading": "B", "item": "verdict", "task": "all", "value": d,
                 "p_greater": pg, "p_less": test.less, "p_two_sided": test.two_sided,
                 "p_method": test.method, "verdict": verdict})  # fmt: skip
    shown = ", ".join(f"{t} {v:+.2f}" for t, v in per.items())
    return [
        f"**B. The DMP head, off-policy** (`{ndp}` - `{CHUNK}`, same learner and k): {shown}; "
        f"mean {d:+.2f}; one-sided p(NDP-SAC > chunked SAC) = {pg:.3g} (the rule's test: "
        f"'helps' needs it below {ALPHA}), one-sided p(chunked SAC > NDP-SAC) = "
        f"{test.less:.3g}, two-sided p = {test.two_sided:.3g} ({test.method}, stratified by "
        f"task). Verdict: **{verdict}**.",
        "",
    ]


def _stands(r: ArmRuns, tasks: Sequence[str], ndp: str, rows: list[CsvRow]) -> list[str]:
    """Reading C: NDP-SAC against every other learner of the table."""
    md = [
        f"**C. Where NDP-SAC (`{ndp}`) stands** (mean det. area over {', '.join(tasks)}). "
        "Reading: the registered rule on the one-sided p of each direction: **ahead** where "
        f"p(NDP-SAC > it) < {ALPHA}, **behind** where p(it > NDP-SAC) < {ALPHA}, else "
        "**level**. Beside it the convention of docs/metrics.md: the two-sided p, Holm-adjusted "
        "over the reading's five pairs; significant where Holm p <= 0.05.",
        "",
        "| against | arm | NDP-SAC - it | one-sided p(NDP-SAC > it) | one-sided p(it > NDP-SAC) "
        "| reading (registered rule) | p (two-sided) | Holm p | Holm p <= 0.05 | test |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    found = [(arm, name, _pair(r, tasks, ndp, arm)) for arm, name in OTHERS]
    adjusted = iter(stats.holm([got[1].two_sided for *_, got in found if got is not None]))
    for arm, name, got in found:
        if got is None:
            md.append(f"| {name} | `{arm}` | (waits) | - | - | - | - | - | - | - |")
            continue
        d, test = got
        pg, pl, q = test.greater, test.less, float(next(adjusted))
        what = "ahead" if pg < ALPHA else "behind" if pl < ALPHA else "level"
        word = ("not significant" if q > stats.ALPHA
                else "**NDP-SAC ahead**" if d > 0 else "**NDP-SAC behind**")  # fmt: skip
        md.append(f"| {name} | `{arm}` | {d:+.2f} | {pg:.3g} | {pl:.3g} | {what} "
                  f"| {test.two_sided:.3g} | {q:.3g} | {word} | {test.method} |")  # fmt: skip
        rows.append({"reading": "C", "item": f"{ndp} vs {arm}", "task": "all", "value": d,
                     "p_greater": pg, "p_less": pl, "p_two_sided": test.two_sided,
                     "p_holm": q, "p_method": test.method, "verdict": what})  # fmt: skip
    return [*md, ""]


def _lift(r: ArmRuns, tasks: Sequence[str], ndp: str, rows: list[CsvRow]) -> list[str]:
    """Reading D: the learner x action-space interaction (description only)."""
    parts = [r.mean(t, a) - r.mean(t, b) for t in tasks
             for a, b in ((ndp, "ndp-k5"), (CHUNK, "ppo-multi-k5"))]  # fmt: skip
    if any(math.isnan(v) for v in parts):
        return ["**D. What the off-policy learner adds**: waits for its four arms.", ""]
    ndp_lift = float(np.mean(parts[0::2]))
    chunk_lift = float(np.mean(parts[1::2]))
    rows.append({"reading": "D", "item": "(ndp-sac - ndp) - (sac-chunk - ppo-multi)",
                 "task": "all", "value": ndp_lift - chunk_lift})  # fmt: skip
    return [
        f"**D. What the off-policy learner adds** (SAC-family arm minus its on-policy "
        f"counterpart, mean over tasks): DMP head {ndp_lift:+.2f} (`{ndp}` - `ndp-k5`), plain "
        f"chunk {chunk_lift:+.2f} (`{CHUNK}` - `ppo-multi-k5`); "
        + ("the learner lifts the DMP head more." if ndp_lift > chunk_lift
           else "the learner does not lift the DMP head more than the plain chunk."),
        "",
    ]  # fmt: skip


LN_ARMS = {"ndp-sac-ln-k5": "ndp-sac-k5", "sac-chunk-ln-k5": CHUNK}
"""Reading E's arms (LayerNorm critics) and their plain-critic counterparts."""


def _layer_norm(r: ArmRuns, rows: list[CsvRow]) -> list[str]:
    """Reading E (post-hoc): the DMP head with LayerNorm critics on push-v3."""
    ndp, chunk = LN_ARMS
    if not set(LN_ARMS) & r.labels:  # optional arms: no runs is no wait
        return [f"**E. The DMP head with LayerNorm critics** (post-hoc, {CRITIC_TASK}): no runs "
                f"(`ndp sweep off-policy --arms {ndp} {chunk}` runs them).", ""]  # fmt: skip
    got = _pair(r, [CRITIC_TASK], ndp, chunk)
    if got is None:
        return [f"**E. The DMP head with LayerNorm critics** (post-hoc, {CRITIC_TASK}): waits "
                f"for `{ndp}` and `{chunk}`.", ""]  # fmt: skip
    d, test = got
    pg = test.greater
    verdict = "helps" if d > 0 and pg <= ALPHA else "does not help" if d <= 0 else "mixed"
    rows.append({"reading": "E", "item": f"{ndp} vs {chunk}", "task": CRITIC_TASK, "value": d,
                 "p_greater": pg, "p_two_sided": test.two_sided, "p_method": test.method,
                 "verdict": verdict})  # fmt: skip
    lifts = []
    for ln, plain in LN_ARMS.items():
        lift = r.mean(CRITIC_TASK, ln) - r.mean(CRITIC_TASK, plain)
        lifts.append(f"`{ln}` - `{plain}` {lift:+.2f}" if not math.isnan(lift)
                     else f"`{ln}` - `{plain}` (waits)")  # fmt: skip
    return [
        f"**E. The DMP head with LayerNorm critics** (post-hoc, {CRITIC_TASK}; `{ndp}` - "
        f"`{chunk}`): {d:+.2f}, one-sided p(NDP-SAC > chunked SAC) = {pg:.3g} "
        f"({test.method}). Verdict: "
        f"**{verdict}**. What LayerNorm changes (description): {'; '.join(lifts)}.",
        "",
    ]


def critic_health(cells: Sequence[Cell], reading: bool = False) -> tuple[list[str], list[CsvRow]]:
    """(Markdown lines, CSV rows) of the critic diagnostic: per run that logs ``sac/q``, its
    peak value estimate against the largest mean episode return of the run
    (:func:`ndp.rl.sac.health.q_runaway`),
    and the temperature's peak and final value. A description, not a pre-registered reading:
    added 2026-12-05 after seed 0 of ``ndp-sac-k5`` on push-v3 was seen to diverge.

    Args:
        cells: the report's RL cells; a cell's ``runs`` (seed -> run info with ``path``) are
            read, runs without a ``sac/q`` column (the on-policy arms) are left out.
        reading: the table is the numbers of a study's reading (``sac-critic``), not a
            diagnostic beside other readings; its heading says so.
    """
    md_rows, rows = [], []
    for c in cells:
        for seed, info in sorted(getattr(c, "runs", {}).items()):
            r = _critic_row(c, seed, info.path)
            if r is None:
                continue
            rows.append(r)
            md_rows.append(
                f"| {c.task} | {c.label} | {seed} | {r['q_peak']:,.0f} | {r['q_peak_step']:,.0f} "
                f"| {r['return_peak']:,.0f} | {r['alpha_peak']:.3g} | {r['alpha_final']:.3g} "
                f"| {'**diverged**' if r['verdict'] == 'diverged' else 'ok'} |"
            )
    if not rows:
        return [], []
    return _critic_md(rows, md_rows, reading), rows


def _critic_row(c: Cell, seed: int, path: Path) -> CsvRow | None:
    """One run's critic numbers (peak Q, its step, the return scale, alpha), or None for a run
    without a readable log or without ``sac/q``."""
    try:
        log = read_metrics(path)
    except (FileNotFoundError, ValueError):
        return None
    q = np.array([r.get("sac/q", math.nan) for r in log], dtype=float)
    if not np.isfinite(q).any():
        return None
    ret = np.array([r.get("charts/episode_return", math.nan) for r in log], dtype=float)
    alpha = np.array([r.get("sac/alpha", math.nan) for r in log], dtype=float)
    steps = np.array([r.get("global_step", math.nan) for r in log], dtype=float)
    i = int(np.nanargmax(q))
    scale = max(float(np.nanmax(np.abs(ret))) if np.isfinite(ret).any() else 0.0, 1.0)
    diverged = q_runaway(float(q[i]), scale)
    a_fin = alpha[np.isfinite(alpha)]
    return {"reading": "critic", "item": f"{c.label} s{seed}", "task": c.task,
            "value": float(q[i]) / scale, "q_peak": float(q[i]),
            "q_peak_step": float(steps[i]), "return_peak": scale,
            "alpha_peak": float(np.nanmax(alpha)) if a_fin.size else math.nan,
            "alpha_final": float(a_fin[-1]) if a_fin.size else math.nan,
            "verdict": "diverged" if diverged else "ok"}  # fmt: skip


def _critic_md(rows: list[CsvRow], md_rows: list[str], reading: bool) -> list[str]:
    """The critic-health section around its table rows."""
    bad = [f"{r['task']} {r['item']}" for r in rows if r["verdict"] == "diverged"]
    why = ("The numbers of the reading above." if reading else
           "Added on 2026-12-05 after seed 0 of `ndp-sac-k5` on push-v3 was seen to diverge; "
           "it changes no reading.")  # fmt: skip
    return [
        "## Critic health" + ("" if reading else " (a diagnostic, not a pre-registered reading)"),
        "",
        f"Per SAC-family run: the peak of the critics' value estimate (`sac/q`, mean min-Q of an "
        f"update's batches), the env step it was reached at, the largest mean training-episode "
        f"return of any update, and the temperature. **Diverged**: the peak is above "
        f"{Q_RUNAWAY:g} times that return (a critic that tracks the return stays near or below "
        f"it). {why}",
        "",
        "| task | arm | seed | peak Q | at env step | largest episode return | peak alpha "
        "| final alpha | critic |",
        "|---|---|---|---|---|---|---|---|---|",
        *md_rows,
        "",
        f"Diverged: {len(bad)} of {len(rows)} runs" + (f" ({', '.join(bad)})." if bad else "."),
        "",
    ]


def off_policy_readings(
    cells: Sequence[Cell], seeds: Sequence[int]
) -> tuple[list[str], list[CsvRow]]:
    """(Markdown lines, CSV rows) of the ``off-policy`` study's readings (the module doc).

    Args:
        cells: the report's RL cells (``task``, ``label``, ``numbers`` per seed), the SAC arms
            and ndp-regimes' fair on-policy arms together.
        seeds: the seeds every arm should have.
    """
    r = ArmRuns(cells, seeds)
    tasks = list(dict.fromkeys(c.task for c in cells))
    md = [
        "## Pre-registered readings (docs/offpolicy.md)",
        "",
        f"Applied by code (`ndp.experiments.report.offpolicy`) to the deterministic success area "
        f"of seeds {' '.join(map(str, seeds))} on {', '.join(tasks)}.",
        "",
    ]
    if tuple(sorted(seeds)) != REGISTERED_SEEDS:
        md += [
            f"**Interim: seeds {' '.join(map(str, seeds))} of the registered "
            f"{' '.join(map(str, REGISTERED_SEEDS))}.** The verdicts below are computed by the "
            "registered rules but are not the study's readings; with fewer seeds the permutation "
            "p cannot reach 0.05 (one seed per task: 0.5 on a task, 0.25 over two).",
            "",
        ]
    rows: list[CsvRow] = []
    lines, kept = _critic(r, rows)
    md += lines
    ndp = kept or CRITIC_ARMS["params"]
    if kept is None:
        md += [f"B-D read `{ndp}` (the default) until reading A decides.", ""]
    md += _head(r, tasks, ndp, rows)
    md += _stands(r, tasks, ndp, rows)
    md += _lift(r, tasks, ndp, rows)
    md += _layer_norm(r, rows)
    md += r.waiting_line("these readings wait")
    health_md, health_rows = critic_health(cells)
    return md + health_md, rows + health_rows


STABILISED = {"plain": "ndp-sac-k5", "layer-norm": "ndp-sac-ln-k5"}
"""The ``sac-critic`` study's arms: NDP-SAC with SAC's plain critics and with LayerNorm ones."""


def critic_study_readings(
    cells: Sequence[Cell], seeds: Sequence[int]
) -> tuple[list[str], list[CsvRow]]:
    """(Markdown lines, CSV rows) of the ``sac-critic`` study's reading (written 2026-12-05,
    before its runs; docs/offpolicy.md, "Critic health"): does a LayerNorm critic stop NDP-SAC's
    runaway on push-v3?

    A run's critic is diverged by :func:`ndp.rl.sac.health.q_runaway` (its peak mean min-Q
    above 10 times its largest mean training-episode return, the :func:`critic_health` table).
    LayerNorm **stops the runaway** if no LayerNorm run diverges while most plain runs do; it
    **does not stop it** if most LayerNorm runs diverge; else **partly**. Until every seed of
    both arms has run, the verdict waits (a run that has not finished is not counted).

    Args:
        cells: the report's RL cells (``runs``: seed -> run info).
        seeds: the seeds every arm should have.
    """
    health_md, health_rows = critic_health(cells, reading=True)
    finished = {f"{c.label} s{seed}" for c in cells
                for seed, info in getattr(c, "runs", {}).items() if info.finished}  # fmt: skip
    diverged: dict[str, list[bool]] = {k: [] for k in STABILISED}
    for key, arm in STABILISED.items():
        for s in seeds:
            item = f"{arm} s{s}"
            hit = [r for r in health_rows if r["item"] == item and item in finished]
            if hit:
                diverged[key].append(hit[0]["verdict"] == "diverged")
    md = ['## Pre-registered reading (docs/offpolicy.md, "Critic health")', ""]
    rows: list[CsvRow] = []
    n = len(seeds)
    if any(len(v) < n for v in diverged.values()):
        have = ", ".join(f"{STABILISED[k]} {len(v)} of {n}" for k, v in diverged.items())
        md += [f"**Does a LayerNorm critic stop NDP-SAC's runaway?** Waits for every seed of "
               f"both arms (finished runs: {have}).", ""]  # fmt: skip
        return md + health_md, health_rows
    plain, ln = sum(diverged["plain"]), sum(diverged["layer-norm"])
    if ln == 0 and plain > n / 2:
        verdict = "stops the runaway"
    elif ln > n / 2:
        verdict = "does not stop the runaway"
    else:
        verdict = "partly stops the runaway"
    rows.append({"reading": "layer-norm", "item": "diverged runs (layer-norm, plain)",
                 "task": "push-v3", "value": float(ln - plain), "verdict": verdict})  # fmt: skip
    md += [
        f"**Does a LayerNorm critic stop NDP-SAC's runaway?** Diverged critics: plain "
        f"(`{STABILISED['plain']}`) {plain} of {n}, LayerNorm (`{STABILISED['layer-norm']}`) "
        f"{ln} of {n}: LayerNorm **{verdict}** (the rule: stops if no LayerNorm run and most "
        f"plain runs diverge; does not if most LayerNorm runs diverge; else partly).",
        "",
    ]
    return md + health_md, rows + health_rows
