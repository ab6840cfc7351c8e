"""Growing the experiment layer: a new kind of run is one row of the run-kind table, and a new
study (of any kind) is one entry of the study table; sweeps and reports then work on them with
no other change."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

from ndp.experiments import run_kinds, studies
from ndp.experiments import sweep as sw
from ndp.experiments.run_kinds import RunKind
from ndp.experiments.study import Arm

# A toy trainer: counts to its budget, one metrics row per step, then says it is finished in
# its run.json (the manifest every trainer's run session writes).
COUNTER = """
import sys
from pathlib import Path
from ndp.runs.session import Manifest, write_manifest
run, task, seed, budget = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
run.mkdir(parents=True, exist_ok=True)
rows = "".join(f"{i},{i * i}\\n" for i in range(1, budget + 1))
(run / "metrics.csv").write_text("step,value\\n" + rows)
write_manifest(run, Manifest(kind="count", task=task, label="counter", seed=seed, budget=budget,
                             unit="steps", done=budget, finished=True, reason="budget"))
"""


def _counter_algos() -> tuple[str, ...]:
    return ("counter",)


def _counter_command(
    task: str, arm: Any, seed: int, steps: int, run: Path, num_envs: int, vector: str
) -> list[str]:
    return [sys.executable, "-c", COUNTER, str(run), task, str(seed), str(steps)]


COUNT_KIND = RunKind(
    "count",
    "steps",
    "step",
    "steps",
    10,
    "",
    takes_options=False,
    resumable=False,
    algos=_counter_algos,
    command=_counter_command,
)


def test_a_new_run_kind_is_one_row(tmp_path, monkeypatch):
    monkeypatch.setitem(run_kinds.RUN_KINDS, "count", COUNT_KIND)
    arm = Arm("counter", "counter")
    assert arm.kind == "count"
    with pytest.raises(ValueError, match="args: the 'counter' arm takes no ndp options"):
        Arm("counter", "counter", ("--lr", "1"))
    jobs = sw.make_jobs(["point-mass"], [arm], [0, 1], 7, tmp_path)
    assert [sw.execute(j).status for j in jobs] == ["done", "done"]
    for j in jobs:
        rows = (j.run_dir / "metrics.csv").read_text().splitlines()
        assert len(rows) == 1 + 7
        assert json.loads((j.run_dir / "run.json").read_text())["finished"] is True
    # finished runs are reused, not trained again
    assert [sw.execute(j).status for j in jobs] == ["skipped", "skipped"]


def _one_task() -> tuple[str, ...]:
    return ("point-mass",)


def _two_arms() -> tuple[studies.ArmSpec, ...]:
    return (studies.ArmSpec("ndp", "ndp"), studies.ArmSpec("ppo-k", "ppo", ("--lr", "0.001")))


def test_a_new_study_is_one_entry_and_sweeps_and_reports(tmp_path, monkeypatch, capsys):
    from ndp.cli import main

    study = studies.Study(
        name="toy-two-arms",
        title="Two arms on the toy task",
        doc="NDP and PPO (another learning rate) on point-mass, one seed, 512 env steps.",
        tasks=_one_task,
        arms=_two_arms,
        seeds=(0,),
        steps=512,
    )
    monkeypatch.setitem(studies.STUDIES, study.name, study)
    runs = tmp_path / "runs"
    assert main(["sweep", "toy-two-arms", "--runs-dir", str(runs), "--jobs", "1"]) == 0
    assert sorted(p.name for p in runs.iterdir() if p.is_dir()) == [
        "point-mass-ndp-s0",
        "point-mass-ppo-k-s0",
    ]
    out = tmp_path / "table"
    assert main(["report", str(runs), "--study", "toy-two-arms", "--out", str(out)]) == 0
    table = out.with_suffix(".md").read_text()
    assert "| point-mass | ndp |" in table and "| point-mass | ppo-k |" in table
    capsys.readouterr()


def _count_numbers(info: Any, budgets: Any, episodes: int, evaluable: bool) -> dict[str, Any]:
    """The counter's row: its last value as every success-table number (a real kind reads its
    run's own files the same way)."""
    import math

    import numpy as np

    lines = (info.path / "metrics.csv").read_text().splitlines()[1:]
    x = np.array([float(r.split(",")[0]) for r in lines])
    y = np.array([float(r.split(",")[1]) for r in lines])
    nums = ("area", "final", "final_last", "return", "det", "det_area", "det_final")
    out: dict[str, Any] = {k: float(y[-1]) for k in nums}
    out.update({f"at:{b}": math.nan for b in budgets}, det_final_last=math.nan)
    out.update(curve=(x, y), det_curve=(x[:0], y[:0]))
    return out


def test_a_new_kind_reports_through_its_own_row(tmp_path, monkeypatch):
    """The report reads a kind's numbers and CSV columns from its row of the run-kind table:
    no branch of the report names the kind."""
    import dataclasses

    from ndp.experiments.report import report
    from ndp.experiments.rows import ReportRow

    row = ReportRow("success", _count_numbers, lambda budgets: [("last_value", "final")])
    monkeypatch.setitem(run_kinds.RUN_KINDS, "count", dataclasses.replace(COUNT_KIND, report=row))
    jobs = sw.make_jobs(["point-mass"], [Arm("counter", "counter")], [0, 1], 5, tmp_path)
    assert [sw.execute(j).status for j in jobs] == ["done", "done"]
    res = report([tmp_path], tmp_path / "t", "test", plots=False, eval_episodes=0)
    (r,) = res["rows"]
    assert (r["kind"], r["method"], r["n_seeds"]) == ("count", "counter", 2)
    assert r["last_value_mean"] == 25.0 and r["last_value_std"] == 0.0
    assert "success_area_mean" not in r  # the SUCCESS_ROW's columns are not the counter's
    assert "| point-mass | counter |" in (tmp_path / "t.md").read_text()
