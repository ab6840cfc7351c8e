"""ndp report from fixture run directories: numbers, tables, CSV, curves, provenance, and the
refusal (or the loud marker) when a cell lacks seeds."""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from ndp.cli import main
from ndp.experiments.report import MissingSeedsError, report, success_at

BUDGET = 1000


def _rl_run(root, task, label, seed, success, ret=-10.0, done=True, algo=None, arm=True):
    """An RL run of 10 updates of 100 env steps (unfinished: 5), success ``success`` (a number,
    or a function of the update index), live return ``ret``."""
    run = root / f"{task}-{label}-s{seed}"
    run.mkdir(parents=True)
    cols = ["update", "global_step", "charts/success_any", "charts/episode_return",
            "charts/episode_return_live"]  # fmt: skip
    with (run / "metrics.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for i in range(10 if done else 5):
            y = success(i) if callable(success) else success
            w.writerow([i + 1, (i + 1) * 100, y, ret - 5, ret])
    if arm:
        (run / "arm.json").write_text(json.dumps({
            "label": label, "algo": algo or label, "args": [], "note": "", "steps": BUDGET,
            "task": task, "seed": seed, "kind": "rl"}))  # fmt: skip
    else:
        (run / "config.json").write_text(
            json.dumps({"task": task, "algo": algo or label, "seed": seed, "steps": BUDGET})
        )
    (run / "provenance.json").write_text(json.dumps([{"event": "start", "commit": "abcdef0123"}]))
    if done:
        (run / "done.json").write_text("{}")
    return run


def _grid(root, seeds=(0, 1)):
    for seed in seeds:
        _rl_run(root, "push-v3", "ndp", seed, 0.8 + 0.1 * seed, ret=100.0 + seed)
        _rl_run(root, "push-v3", "ppo", seed, 0.5)
        _rl_run(root, "soccer-v3", "ndp", seed, 0.2)
        _rl_run(root, "soccer-v3", "ppo", seed, lambda i: 1.0 if i >= 5 else 0.0)


def test_report_tables_csv_and_curves(tmp_path):
    runs = tmp_path / "runs"
    _grid(runs)
    res = report([runs], tmp_path / "out" / "rep", "ndp report runs", title="Fixture")
    assert res["seeds"] == [0, 1] and res["budgets"] == [250, 500, 1000]
    md = (tmp_path / "out" / "rep.md").read_text()
    assert md.startswith("# Fixture") and "Command: `ndp report runs`" in md
    assert f"Commit: {res['commit']}, date: {res['date']}" in md and "abcdef0" in md
    # push ndp: success 0.8 and 0.9 (seeds 0, 1): mean 0.85, std 0.05; live return 100.5 +- 0.5
    assert "| push-v3 | ndp | 2 | 0.85 +- 0.05 | 0.85 +- 0.05 | 0.85 +- 0.05 |" in md
    assert "| 100.5 +- 0.5 |" in md
    # soccer ppo: success 0 for updates 1-5 (steps 100-500), 1 after: at 500 -> 0, at 1000 -> 1
    row = next(r for r in res["rows"] if r["task"] == "soccer-v3" and r["method"] == "ppo")
    assert row["success_at_500_mean"] == 0.0 and row["success_at_1000_mean"] == 1.0
    assert row["final_success_mean"] == 1.0
    assert row["success_area_mean"] == pytest.approx(0.5, abs=0.05)
    assert (
        "NDP >= ppo (mean final success) on 1 of 2 tasks: higher on 1, equal on 0 "
        "(0 with both at 0), lower on 1." in md
    )
    assert "| ndp | 0.525 |" in md  # mean over tasks of (0.85, 0.2)
    with (tmp_path / "out" / "rep.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4 and {r["commit"] for r in rows} == {res["commit"]}
    assert all(r["command"] == "ndp report runs" and r["date"] == res["date"] for r in rows)
    assert rows[0]["missing_seeds"] == "" and rows[0]["seeds"] == "0 1"
    for task in ("push-v3", "soccer-v3"):
        png = tmp_path / "out" / f"rep-{task}.png"
        data = png.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
        assert b"ndp report runs" in data  # the command, commit and date in the PNG's text


def test_over_tasks_summary_splits_ties_and_counts_both_at_zero(tmp_path):
    """MT50's "NDP >= PPO on n tasks" counts ties; the summary says how many are both at 0."""
    runs = tmp_path / "runs"
    for task, ndp, ppo in [
        ("reach-v3", 0.9, 0.5),
        ("push-v3", 0.0, 0.0),
        ("pick-place-v3", 0.0, 0.3),
    ]:
        _rl_run(runs, task, "ndp", 0, ndp)
        _rl_run(runs, task, "ppo", 0, ppo)
    report([runs], tmp_path / "rep", "ndp report runs")
    md = (tmp_path / "rep.md").read_text()
    assert "Over tasks (3 of 3 tasks where every method has runs):" in md
    assert (
        "NDP >= ppo (mean final success) on 2 of 3 tasks: higher on 1, equal on 1 "
        "(1 with both at 0), lower on 1." in md
    )
    assert "| ndp | 0.300 |" in md and "| ppo | 0.267 |" in md
    # 3 or more tasks: one bar chart of final success per task and method, first in the page
    png = tmp_path / "rep-over-tasks.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    figs = [line for line in md.splitlines() if line.startswith("![")]
    assert figs[0] == "![rep-over-tasks](rep-over-tasks.png)" and len(figs) == 4


def test_report_refuses_a_cell_with_missing_seeds(tmp_path, capsys):
    runs = tmp_path / "runs"
    _grid(runs)
    _rl_run(runs, "push-v3", "ndp", 2, 0.9)  # seed 2 only in one cell
    _rl_run(runs, "push-v3", "ppo", 2, 0.1, done=False)  # unfinished: a missing seed too
    with pytest.raises(MissingSeedsError) as err:
        report([runs], tmp_path / "rep", "cmd")
    msg = str(err.value)
    assert "seeds missing from 3 of 4 cells" in msg and "soccer-v3 x ndp: seeds [2] missing" in msg
    assert "push-v3 x ppo: seeds [2] missing (1 unfinished: seeds [2])" in msg
    assert "--allow-missing" in msg and not (tmp_path / "rep.md").exists()
    # the command: exit 2, the same message, nothing written
    assert main(["report", str(runs), "--out", str(tmp_path / "rep")]) == 2
    assert "soccer-v3 x ndp: seeds [2] missing" in capsys.readouterr().err
    # --seeds 0 1: complete; --allow-missing: loud markers in every output
    assert main(["report", str(runs), "--out", str(tmp_path / "ok"), "--seeds", "0", "1"]) == 0
    res = report([runs], tmp_path / "marked", "cmd", allow_missing=True)
    md = (tmp_path / "marked.md").read_text()
    assert "**WARNING: seeds are missing from 3 cells" in md
    assert "| soccer-v3 | ndp | 2 **MISSING seeds 2** |" in md
    assert {(t, m): s for t, m, s in res["missing"]}[("push-v3", "ppo")] == [2]
    with (tmp_path / "marked.csv").open() as fh:
        rows = {(r["task"], r["method"]): r for r in csv.DictReader(fh)}
    assert rows[("soccer-v3", "ndp")]["missing_seeds"] == "2"
    assert rows[("push-v3", "ndp")]["missing_seeds"] == ""


def test_report_reads_plain_runs_and_filters(tmp_path):
    runs = tmp_path / "runs"
    for s in (0, 1):
        _rl_run(runs, "reach-v3", "ppo", s, 1.0, arm=False)  # a plain `ndp rl train` run
        _rl_run(runs, "reach-v3", "ndp", s, 0.5, arm=False)
    _rl_run(runs, "pick", "ndp", 0, 0.5)  # filtered out below (its seeds would be missing)
    res = report([runs], tmp_path / "r", "cmd", tasks=["reach-v3"], methods=["ppo"], plots=False)
    assert [(r["task"], r["method"], r["n_seeds"]) for r in res["rows"]] == [("reach-v3", "ppo", 2)]
    # rows follow the order of --methods (found: ndp before ppo)
    res = report([runs], tmp_path / "r", "cmd", tasks=["reach-v3"], methods=["ppo", "ndp"])
    assert [r["method"] for r in res["rows"]] == ["ppo", "ndp"]
    md = (tmp_path / "r.md").read_text()
    assert md.index("| reach-v3 | ppo |") < md.index("| reach-v3 | ndp |")
    with pytest.raises(ValueError, match="no runs of the methods"):
        report([runs], tmp_path / "r", "cmd", methods=["dyne"])
    # a wrong method beside a right task is named as the method (it was "no runs of the tasks")
    with pytest.raises(ValueError, match=r"no runs of the methods \['dyne'\] .*found: ndp, ppo"):
        report([runs], tmp_path / "r", "cmd", tasks=["reach-v3"], methods=["dyne"])
    # the report's own arguments are checked before any run is read
    for kw, msg in (({"seeds": [-1]}, "seeds: expected integers >= 0"),
                    ({"budgets": [0]}, "budgets: expected env steps > 0")):  # fmt: skip
        with pytest.raises(ValueError, match=msg):
            report([tmp_path / "nope"], tmp_path / "r2", "cmd", **kw)
    with pytest.raises(FileNotFoundError):
        report([tmp_path / "nope"], tmp_path / "r", "cmd")


def test_report_of_imitation_runs(tmp_path):
    runs = tmp_path / "runs"
    for model in ("ndp", "cnn"):
        for seed in (0, 1):
            run = runs / f"synthetic-300-{model}-s{seed}"
            run.mkdir(parents=True)
            (run / "metrics.csv").write_text("epoch,train/loss,test/mse_px2\n1,5,9\n2,4,8\n")
            mse = {"ndp": 2.0, "cnn": 4.0}[model] + seed
            (run / "eval.json").write_text(json.dumps(
                {"test_mse_px2": {"mean": mse}, "test_dtw_px": {"mean": 1.0}}))  # fmt: skip
            (run / "arm.json").write_text(json.dumps({
                "label": model, "algo": f"il-{model}", "args": [], "steps": 2,
                "task": "synthetic-300", "seed": seed, "kind": "il"}))  # fmt: skip
            (run / "done.json").write_text("{}")
    res = report([runs], tmp_path / "il", "cmd")
    md = (tmp_path / "il.md").read_text()
    assert "| synthetic-300 | ndp | 2 | 2.50 +- 0.50 | 1.00 +- 0.00 |" in md
    assert "| synthetic-300 | cnn | 2 | 4.50 +- 0.50 |" in md
    assert res["png"] and all(p.endswith(".png") for p in res["png"])


def test_success_at_budget():
    x = np.arange(1, 11) * 100.0
    y = np.r_[np.zeros(5), np.ones(5)]
    assert success_at(x, y, 1000, 1000) == 1.0  # updates at 1000 (the last 10% of [0, 1000])
    assert success_at(x, y, 500, 1000) == 0.0
    assert success_at(x, y, 250, 1000) == 0.0  # no update in (225, 250]: the last before it
    assert math.isnan(success_at(x, y, 2000, 1000))  # past the run's budget


def test_report_deterministic_success_column_reads_and_writes_the_per_run_cache(
    tmp_path, monkeypatch
):

    runs = tmp_path / "runs"
    _grid(runs, seeds=(0,))
    calls = []

    def fake_evaluate(path, episodes, deterministic):
        calls.append((path.name, episodes, deterministic))
        return {"success_any": 0.25 if "ndp" in path.name else 0.75}

    monkeypatch.setattr("ndp.rl.evaluate.evaluate", fake_evaluate)
    # a cache already there is read, not recomputed
    (runs / "push-v3-ndp-s0" / "eval-det-e5.json").write_text(json.dumps({"success_any": 1.0}))
    res = report([runs], tmp_path / "rep", "cmd", eval_episodes=5)
    assert sorted(calls) == [("push-v3-ppo-s0", 5, True), ("soccer-v3-ndp-s0", 5, True),
                             ("soccer-v3-ppo-s0", 5, True)]  # fmt: skip
    by = {(r["task"], r["method"]): r for r in res["rows"]}
    assert by[("push-v3", "ndp")]["det_success_mean"] == 1.0
    assert by[("soccer-v3", "ndp")]["det_success_mean"] == 0.25
    md = (tmp_path / "rep.md").read_text()
    assert "deterministic success |" in md and "over 5 fresh episodes" in md
    # the summary over tasks gains the mean deterministic success: ndp (1.0 + 0.25) / 2
    assert "| method | mean final success | mean success area | mean deterministic success |" in md
    assert next(r for r in md.splitlines() if r.startswith("| ndp |")).endswith(" 0.625 |")
    assert next(r for r in md.splitlines() if r.startswith("| ppo |")).endswith(" 0.750 |")
    assert json.loads((runs / "push-v3-ppo-s0" / "eval-det-e5.json").read_text()) == {
        "success_any": 0.75
    }
    calls.clear()
    report([runs], tmp_path / "rep2", "cmd", eval_episodes=5)
    assert calls == []  # every run cached now
    assert "deterministic" not in (
        report([runs], tmp_path / "rep3", "cmd")["markdown"] and (tmp_path / "rep3.md").read_text()
    )
    with pytest.raises(ValueError, match="eval_episodes"):
        report([runs], tmp_path / "rep4", "cmd", eval_episodes=-1)


def _release_runs(root, seeds=(0, 1, 2)):
    """Every arm of the release-conditions study on its 3 tasks: success constant per run,
    NDP's 0.9 under fixed goals (arms *-v1-fixed), 0.1 elsewhere; PPO-multi 0.5; PPO 0.3 + 0.1
    per seed; success at the final step half of it."""
    from ndp.experiments.studies import RELEASE_TASKS, get_study

    for spec in get_study("release-conditions").arm_specs():
        for task in RELEASE_TASKS:
            for seed in seeds:
                if spec.algo == "ndp":
                    y = 0.9 if spec.label.endswith("-v1-fixed") else 0.1
                else:
                    y = 0.5 if spec.algo == "ppo-multi" else 0.3 + 0.1 * seed
                run = _rl_run(root, task, spec.label, seed, y, algo=spec.algo)
                rows = list(csv.reader((run / "metrics.csv").open()))
                rows[0].append("charts/success_final")
                for r in rows[1:]:
                    r.append(str(float(r[2]) / 2))
                with (run / "metrics.csv").open("w", newline="") as fh:
                    csv.writer(fh).writerows(rows)


@pytest.fixture(scope="module")
def release_report(tmp_path_factory):
    """One report of the release-conditions fixture runs (a minute beside other work), read by
    the two tests below: (the report's result, the folder of its outputs)."""
    tmp_path = tmp_path_factory.mktemp("release-report")
    runs = tmp_path / "runs"
    _release_runs(runs)
    res = report([runs], tmp_path / "out" / "rc", "ndp report runs --study release-conditions",
                 study="release-conditions")  # fmt: skip
    return res, tmp_path


def test_report_of_a_study_with_conditions(release_report):
    res, tmp_path = release_report
    md = (tmp_path / "out" / "rc.md").read_text()
    assert "**release-goals (UNEQUAL)**" in md and "## Conditions" in md
    # per task: NDP under fixed goals 0.90 at any step, 0.45 at the final step, every seed
    # (area 0.81: the curve is 0 before the first logged update, at 10% of the budget)
    assert ("| fixed-all | ndp | `ndp-v1-fixed` | 3 | 0.81 [0.81, 0.81] | 0.90 [0.90, 0.90] "
            "| 0.45 [0.45, 0.45] |") in md  # fmt: skip
    # tasks in the study's order
    assert md.index("### push-v3") < md.index("### soccer-v3") < md.index("### faucet-open-v3")
    # PPO: seeds 0.3, 0.4, 0.5 -> mean 0.40, the bootstrap interval inside [0.3, 0.5]
    row = next(
        r
        for r in (csv.DictReader((tmp_path / "out" / "rc-conditions.csv").open()))
        if r["condition"] == "fair" and r["task"] == "push-v3" and r["method"] == "ppo"
    )
    assert float(row["final_mean"]) == pytest.approx(0.4)
    assert 0.3 <= float(row["final_ci_low"]) < 0.4 < float(row["final_ci_high"]) <= 0.5
    # over tasks: IQM of PPO's 9 runs (three each of 0.3, 0.4, 0.5): the middle 5 -> 0.4
    assert re.search(r"\| fair \| ppo \| [0-9.]+ \[[^]]*\] \| 0\.40 \[", md)
    # NDP beats every run of both baselines under fixed goals, loses every pair elsewhere
    assert "| release-goals (UNEQUAL) | 1.00 [1.00, 1.00] |" in md
    assert "| fair | 0.00 [0.00, 0.00] |" in md
    lines = [ln for ln in md.splitlines() if ln.startswith("| release-goals (UNEQUAL) | 1.00")]
    assert lines and lines[0].endswith("| yes |")  # 0.9 > 0.5 > 0.4
    assert next(ln for ln in md.splitlines() if ln.startswith("| v1 | 0.00")).endswith("| no |")
    assert any(p.endswith("rc-conditions.png") for p in res["png"])
    # the per-arm table carries the final-step success too
    assert "final success (final step)" in md


def test_report_selects_each_models_learning_rate_on_validation_only(tmp_path):
    """digits-converged: per data set and model the arm with the lowest mean validation MSE is
    chosen, even where another arm has a lower test MSE; its test MSE, CI, epochs to best and
    wall time are reported; an early-stopped run (done.json) counts as finished."""
    from ndp.experiments.studies import get_study

    runs = tmp_path / "runs"
    val = {"3e-4": 3.0, "1e-3": 2.0, "3e-3": 2.5}
    test = {"3e-4": 1.0, "1e-3": 5.0, "3e-3": 9.0}  # the test split must not decide
    for spec in get_study("digits-converged").arm_specs():
        lr = spec.label.rsplit("-lr", 1)[1]
        for seed in (0, 1, 2):
            run = runs / f"synthetic-300-{spec.label}-s{seed}"
            run.mkdir(parents=True)
            rows = ["epoch,train/loss,val/mse_px2,test/mse_px2,time/epoch_s"]
            rows += [f"{e},1,{val[lr] + (e - 3) ** 2},,2" for e in range(1, 7)]
            rows[-1] += ""
            (run / "metrics.csv").write_text("\n".join(rows) + "\n")
            (run / "eval.json").write_text(json.dumps({"test_mse_px2": {"mean": test[lr] + seed}}))
            # lr 3e-3 of seed 2 reached its epoch cap (6 here; not stopped by patience)
            capped = (lr, seed) == ("3e-3", 2)
            reason = "budget" if capped else "early stop"
            (run / "arm.json").write_text(json.dumps({
                "label": spec.label, "algo": spec.algo, "args": list(spec.args),
                "steps": 6 if capped else 500, "task": "synthetic-300", "seed": seed,
                "kind": "il"}))  # fmt: skip
            (run / "done.json").write_text(json.dumps({"reason": reason, "epoch": 6}))
    res = report([runs], tmp_path / "dc", "cmd", study="digits-converged", plots=False,
                 tasks=["synthetic-300"])  # fmt: skip
    md = (tmp_path / "dc.md").read_text()
    # the test split is scored once: the drawn curve is the validation MSE, and says so
    from ndp.experiments.report import il_numbers, run_info

    nums = il_numbers(run_info(runs / "synthetic-300-ndp-lr1e-3-s0"))
    assert nums["curve_of"] == "validation" and list(nums["curve"][1][:3]) == [6.0, 3.0, 2.0]
    assert "## Selected on the validation split" in md
    for model in ("ndp", "cnn", "cnn-dmp"):
        row = next(ln for ln in md.splitlines() if ln.startswith(f"| synthetic-300 | {model} |"))
        # lr 1e-3: validation 2.0 (lowest); test 5, 6, 7 -> mean 6; best epoch 3; wall 6 x 2 s
        assert f"`{model}-lr1e-3` | 3 | 2 | 6 [" in row and "| 3 | 3/3 | 12 |" in row, row
        assert f"`{model}-lr3e-3` 2.5 (cap 1/3)" in row and f"`{model}-lr3e-4` 3 |" in row
    assert res["missing"] == []
    assert res["section_csv"] == [str(tmp_path / "dc-selection.csv")]  # named in "wrote ..."


def test_selection_compares_a_models_arms_on_the_seeds_they_all_finished(tmp_path):
    """With seeds missing (--allow-missing), each model's arms are compared on the seeds every
    one of them has finished, the row says which are missing, and a model whose arms share no
    finished seed gets no choice at all."""
    from ndp.experiments.studies import get_study

    runs = tmp_path / "runs"
    val = {"3e-4": 3.0, "1e-3": 2.0, "3e-3": 2.5}
    for spec in get_study("digits-converged").arm_specs():
        model, lr = spec.label.rsplit("-lr", 1)
        for seed in (0, 1, 2):
            if model == "ndp" and lr == "3e-3" and seed == 2:
                continue  # still training: ndp is compared on seeds 0-1
            if model == "cnn" and (lr == "3e-4") != (seed == 2):
                continue  # cnn-lr3e-4 has run seed 2 only, cnn-lr1e-3 / 3e-3 seeds 0-1 only
            run = runs / f"synthetic-300-{spec.label}-s{seed}"
            run.mkdir(parents=True)
            # seed 2 of ndp-lr1e-3 is very bad on validation: it must not count for ndp
            v = 50.0 if (model, lr, seed) == ("ndp", "1e-3", 2) else val[lr]
            rows = ["epoch,train/loss,val/mse_px2,test/mse_px2,time/epoch_s"]
            rows += [f"{e},1,{v + (e - 3) ** 2},,2" for e in range(1, 7)]
            (run / "metrics.csv").write_text("\n".join(rows) + "\n")
            (run / "eval.json").write_text(json.dumps({"test_mse_px2": {"mean": 5.0 + seed}}))
            (run / "arm.json").write_text(json.dumps({
                "label": spec.label, "algo": spec.algo, "args": list(spec.args),
                "steps": 500, "task": "synthetic-300", "seed": seed, "kind": "il"}))  # fmt: skip
            (run / "done.json").write_text(json.dumps({"reason": "early stop", "epoch": 6}))
    report([runs], tmp_path / "dc", "cmd", study="digits-converged", plots=False,
           tasks=["synthetic-300"], seeds=[0, 1, 2], allow_missing=True)  # fmt: skip
    md = (tmp_path / "dc.md").read_text()
    row = {m: next(ln for ln in md.splitlines() if ln.startswith(f"| synthetic-300 | {m} |"))
           for m in ("ndp", "cnn", "cnn-dmp")}  # fmt: skip
    # ndp: seeds 0-1 only; lr 1e-3 still wins (2.0), its test mean over seeds 0-1 is 5.5
    assert "`ndp-lr1e-3` | 2 **MISSING seeds 2** | 2 | 5.5 [" in row["ndp"], row["ndp"]
    assert "no seed that every arm has finished yet" in row["cnn"]
    assert "`cnn-dmp-lr1e-3` | 3 | 2 | 6 [" in row["cnn-dmp"], row["cnn-dmp"]
    sel = list(csv.DictReader((tmp_path / "dc-selection.csv").open()))
    assert [(r["model"], r["seeds"]) for r in sel if r["arm"] != "fit_dmp"] == [
        ("ndp", "0 1"), ("cnn-dmp", "0 1 2")]  # fmt: skip


def test_conditions_report_per_task_arms_permutation_tests_and_gap(release_report):
    """The corrected release-goals condition takes PPO's arm per task (faucet-open: the
    fixed-goal arm); every pair of methods gets exact permutation p-values per task and pooled;
    the over-tasks table gives rliable's optimality gap; a profiles figure is written."""
    res, tmp_path = release_report
    md = (tmp_path / "out" / "rc.md").read_text()
    assert "ppo = `ppo-v1 / faucet-open-v3: ppo-v1-fixed`" in md
    rows = list(csv.DictReader((tmp_path / "out" / "rc-conditions.csv").open()))

    def cell(cond, task, method):
        return next(
            r for r in rows if (r["condition"], r["task"], r["method"]) == (cond, task, method)
        )

    # on faucet-open the corrected condition's PPO is ppo-v1-fixed; both PPO arms have the same
    # fixture numbers, so check the arm it names
    assert cell("release-goals per task", "faucet-open-v3", "ppo")["arm"].startswith("ppo-v1 /")
    # NDP (0.9 everywhere under fixed goals) beats PPO (0.3-0.5) in every pair: per task the
    # smallest one-sided p of 3 + 3 seeds, 1/20; pooled over 3 tasks 1/20^3
    push = cell("release-goals per task", "push-v3", "ndp vs ppo")
    assert float(push["p_a_greater"]) == pytest.approx(0.05)
    pooled = next(r for r in rows if r["condition"] == "release-goals per task"
                  and r["task"].startswith("over ") and r["method"] == "ndp vs ppo")  # fmt: skip
    assert float(pooled["p_a_greater"]) == pytest.approx(1 / 8000)
    assert float(pooled["p_b_greater"]) == pytest.approx(1.0)
    # two-sided p, Holm within the condition's three pairs of the table, and the test's label
    assert float(push["p_two_sided"]) == pytest.approx(0.1) and push["holm_m"] == "3"
    assert push["p_method"] == "exact permutation (all 20 splits)"
    assert float(pooled["p_two_sided"]) == pytest.approx(2 / 8000)
    assert pooled["p_method"] == "exact permutation (all 8,000 splits)"
    family = [r for r in rows if r["condition"] == "release-goals per task"
              and r["task"] == pooled["task"] and r.get("p_holm")]  # fmt: skip
    assert len(family) == 3 and pooled["significant"] == "True"
    raw = sorted(float(r["p_two_sided"]) for r in family)
    assert min(float(r["p_holm"]) for r in family) == pytest.approx(3 * raw[0])
    assert "| Holm p (m) | Holm p <= 0.05 | one-sided p(A > B) | one-sided p(B > A) | test |" in md
    assert "| **ndp > ppo** |" in md
    # optimality gap of NDP's identical runs (area ~0.81): 1 - area
    iq = cell("fixed-all", "IQM over tasks", "ndp")
    assert 0.8 < float(iq["area_mean"]) < 0.82
    assert float(iq["gap_mean"]) == pytest.approx(1 - float(iq["area_mean"]), abs=1e-9)
    assert "optimality gap, success area" in md and "t-interval" in md
    assert any(p.endswith("rc-profiles.png") for p in res["png"])


def test_report_header_names_environments_lost_commits_and_mixed_runs(tmp_path):
    """The header lists the runs' environment fingerprints (package versions, CPU model); a
    commit that no ref of the repository reaches is marked lost; runs of several commits or
    fingerprints get a MIXED warning, one commit and one fingerprint none."""
    from ndp.provenance import commit_in_history, git_commit

    head = git_commit(short=False)
    runs = tmp_path / "runs"
    env = {"python": "3.11.7", "torch": "2.13.0", "numpy": "2.4.6", "mujoco": "3.3.0",
           "metaworld": "3.1.1"}  # fmt: skip
    for seed in (0, 1):
        for label in ("ndp", "ppo"):
            run = _rl_run(runs, "push-v3", label, seed, 0.5)
            entry = {"event": "start", "commit": head, "versions": env, "cpu": "CPU A"}
            (run / "provenance.json").write_text(json.dumps([entry]))
    report([runs], tmp_path / "one", "cmd", title="One")
    md = (tmp_path / "one.md").read_text()
    fp = "python 3.11.7, torch 2.13.0, numpy 2.4.6, mujoco 3.3.0, metaworld 3.1.1, CPU CPU A"
    assert f"Runs' environment: {fp} (every run)." in md
    assert "MIXED" not in md and "lost" not in md
    # one run resumed on another CPU, one trained at a commit outside the history
    other = runs / "push-v3-ppo-s1" / "provenance.json"
    sessions = json.loads(other.read_text())
    other.write_text(json.dumps([*sessions, {**sessions[0], "event": "resume", "cpu": "CPU B"}]))
    lost = runs / "push-v3-ndp-s1" / "provenance.json"
    lost.write_text(json.dumps([{"event": "start", "commit": "abcdef0123", "versions": env}]))
    report([runs], tmp_path / "two", "cmd", title="Two")
    md = (tmp_path / "two.md").read_text()
    assert f"{fp} (3 runs)" in md and "CPU B (1 run)" in md and "CPU not recorded (1 run)" in md
    assert "**MIXED: the 4 runs of this table were trained at 2 commits (" in md
    assert f"{head[:7]}: 3 runs" in md and "abcdef0: 1 run" in md
    assert "and 3 environment fingerprints (above)" in md
    if commit_in_history(head[:7]):  # a git checkout with its history (not an sdist)
        assert f"{head[:7]}, abcdef0 (lost: not in this repository's history)" in md or (
            f"abcdef0 (lost: not in this repository's history), {head[:7]}" in md
        )


def test_report_headlines_the_periodic_deterministic_evaluation(tmp_path):
    """Runs with eval/* columns: the table's first numbers are the deterministic area (mean over
    evaluations) and final; the figure of deterministic success is written."""
    runs = tmp_path / "runs"
    for seed in (0, 1):
        run = _rl_run(runs, "push-v3", "ndp", seed, 0.2)
        rows = list(csv.reader((run / "metrics.csv").open()))
        rows[0] += ["eval/success_any", "eval/success_final"]
        for i, r in enumerate(rows[1:]):
            r += [str(0.1 * (i + 1)), str(0.05 * (i + 1))] if i % 3 == 2 else ["", ""]
        with (run / "metrics.csv").open("w", newline="") as fh:
            csv.writer(fh).writerows(rows)
    res = report([runs], tmp_path / "o" / "r", "ndp report runs")
    md = (tmp_path / "o" / "r.md").read_text()
    # evaluations at updates 3, 6, 9: 0.3, 0.6, 0.9 -> area 0.6, final 0.9, final step 0.45
    assert "| push-v3 | ndp | 2 | 0.60 +- 0.00 | 0.90 +- 0.00 | 0.45 +- 0.00 |" in md
    assert res["rows"][0]["det_success_area_mean"] == pytest.approx(0.6)
    assert any(p.endswith("r-push-v3-det.png") for p in res["png"])


def test_a_report_without_conditions_tests_every_pair_of_methods(tmp_path):
    """Every pair of methods on a task gets exact permutation p-values of the success area:
    with every run of one above every run of the other, 3 + 3 runs give one-sided p = 1 / 20
    and 1, two-sided 2 / 20; Holm over the task's three pairs (0.1, 0.1, ~1) gives 0.3: not
    significant. Each p is labelled with its test."""
    runs = tmp_path / "runs"
    for seed in (0, 1, 2):
        _rl_run(runs, "push-v3", "ndp", seed, 0.8 + 0.01 * seed)
        _rl_run(runs, "push-v3", "ppo", seed, 0.5 + 0.01 * seed)
        _rl_run(runs, "push-v3", "sac", seed, 0.5 + 0.01 * (2 - seed))
    report([runs], tmp_path / "rep", "ndp report runs", title="Pairs")
    md = (tmp_path / "rep.md").read_text()
    assert re.search(
        r"\| push-v3 \| success area \| ndp vs ppo \| 3 \+ 3 \| \+0\.\d+ \| \[\+0\.\d+, \+0\.\d+\] "
        r"\| 0\.100 \| 0\.300 \(3\) \| not significant \| 0\.050 \| 1\.000 "
        r"\| exact permutation \(all 20 splits\) \|",
        md,
    )
    assert "| p (two-sided) | Holm p (m) | Holm p <= 0.05 | one-sided p(A > B) |" in md
    with (tmp_path / "rep-pairwise.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["method"] for r in rows] == ["ndp vs ppo", "ndp vs sac", "ppo vs sac"]
    ppo_sac = rows[2]  # the same three areas in another seed order: no direction at all
    assert float(ppo_sac["diff_mean"]) == pytest.approx(0.0, abs=1e-12)
    assert float(ppo_sac["p_a_greater"]) > 0.4 and float(ppo_sac["p_b_greater"]) > 0.4
    assert [float(r["p_two_sided"]) for r in rows[:2]] == pytest.approx([0.1, 0.1])
    assert [float(r["p_holm"]) for r in rows] == pytest.approx([0.3, 0.3, 1.0])
    assert {r["holm_m"] for r in rows} == {"3"} and {r["significant"] for r in rows} == {"False"}
    assert {r["p_method"] for r in rows} == {"exact permutation (all 20 splits)"}
    assert all(r["commit"] for r in rows)  # provenance in every row
    # the difference's Welch interval: around the difference, above 0 (the spreads are small)
    d, lo, hi = (float(rows[0][k]) for k in ("diff_mean", "diff_t_low", "diff_t_high"))
    assert 0 < lo < d < hi and hi - d == pytest.approx(d - lo)
    # a task crowded with methods gets a line saying how to narrow it, not hundreds of pairs
    from ndp.experiments.report.conditions import PAIRWISE_MAX_METHODS

    for i in range(PAIRWISE_MAX_METHODS + 1):
        for seed in (0, 1):
            _rl_run(runs, "soccer-v3", f"arm{i}", seed, 0.1 * (i % 3))
    report([runs], tmp_path / "rep2", "ndp report runs", title="Crowded", allow_missing=True)
    md = (tmp_path / "rep2.md").read_text()
    assert f"Pairwise tests left out on soccer-v3 ({PAIRWISE_MAX_METHODS + 1} methods)" in md
    assert "| push-v3 | success area | ndp vs ppo |" in md  # the other task is still tested


def test_pairs_are_also_tested_over_all_tasks_stratified(tmp_path):
    """With two tasks, each pair gets a row over both: labels exchanged within each task, so
    every NDP run above every PPO run on both tasks gives p = 1 / C(6, 3)^2 = 1 / 400; a method
    without runs on every task gets no such row."""
    runs = tmp_path / "runs"
    for seed in (0, 1, 2):
        for task, base in (("push-v3", 0.5), ("soccer-v3", 0.1)):
            _rl_run(runs, task, "ndp", seed, base + 0.3 + 0.01 * seed)
            _rl_run(runs, task, "ppo", seed, base + 0.01 * seed)
        _rl_run(runs, "push-v3", "sac", seed, 0.2)
    report([runs], tmp_path / "rep", "ndp report runs", title="Pooled", allow_missing=True)
    with (tmp_path / "rep-pairwise.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    pooled = [r for r in rows if r["task"].startswith("all tasks")]
    assert [r["method"] for r in pooled] == ["ndp vs ppo"]
    assert pooled[0]["task"] == "all tasks (push-v3, soccer-v3)"
    assert float(pooled[0]["p_a_greater"]) == pytest.approx(1 / 400)
    assert float(pooled[0]["p_b_greater"]) == pytest.approx(1.0)
    assert 0.2 < float(pooled[0]["diff_mean"]) < 0.35
    md = (tmp_path / "rep.md").read_text()
    assert "| all tasks (push-v3, soccer-v3) | success area | ndp vs ppo | 3 + 3 |" in md


def _with_eval(run, value):
    """Add periodic-evaluation columns (every third update at ``value``) to a fake run."""
    rows = list(csv.reader((run / "metrics.csv").open()))
    rows[0] += ["eval/success_any", "eval/success_final"]
    for i, r in enumerate(rows[1:]):
        r += [str(value), str(value)] if i % 3 == 2 else ["", ""]
    with (run / "metrics.csv").open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)


def test_an_arm_on_some_tasks_only_and_newer_runs_with_evaluation(tmp_path):
    """release-goals-1m's `ppo-fixed` runs on Throw only: no push-v3 cell (so no missing seeds,
    no refusal), left out of the summary over tasks by name, and PPO's Throw arm of the
    release-goals condition. Only its runs have periodic evaluation: the training-episode area
    stays the headline, so every comparison still covers every run (no empty over-tasks)."""
    runs = tmp_path / "runs"
    arms = {"ndp": 0.4, "ppo-multi": 0.5, "ppo": 0.6, "ndp-fixed": 0.45, "ppo-multi-fixed": 0.55}
    for seed in (0, 1, 2):
        for task in ("push-v3", "throw"):
            for label, v in arms.items():
                _rl_run(runs, task, label, seed, v + 0.01 * seed, algo=label.split("-fixed")[0])
        _with_eval(_rl_run(runs, "throw", "ppo-fixed", seed, 0.7 + 0.01 * seed, algo="ppo"), 0.9)
    res = report([runs], tmp_path / "rg", "cmd", study="release-goals-1m")
    assert res["missing"] == []
    md = (tmp_path / "rg.md").read_text()
    assert "| push-v3 | ppo-fixed |" not in md and "| throw | ppo-fixed | 3 | 0.90" in md
    assert "not ppo-fixed, which run on some tasks only" in md
    assert "no condition has every seed of every arm on two tasks" not in md
    with (tmp_path / "rg-conditions.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    # throw, release-goals: NDP's fixed arm against PPO's fixed arm, every PPO run above
    throw = [r for r in rows if r["task"] == "throw" and r["condition"] == "release-goals"
             and r["method"] == "ndp vs ppo"]  # fmt: skip
    assert throw and throw[0]["arm"].endswith("throw: ppo-fixed")
    assert float(throw[0]["p_b_greater"]) == pytest.approx(0.05)
    iqm = [r for r in rows if r["task"] == "IQM over tasks" and r["condition"] == "release-goals"]
    assert {r["method"] for r in iqm} == {"ndp", "ppo-multi", "ppo"}
    # the deterministic figure only for the task whose runs have the curve
    figs = sorted(Path(p).name for p in res["png"] if p.endswith("-det.png"))
    assert figs == ["rg-throw-det.png"]


def _short_run(root, seed, cut=False):
    """A chunked run that trained all 10 planned updates of 100 slots but executed 94 env steps
    per update (its episodes end inside a decision): run.json says finished, budget 1000, done
    940; ``cut``: its metrics.csv stops at update 8 (a record cut short)."""
    from ndp.runs.session import Manifest, write_manifest

    run = _rl_run(root, "throw", "ndp-k20", seed, 0.4, algo="ndp")
    (run / "done.json").unlink()  # an RL run's own record is run.json
    rows = list(csv.reader((run / "metrics.csv").open()))
    with (run / "metrics.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(rows[0])
        for i, r in enumerate(rows[1 : 9 if cut else None]):
            w.writerow([r[0], (i + 1) * 94, *r[2:]])
    m = Manifest(kind="rl", task="throw", label="ndp", seed=seed, budget=1000, unit="env_steps",
                 done=940, finished=True, reason="budget")  # fmt: skip
    write_manifest(run, m)
    return run


def test_report_counts_a_run_that_executed_fewer_env_steps_and_says_so(tmp_path):
    """A finished run whose decisions were cut by episode ends executed fewer env steps than its
    budget: the report counts it (its record reaches what it executed) and names the shortfall;
    a record cut below what the run executed is still refused."""
    runs = tmp_path / "runs"
    for seed in (0, 1):
        _short_run(runs, seed)
        _rl_run(runs, "throw", "ppo", seed, 0.5)
    res = report([runs], tmp_path / "rep", "ndp report runs")
    md = (tmp_path / "rep.md").read_text()
    assert {r["method"] for r in res["rows"]} == {"ndp-k20", "ppo"}
    assert "**Executed env steps below the budget**" in md
    assert "throw x `ndp-k20`: 940 of 1,000 (94%) in 2 of 2 runs" in md
    assert "`ppo`:" not in md.split("**Executed env steps below the budget**")[1].split("\n")[0]
    cut = tmp_path / "cut"
    _short_run(cut, 0, cut=True)
    with pytest.raises(MissingSeedsError, match=r"metrics\.csv ends at env step 752 of 1,000"):
        report([cut], tmp_path / "rep2", "ndp report cut", seeds=[0])


def test_an_interval_with_one_run_on_a_side_says_so_instead_of_nan():
    """A Welch interval needs two runs a side: with one, the tables print ``n/a (one run)``,
    not ``[+nan, +nan]``."""
    from ndp.experiments.report.readings import interval

    assert interval(-0.0304, 0.125) == "[-0.030, +0.125]"
    assert interval(math.nan, math.nan) == "n/a (one run)"
    assert interval(0.1, math.nan) == "n/a (one run)"


def test_a_study_without_conditions_gets_its_readings_after_the_pairwise_tests(tmp_path):
    """sac-critic has readings but no conditions: the report applies them (here: three plain
    critics that run away, three LayerNorm ones that do not) and writes their CSV."""
    runs = tmp_path / "runs"
    for seed in (0, 1, 2):
        for label, peak in (("ndp-sac-k5", 5000.0), ("ndp-sac-ln-k5", 30.0)):  # returns 5
            run = _rl_run(runs, "push-v3", label, seed, 0.1, ret=10.0, algo="ndp-sac")
            with (run / "metrics.csv").open() as fh:
                rows = list(csv.reader(fh))
            rows[0] += ["sac/q", "sac/alpha"]
            for i, row in enumerate(rows[1:]):
                row += [peak * (i + 1) / 10, 0.1]
            with (run / "metrics.csv").open("w", newline="") as fh:
                csv.writer(fh).writerows(rows)
    report([runs], tmp_path / "rep", "ndp report runs --study sac-critic", study="sac-critic")
    md = (tmp_path / "rep.md").read_text()
    assert md.index("| push-v3 | success area | ndp-sac-k5 vs ndp-sac-ln-k5 |") < md.index(
        "LayerNorm **stops the runaway**"
    )
    with (tmp_path / "rep-readings.csv").open() as fh:
        verdicts = {r["item"]: r["verdict"] for r in csv.DictReader(fh)}
    assert verdicts["diverged runs (layer-norm, plain)"] == "stops the runaway"
    assert verdicts["ndp-sac-k5 s0"] == "diverged" and verdicts["ndp-sac-ln-k5 s2"] == "ok"


def test_a_report_replaces_its_own_tables_and_nothing_else(tmp_path):
    """Regenerating a report over its stem works (twice); an existing markdown or CSV that the
    package did not generate is refused before any run is read, and left as it was."""
    runs = tmp_path / "runs"
    for s in (0, 1):
        _rl_run(runs, "reach-v3", "ppo", s, 1.0, arm=False)
    for _ in range(2):
        report([runs], tmp_path / "r", "ndp report runs", plots=False)
    assert "Command: `ndp report runs`" in (tmp_path / "r.md").read_text()
    for name, text in (("notes.md", "# my notes\n"), ("data.csv", "a,b\n1,2\n")):
        (tmp_path / name).write_text(text)
        stem = tmp_path / name.split(".")[0]
        with pytest.raises(FileExistsError, match=rf"^out: .*{name} exists and is not an ndp"):
            report([tmp_path / "nope"], stem, "ndp report runs", plots=False)
        assert (tmp_path / name).read_text() == text
        assert not stem.with_suffix(".csv" if name.endswith(".md") else ".md").exists()


def test_a_dotted_report_stem_keeps_every_file_together(tmp_path):
    """``--out v1.2`` wrote v1.md / v1.csv beside v1.2-<task>.png (Path.with_suffix); every file
    now carries the whole stem, and ``--out r.md`` still writes r.md."""
    runs = tmp_path / "runs"
    for s in (0, 1):
        _rl_run(runs, "reach-v3", "ppo", s, 1.0, arm=False)
    res = report([runs], tmp_path / "v1.2", "ndp report runs")
    assert res["markdown"] == str(tmp_path / "v1.2.md") and res["csv"] == str(tmp_path / "v1.2.csv")
    assert all(Path(p).name.startswith("v1.2-") for p in res["png"]) and res["png"]
    assert not (tmp_path / "v1.md").exists()
    plain = report([runs], tmp_path / "r.md", "cmd", plots=False)
    assert plain["markdown"] == str(tmp_path / "r.md")


def test_compare_writes_the_registered_family_with_holm_over_all_of_it(tmp_path, capsys):
    """``ndp report --compare A:B C:D --compare-pooled``: each pair per task and over both
    tasks, Holm over the whole family (m = 6), in the markdown and ``-family.csv``; an unknown
    label is refused before anything is written."""
    runs = tmp_path / "runs"
    for seed in (0, 1, 2):
        for task, base in (("push-v3", 0.5), ("soccer-v3", 0.1)):
            _rl_run(runs, task, "ndp", seed, base + 0.3 + 0.01 * seed)
            _rl_run(runs, task, "ppo", seed, base + 0.01 * seed)
            _rl_run(runs, task, "sac", seed, base + 0.01 * (2 - seed))
    out = tmp_path / "fam"
    assert main(["report", str(runs), "--out", str(out), "--no-plots",
                 "--compare", "ndp:ppo", "sac:ppo", "--compare-pooled"]) == 0  # fmt: skip
    with (tmp_path / "fam-family.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["task"], r["method"]) for r in rows] == [
        ("push-v3", "ndp vs ppo"), ("soccer-v3", "ndp vs ppo"), ("all tasks", "ndp vs ppo"),
        ("push-v3", "sac vs ppo"), ("soccer-v3", "sac vs ppo"), ("all tasks", "sac vs ppo"),
    ]  # fmt: skip
    assert {r["holm_m"] for r in rows} == {"6"}
    assert float(rows[2]["p_two_sided"]) == pytest.approx(2 / 400)  # stratified, both tasks
    assert all(r["commit"] and r["command"].startswith("ndp report") for r in rows)
    assert "Registered family (6 tests" in (tmp_path / "fam.md").read_text()
    assert (
        main(["report", str(runs), "--out", str(tmp_path / "bad"), "--compare", "ndp:vices"]) != 0
    )
    assert "compare: vices is not a method of this report" in capsys.readouterr().err
    assert not list(tmp_path.glob("bad*"))
