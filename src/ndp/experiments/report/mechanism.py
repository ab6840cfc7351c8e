"""The pre-registered readings 2 (basis) and 3 (rewards) of ``ndp-mechanism``, applied by code
(docs/rl-mechanism.md, "Readings": written and committed 2026-12-06, before any of their runs).

Reading 1 (conditioning, 10 seeds) is a family of permutation tests that ``ndp report
--compare ... --compare-pooled --compare-holm pooled`` gives; its table is
``docs/results/ndp_mechanism/conditioning.md``. The two pilots read here are descriptions at
3 seeds, by the rules as registered:

- **Reading 2, basis** (push-v3, at k = 10 and k = 20): every arm's mean deterministic success
  area over the seeds and its standard deviation over seeds (population std, as in the report's
  tables). The **spread** of a comparison is the larger of its two arms' std. A basis "differs
  from free PPO-multi" when its mean is more than the spread away (it then runs 10 seeds, the
  second stage). "A low-dimensional basis, not the DMP" when the dmp basis is within the spread
  of both the DCT and the B-spline bases; "the DMP's span is a poor basis" when it is below both
  by more than the spread; "restriction helps at large k" when every generic basis (dct,
  bspline, pca) is above free PPO-multi by more than the spread, "restriction hurts" when every
  one is below by more; NDP against the dmp basis: level within the spread means the DMP head
  loses nothing to its linear span at that k.
- **Reading 3, rewards** (reach-v3 and push-v3, under the sparse and the smooth reward): per
  (task, variant), NDP's probability of improvement over the better of PPO-multi and PPO (the
  one with the higher mean; a tie takes PPO-multi), P(X > Y) over all run pairs with ties
  counted half, with its bootstrap interval (runs of each arm resampled, 10,000 times). NDP
  "should win here" where it is >= 0.7 (:data:`IMPROVEMENT_RULE`): that cell runs 10 seeds.

A reading whose arms are not all in the report (all seeds) says what it waits for.
"""

from __future__ import annotations

from collections.abc import Sequence

from ndp.experiments.report import stats
from ndp.experiments.report.cells import Cell, CsvRow
from ndp.experiments.report.readings import ArmRuns

BASIS_TASK = "push-v3"
"""The task of the basis pilot."""
BASIS_KS = (10, 20)
"""The chunk sizes of the basis pilot."""
GENERIC_BASES = ("dct", "bspline", "pca")
"""The bases that are not the DMP's own span."""
REWARD_TASKS = ("reach-v3", "push-v3")
"""The tasks of the rewards pilot."""
REWARD_VARIANTS = ("sparse", "smooth")
"""The reward variants of the rewards pilot."""
IMPROVEMENT_RULE = 0.7
"""Reading 3's threshold on NDP's probability of improvement over the better baseline."""


def free_label(k: int) -> str:
    """The free PPO-multi arm of the basis pilot at chunk size ``k``."""
    return f"ppo-multi-live-k{k}"


def basis_label(basis: str, k: int) -> str:
    """The PPO-multi arm restricted to ``basis`` at chunk size ``k``."""
    return f"ppo-multi-{basis}-k{k}"


def ndp_label(k: int) -> str:
    """NDP's arm of the basis pilot at chunk size ``k``."""
    return f"ndp-live-k{k}"


def mechanism_readings(
    cells: Sequence[Cell], seeds: Sequence[int]
) -> tuple[list[str], list[CsvRow]]:
    """(Markdown lines, CSV rows) of readings 2 and 3 of ``ndp-mechanism`` (module doc).

    Args:
        cells: the report's RL cells (``task``, ``label``, ``numbers`` per seed).
        seeds: the seeds every arm should have.
    """
    labels = {c.label for c in cells}
    md = [
        "## Pre-registered readings 2 and 3 (docs/rl-mechanism.md)",
        "",
        "Applied by code (`ndp.experiments.report.mechanism`) to the deterministic success area "
        f"of seeds {' '.join(map(str, seeds))}; descriptions at pilot size, no test. Reading 1 "
        "(conditioning) is `docs/results/ndp_mechanism/conditioning.md`.",
        "",
    ]
    rows: list[CsvRow] = []
    basis_arms = {free_label(k) for k in BASIS_KS} | {
        basis_label(b, k) for b in ("dmp", *GENERIC_BASES) for k in BASIS_KS
    }
    if labels & basis_arms:
        r = ArmRuns(cells, seeds)
        for k in BASIS_KS:
            md += basis_reading(r, k, rows)
        md += r.waiting_line("reading 2 waits")
    else:
        md += ["Reading 2 (basis): none of its arms is in this report.", ""]
    reward_arms = {f"{m}-{v}" for m in ("ndp", "ppo-multi", "ppo") for v in REWARD_VARIANTS}
    if labels & reward_arms:
        r = ArmRuns(cells, seeds)
        md += rewards_reading(r, rows)
        md += r.waiting_line("reading 3 waits")
    else:
        md += ["Reading 3 (rewards): none of its arms is in this report.", ""]
    return md, rows


def _stat(r: ArmRuns, task: str, label: str) -> tuple[float, float] | None:
    """(mean, population std over seeds) of an arm, or None while a seed is missing."""
    v = r.values(task, label)
    return None if v is None else (float(v.mean()), float(v.std()))


def _side(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float, str]:
    """(a - b, spread, 'above' / 'below' / 'within'): the difference of two arms' means against
    the larger of their two stds."""
    diff, spread = a[0] - b[0], max(a[1], b[1])
    return diff, spread, "above" if diff > spread else "below" if diff < -spread else "within"


def basis_reading(r: ArmRuns, k: int, rows: list[CsvRow]) -> list[str]:
    """Reading 2 at chunk size ``k``: each basis and NDP against free PPO-multi, the dmp basis
    against the generic ones, and the registered verdicts (appends CSV rows to ``rows``)."""
    task = BASIS_TASK
    free = _stat(r, task, free_label(k))
    stats_ = {b: _stat(r, task, basis_label(b, k)) for b in ("dmp", *GENERIC_BASES)}
    ndp = _stat(r, task, ndp_label(k))
    md = [
        f"### Reading 2, basis, {task}, k = {k}",
        "",
        "| arm | mean (std) | - free PPO-multi | spread | differs (second stage) |",
        "|---|---|---|---|---|",
    ]
    if free is None:
        return [*md[:2], f"Waits for free PPO-multi ({free_label(k)}).", ""]
    md.append(f"| {free_label(k)} (free) | {free[0]:.3f} ({free[1]:.3f}) | - | - | - |")
    sides: dict[str, str] = {}
    for name, st in [*((basis_label(b, k), s) for b, s in stats_.items()), (ndp_label(k), ndp)]:
        if st is None:
            md.append(f"| {name} | waits | | | |")
            continue
        diff, spread, side = _side(st, free)
        sides[name] = side
        differs = side != "within"
        md.append(
            f"| {name} | {st[0]:.3f} ({st[1]:.3f}) | {diff:+.3f} | {spread:.3f} | "
            f"{'yes' if differs else 'no'} |"
        )
        rows.append(
            {
                "reading": "2",
                "task": task,
                "k": k,
                "arm": name,
                "vs": free_label(k),
                "mean": st[0],
                "std": st[1],
                "diff": diff,
                "spread": spread,
                "side": side,
            }
        )
    md += ["", *_basis_verdicts(k, stats_, ndp, sides, rows), ""]
    return md


def _basis_row(k: int, arm: str, vs: str, **numbers: str | float) -> CsvRow:
    """One CSV row of reading 2 at ``k``."""
    return {"reading": "2", "task": BASIS_TASK, "k": k, "arm": arm, "vs": vs, **numbers}


def _basis_verdicts(
    k: int,
    st: dict[str, tuple[float, float] | None],
    ndp: tuple[float, float] | None,
    sides: dict[str, str],
    rows: list[CsvRow],
) -> list[str]:
    """The registered sentences of reading 2 at ``k`` (one bullet each)."""
    return [
        _dmp_verdict(k, st, rows),
        _restriction_verdict(k, sides, rows),
        _ndp_verdict(k, ndp, st["dmp"], rows),
    ]


def _dmp_verdict(k: int, st: dict[str, tuple[float, float] | None], rows: list[CsvRow]) -> str:
    """The dmp basis against the DCT and B-spline bases: within both spreads, below both, or
    neither rule."""
    dmp, dct, bsp = st["dmp"], st["dct"], st["bspline"]
    if dmp is None or dct is None or bsp is None:
        return "- dmp against the generic bases: waits for the dmp, dct and bspline arms."
    vs = [_side(dmp, dct)[2], _side(dmp, bsp)[2]]
    if vs == ["within", "within"]:
        verdict = "a low-dimensional basis, not the DMP"
    elif vs == ["below", "below"]:
        verdict = "the DMP's span is a poor basis"
    else:
        verdict = "neither rule (dmp - dct " + vs[0] + ", dmp - bspline " + vs[1] + ")"
    rows.append(_basis_row(k, "dmp-basis", "dct bspline", side=" ".join(vs), verdict=verdict))
    return f"- dmp against dct and bspline: **{verdict}**."


def _restriction_verdict(k: int, sides: dict[str, str], rows: list[CsvRow]) -> str:
    """Every generic basis above free PPO-multi by more than the spread (helps), every one
    below (hurts), or neither; waits while a generic basis lacks runs."""
    generic = [sides.get(basis_label(b, k)) for b in GENERIC_BASES]
    if any(s is None for s in generic):
        known = [b for b, s in zip(GENERIC_BASES, generic, strict=True) if s is not None]
        waits = ", ".join(b for b in GENERIC_BASES if b not in known)
        so_far = ", ".join(f"{b} {sides[basis_label(b, k)]}" for b in known)
        return f"- restriction at this k: waits for {waits}" + (
            f" ({so_far} so far)." if known else "."
        )
    verdict = (
        "restriction helps at large k"
        if all(s == "above" for s in generic)
        else "restriction hurts"
        if all(s == "below" for s in generic)
        else "neither (not every generic basis on one side of free PPO-multi)"
    )
    side = " ".join(str(s) for s in generic)
    rows.append(_basis_row(k, "generic-bases", free_label(k), side=side, verdict=verdict))
    return f"- generic bases against free PPO-multi: **{verdict}**."


def _ndp_verdict(
    k: int, ndp: tuple[float, float] | None, dmp: tuple[float, float] | None, rows: list[CsvRow]
) -> str:
    """NDP against the dmp basis (the same span): level within the spread, or not."""
    if ndp is None or dmp is None:
        return "- NDP against the dmp basis: waits for both arms."
    diff, spread, side = _side(ndp, dmp)
    verdict = (
        "level: the DMP head loses nothing to its linear span at this k"
        if side == "within"
        else f"NDP {side} the dmp basis by more than the spread"
    )
    rows.append(
        _basis_row(k, ndp_label(k), basis_label("dmp", k), diff=diff, spread=spread, side=side,
                   verdict=verdict)
    )  # fmt: skip
    return f"- NDP - dmp basis {diff:+.3f} (spread {spread:.3f}): **{verdict}**."


def rewards_reading(r: ArmRuns, rows: list[CsvRow]) -> list[str]:
    """Reading 3: per (task, variant), NDP's P(improvement) over the better baseline and the
    registered verdict (appends CSV rows to ``rows``)."""
    md = [
        "### Reading 3, rewards (pilot)",
        "",
        "| task | reward | NDP | PPO-multi | PPO | better baseline | P(NDP > it) [95% CI] | "
        f">= {IMPROVEMENT_RULE} |",
        "|---|---|---|---|---|---|---|---|",
    ]
    wins, complete = [], True
    for task in REWARD_TASKS:
        for v in REWARD_VARIANTS:
            row = _reward_cell(r, task, v)
            if row is None:
                complete = False
                md.append(f"| {task} | {v} | waits | | | | | |")
                continue
            rows.append(row)
            p, win = float(row["p_improvement"]), row["verdict"] == "should win here"
            if win:
                wins.append((p, task, v))
            md.append(
                f"| {task} | {v} | {row['mean']:.3f} | {row['ppo_multi_mean']:.3f} | "
                f"{row['ppo_mean']:.3f} | {str(row['vs']).removesuffix('-' + v)} | {p:.2f} "
                f"[{row['ci_low']:.2f}, {row['ci_high']:.2f}] | {'yes' if win else 'no'} |"
            )
    return [*md, "", _rewards_answer(wins, complete), ""]


def _reward_cell(r: ArmRuns, task: str, v: str) -> CsvRow | None:
    """Reading 3's row of one (task, variant): NDP against the baseline with the higher mean
    (a tie: PPO-multi), P(improvement) with its interval and the verdict; None while an arm
    lacks seeds."""
    x = r.values(task, f"ndp-{v}")
    base = {m: r.values(task, f"{m}-{v}") for m in ("ppo-multi", "ppo")}
    ys = {m: b for m, b in base.items() if b is not None}
    if x is None or len(ys) < len(base):
        return None
    means = {m: float(b.mean()) for m, b in ys.items()}
    best = max(means, key=lambda m: (means[m], m == "ppo-multi"))
    p = stats.probability_of_improvement(x[:, None], ys[best][:, None])
    lo, hi = stats.probability_of_improvement_ci(x[:, None], ys[best][:, None])
    return {"reading": "3", "task": task, "reward": v, "arm": f"ndp-{v}", "vs": f"{best}-{v}",
            "mean": float(x.mean()), "vs_mean": means[best], "ppo_multi_mean": means["ppo-multi"],
            "ppo_mean": means["ppo"], "p_improvement": p, "ci_low": lo, "ci_high": hi,
            "verdict": "should win here" if p >= IMPROVEMENT_RULE else "no"}  # fmt: skip


def _rewards_answer(wins: list[tuple[float, str, str]], complete: bool) -> str:
    """Reading 3's sentence: the cells that reach the rule, or the registered negative answer."""
    if wins:
        cells = "; ".join(f"{t} {v} ({p:.2f})" for p, t, v in sorted(wins, reverse=True))
        return (
            f"NDP **should win here** (P(improvement) >= {IMPROVEMENT_RULE}): {cells}. By the "
            "registered rule these cells run 10 seeds (tested then: NDP - PPO-multi and NDP - "
            "PPO on that cell, Holm over the two), and the best of them 1M env steps."
        )
    if complete:
        return (
            f"No cell reaches {IMPROVEMENT_RULE}: by the registered rule, neither a sparse success "
            "reward nor a priced smoothness makes the DMP action space pay off on these tasks at "
            "300k env steps (3 seeds)."
        )
    return "No cell reaches the rule yet; the cells that wait may."
