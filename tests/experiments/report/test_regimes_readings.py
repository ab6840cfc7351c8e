"""ndp-regimes' pre-registered readings applied by code (ndp.experiments.report.regimes): the
verdict of readings 1-2 in each of its three outcomes and while arms are missing, the metric,
compression, exploration, best-k rules, and the report's readings section end to end."""

from __future__ import annotations

import csv
import json
from types import SimpleNamespace

import pytest

from ndp.experiments.report import regimes as rg
from ndp.experiments.report import report

SEEDS = (0, 1, 2)
TASKS = ("push-v3", "throw")
REQUIRED = [lb for lb in (*rg.NDP_POOL, *rg.PPO_MULTI_POOL, *rg.PPO_POOL)
            if lb not in rg.CONDITIONAL] + ["ndp-tuned"]  # fmt: skip


def _cells(det, area=None, seeds=SEEDS):
    """Fake report cells: ``det[(task, label)]`` (or ``det[label]`` for every task) is the
    det. area of every seed; the training area is ``area`` (default: det - 0.1)."""
    out = []
    for task in TASKS:
        for lb in REQUIRED:
            v = det.get((task, lb), det.get(lb, 0.2))
            if v is None:
                continue
            a = (area or {}).get(lb, v - 0.1)
            # the seeds spread by +-0.01 so that permutation tests are not all ties
            nums = {s: {"det_area": v + 0.01 * (s - 1), "area": a} for s in seeds}
            out.append(SimpleNamespace(task=task, label=lb, numbers=nums))
    return out


def _text(md):
    return "\n".join(md)


def test_reading_1_helps_when_ndps_best_beats_ppo_multis_on_both_tasks():
    md, rows = rg.regimes_readings(_cells({"ndp-k10": 0.8, "ppo": 0.82}), SEEDS)
    text = _text(md)
    assert "| push-v3 | `ndp-k10` | 0.80 | `ppo-multi-k5` | 0.20 | `ppo` | 0.82 |" in text
    verdict = next(r for r in rows if r["item"] == "verdict")
    assert verdict["verdict"] == "helps"
    # every NDP run above every PPO-multi run on both tasks: 1 / C(6, 3)^2
    assert verdict["p_greater"] == pytest.approx(1 / 400)
    assert "one-sided p(best NDP > best PPO-multi) = 0.0025" in text
    assert "two-sided p = 0.005; exact permutation (all 400 splits)" in text
    assert "Verdict: waits" not in text and "(waits)" not in text


def test_reading_1_needs_ndp_within_the_margin_of_ppo():
    md, rows = rg.regimes_readings(_cells({"ndp-k10": 0.8, "ppo": 0.9}), SEEDS)
    assert next(r for r in rows if r["item"] == "verdict")["verdict"] == "mixed"
    assert "not more than 0.05 below PPO's best on any task: no" in _text(md)


def test_reading_2_does_not_help_and_mixed():
    _, rows = rg.regimes_readings(_cells({"ppo-multi-k20": 0.5, "ndp-param-k5": 0.4}), SEEDS)
    assert next(r for r in rows if r["item"] == "verdict")["verdict"] == "does not help"
    mixed = {("push-v3", "ndp-k5"): 0.6, ("throw", "ppo-multi-k5"): 0.6}
    _, rows = rg.regimes_readings(_cells(mixed), SEEDS)
    assert next(r for r in rows if r["item"] == "verdict")["verdict"] == "mixed"


def test_readings_wait_for_a_missing_arm_or_seed_and_name_it():
    md, rows = rg.regimes_readings(_cells({"ndp-nostale": None}), SEEDS)
    text = _text(md)
    assert "Verdict: waits" in text and not any(r["item"] == "verdict" for r in rows)
    assert "ndp-nostale" in text.split("wait for")[-1]
    # one seed short
    cells = _cells({})
    next(c for c in cells if c.label == "ppo-ar1").numbers.pop(2)
    md, rows = rg.regimes_readings(cells, SEEDS)
    assert "Verdict: waits" in _text(md) and "ppo-ar1" in _text(md).split("wait for")[-1]


def test_conditional_ar1_arms_join_the_pool_only_once_they_have_runs():
    cells = _cells({"ndp-k5": 0.3})
    md, rows = rg.regimes_readings(cells, SEEDS)
    assert next(r for r in rows if r["item"] == "best ndp arm")["arm"] == "ndp-k5"
    cells += [SimpleNamespace(task=t, label="ndp-ar1-k10",
                              numbers={s: {"det_area": 0.9, "area": 0.5} for s in SEEDS})
              for t in TASKS]  # fmt: skip
    md, rows = rg.regimes_readings(cells, SEEDS)
    assert next(r for r in rows if r["item"] == "best ndp arm")["arm"] == "ndp-ar1-k10"
    assert "| AR(1), k = 10 | ndp | `ndp-ar1-k10` | +0.70 | +0.70 | +0.70 |" in _text(md)


def test_metric_compression_exploration_stale_and_best_k():
    det = {"ndp-k5": 0.3, "ndp-k10": 0.4, "ndp-k20": 0.2, "ppo-multi-k5": 0.4,
           "ppo-multi-k10": 0.3, "ppo-multi-k20": 0.1, "ndp-ar1-k5": 0.5,
           "ppo-multi-ar1-k5": 0.45, "ndp-nostale": 0.25, "ppo-multi-nostale": 0.2}  # fmt: skip
    area = {f"ndp-k{k}": 0.1 for k in rg.KS} | {f"ppo-multi-k{k}": 0.2 for k in rg.KS}
    md, rows = rg.regimes_readings(_cells(det, area), SEEDS)
    text = _text(md)
    # 3: NDP det - training (0.3+0.4+0.2)/3 - 0.1 = 0.2; PPO-multi (0.4+0.3+0.1)/3 - 0.2 = 0.067
    assert next(r for r in rows if r["reading"] == "3")["value"] == pytest.approx(0.2 - 0.8 / 3
                                                                                 + 0.2)  # fmt: skip
    assert "under-rated NDP relative to PPO-multi by 0.13" in text
    # 4: k = 10 NDP +0.10, PPO-multi -0.10 -> pays off; k = 20 both fall
    assert "| 10 | +0.10 (+0.10, +0.10) | -0.10 (-0.10, -0.10) | the DMP's compression pays" in text
    assert "| 20 | -0.10 (-0.10, -0.10) | -0.30 (-0.30, -0.30) | both fall" in text
    # 5-6
    assert "- AR(1), k = 5: NDP +0.20, PPO-multi +0.05: structured exploration suits" in text
    assert "NDP -0.05, PPO-multi -0.20: the stale rule cost NDP at least as much" in text
    # 7: k = 10 has the highest NDP area
    assert "Best: k = 10 (the AR(1) arms at k = 10 run" in text


def test_the_1m_reading_compares_k_and_ndp_against_ppo_multi():
    cells = [SimpleNamespace(task="push-v3", label=lb,
                             numbers={s: {"det_area": v + 0.01 * s, "area": v} for s in SEEDS})
             for lb, v in (("ndp-k5", 0.5), ("ndp-k10", 0.6), ("ndp-k20", 0.4),
                           ("ppo-multi-k5", 0.5), ("ppo-multi-k10", 0.4),
                           ("ppo-multi-k20", 0.3), ("ppo", 0.7))]  # fmt: skip
    md, rows = rg.regimes_1m_readings(cells, SEEDS)
    text = _text(md)
    assert "| 10 | +0.10 | -0.10 | the DMP's compression pays off |" in text
    row = next(r for r in rows if r["item"] == "ndp-k10 vs ppo-multi-k10")
    assert row["value"] == pytest.approx(0.2) and row["p_greater"] == pytest.approx(0.05)
    # the convention beside the registered one-sided p: two-sided 0.1 at each k (every run
    # of one arm above every run of the other), Holm over the three k: 0.3
    assert row["p_two_sided"] == pytest.approx(0.1) and row["p_holm"] == pytest.approx(0.3)
    assert "| one-sided p(NDP > PPO-multi) | one-sided p(PPO-multi > NDP) |" in text
    assert "| 0.050 | 1.000 | 0.100 | 0.300 | exact permutation (all 20 splits) |" in text
    assert ("NDP k = 10 (0.61) > k = 5 (0.51) > k = 20 (0.41); PPO-multi k = 5 (0.51) > "
            "k = 10 (0.41) > k = 20 (0.31)." in text)  # fmt: skip
    assert next(r for r in rows if r["item"] == "ndp ranking of k")["value"] == "10 > 5 > 20"
    md, _ = rg.regimes_1m_readings(cells, (0,))
    assert "One seed: a direction, not a result." in _text(md)


def _eval_run(root, task, label, seed, det, algo):
    """A finished RL run with the periodic evaluation's columns (det. area = ``det``)."""
    run = root / f"{task}-{label}-s{seed}"
    run.mkdir(parents=True)
    with (run / "metrics.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            [
                "update",
                "global_step",
                "charts/success_any",
                "charts/success_final",
                "charts/episode_return_live",
                "eval/success_any",
                "eval/success_final",
            ]
        )
        for i in range(10):
            w.writerow([i + 1, (i + 1) * 100, 0.1, 0.1, 1.0, det, det])
    (run / "arm.json").write_text(json.dumps({
        "label": label, "algo": algo, "args": [], "note": "", "steps": 1000, "task": task,
        "seed": seed, "kind": "rl"}))  # fmt: skip
    (run / "done.json").write_text("{}")


def test_report_of_ndp_regimes_1m_adds_the_readings_and_names_arms_without_runs(tmp_path):
    runs = tmp_path / "runs"
    arms = {"ndp-k5": 0.5, "ndp-k10": 0.6, "ppo-multi-k5": 0.5, "ppo-multi-k10": 0.4, "ppo": 0.7}
    for lb, v in arms.items():
        for s in SEEDS:
            _eval_run(runs, "push-v3", lb, s, v + 0.01 * s, lb.rsplit("-k", 1)[0])
    out = tmp_path / "o" / "r1m"
    res = report([runs], out, "ndp report runs --study ndp-regimes-1m", study="ndp-regimes-1m")
    md = (tmp_path / "o" / "r1m.md").read_text()
    assert "## Pre-registered reading 8" in md
    assert "| 10 | +0.10 | -0.10 | the DMP's compression pays off |" in md
    assert "| 20 | (waits) | (waits) | - |" in md
    # the k = 20 arms never ran: named, and their condition left out, not shown empty
    assert "Arms of the study with no runs here (left out): ndp-k20, ppo-multi-k20." in md
    assert "Conditions left out where some of their arms have no runs in this report: " in md
    assert "| white, k = 20 |" not in md and "| white, k = 10 | ndp | `ndp-k10` | 3 |" in md
    assert str(out) + "-readings.csv" in res["section_csv"]
    rows = list(csv.DictReader(open(str(out) + "-readings.csv")))
    assert {r["item"] for r in rows} >= {"k10 - k5", "ndp-k10 vs ppo-multi-k10"}


def test_readings_need_the_studys_arms_so_a_methods_subset_leaves_them_out(tmp_path):
    runs = tmp_path / "runs"
    for lb in ("ndp-k5", "ppo-multi-k5", "ppo"):
        for s in SEEDS:
            _eval_run(runs, "push-v3", lb, s, 0.5, lb.rsplit("-k", 1)[0])
    res = report([runs], tmp_path / "o" / "r", "ndp report", study="ndp-regimes-1m",
                 methods=["ndp-k5", "ppo-multi-k5", "ppo"])  # fmt: skip
    md = (tmp_path / "o" / "r.md").read_text()
    assert "## Conditions" in md and "| white, k = 5 | ndp | `ndp-k5` | 3 |" in md
    assert "Pre-registered reading" not in md
    assert not any(p.endswith("-readings.csv") for p in res["section_csv"])


def test_off_policy_report_takes_its_on_policy_arms_from_the_other_run_directory(tmp_path):
    """ndp report OFF ON --study off-policy: the SAC arms and ndp-regimes' fair arms in one
    condition table (IQM over tasks, pairwise p); without the second directory the on-policy
    arms are named as having no runs."""
    off, on = tmp_path / "off", tmp_path / "on"
    for task in ("push-v3", "throw"):
        for s in SEEDS:
            for lb, algo, v in (("sac", "sac", 0.6), ("sac-chunk-k5", "sac-chunk", 0.4),
                                ("ndp-sac-k5", "ndp-sac", 0.5)):  # fmt: skip
                _eval_run(off, task, lb, s, v + 0.01 * s, algo)
            for lb, algo, v in (("ndp-k5", "ndp", 0.2), ("ppo-multi-k5", "ppo-multi", 0.3),
                                ("ppo", "ppo", 0.3), ("ndp-k10", "ndp", 0.1)):  # fmt: skip
                _eval_run(on, task, lb, s, v + 0.01 * s, algo)
    report([off, on], tmp_path / "o" / "op", "ndp report", study="off-policy")
    md = (tmp_path / "o" / "op.md").read_text()
    assert "| k = 5 | sac | `sac` | 3 |" in md and "| k = 5 | ppo | `ppo` | 3 |" in md
    assert "ndp-k10" not in md  # another ndp-regimes arm: not the off-policy study's
    # SAC above NDP on both tasks, every run: stratified p = 1 / 20^2
    rows = [ln for ln in md.splitlines() if ln.startswith("| k = 5 | sac vs ndp |")]
    assert len(rows) == 3 and "| 0.050 | 1.000 |" in rows[0]  # push-v3, throw, both
    assert "| 0.003 | 1.000 |" in rows[2]
    assert "### Over tasks (2 tasks: push-v3, throw" in md
    assert "NDP-SAC's critic input (push-v3, throw)" in md  # its actions arm never ran
    # P(NDP > X): only the methods a condition puts beside NDP, not the other conditions' arms
    head = next(ln for ln in md.splitlines() if ln.startswith("| condition | P(NDP > "))
    against = {c.split(",")[0].strip() for c in head.split("|") if "P(NDP > " in c}
    assert against == {f"P(NDP > {m})" for m in ("sac", "sac-chunk", "ndp-sac", "ppo-multi", "ppo")}
    report([off], tmp_path / "o" / "op1", "ndp report", study="off-policy")
    md1 = (tmp_path / "o" / "op1.md").read_text()
    assert (
        "no runs here (left out): ndp-sac-act-k5, ndp-sac-ln-k5, sac-chunk-ln-k5, "
        "sac-chunk-live-k5, sac-chunk-live-utd1-k5, ndp-sac-live-k5, ndp-sac-live-utd1-k5, "
        "ndp-k5, ppo-multi-k5, ppo, ndp-nostale, ppo-multi-nostale." in md1
    )  # the optional arms (the actions critic, reading E's LayerNorm arms, part 3's live
    # arms) never ran; each named once (ppo is in several conditions)


def test_mt50_attribution_reading_holds_only_with_ndp_ahead_of_ppo_over_the_tasks():
    def cells(ndp, ppo):
        out = []
        for t in ("a-v3", "b-v3"):
            for lb, v in (("ndp", ndp), ("ppo-multi", 0.3), ("ppo", ppo)):
                nums = {s: {"det_area": v + 0.01 * s, "final": v} for s in SEEDS}
                out.append(SimpleNamespace(task=t, label=lb, numbers=nums))
        return out

    md, rows = rg.mt50_attribution_readings(cells(0.6, 0.2), SEEDS)
    assert "the MT50 direction (NDP ahead of PPO) **holds** over these 2 tasks" in _text(md)
    det = next(r for r in rows if r["item"] == "ndp vs ppo" and r["metric"] == "det_area")
    assert det["value"] == pytest.approx(0.4) and det["p_greater"] == pytest.approx(1 / 400)
    assert det["p_two_sided"] == pytest.approx(2 / 400) and "p_holm" in det
    assert [r["p_method"] for r in rows] == ["exact permutation (all 400 splits)"] * 4
    assert "one-sided p(NDP > other) | one-sided p(other > NDP) |" in _text(md)
    md, _ = rg.mt50_attribution_readings(cells(0.2, 0.2), SEEDS)
    assert "**does not hold**" in _text(md)
    short = cells(0.6, 0.2)
    short[-1].numbers.pop(0)  # PPO on b-v3 lacks seed 0
    md, _ = rg.mt50_attribution_readings(short, SEEDS)
    assert "Verdict: waits" in _text(md) and "ppo" in _text(md).split("wait")[-1]
