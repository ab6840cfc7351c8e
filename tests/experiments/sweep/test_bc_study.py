"""Behaviour cloning as a run kind: a study of cloning runs is swept (demonstrations recorded once
per task, each run cloned and evaluated closed loop) and reported in the cloning table."""

from __future__ import annotations

import json

import pytest

from ndp.experiments import studies
from ndp.experiments import sweep as sw
from ndp.experiments.run_kinds import RUN_KINDS
from ndp.experiments.study import Arm
from ndp.experiments.sweep.bc_job import DEMOS_EPISODES, demos_file


def _toy() -> tuple[str, ...]:
    return ("point-mass",)


def _arms() -> tuple[studies.ArmSpec, ...]:
    return (
        studies.ArmSpec("ndp-n5", "bc-ndp", ("--episodes", "5", "--batch-size", "64")),
        studies.ArmSpec("nn-n5", "bc-nn", ("--episodes", "5", "--batch-size", "64")),
    )


def test_the_bc_kind_is_a_row_of_the_table():
    kind = RUN_KINDS["bc"]
    assert Arm("ndp-n5", "bc-ndp").kind == "bc"
    assert kind.needs_eval and not kind.resumable and kind.unit == "epochs"
    cmd = kind.command("throw", Arm("x", "bc-nn", ("--episodes", "25")), 1, 100, None, 4, "sync")
    assert cmd[cmd.index("--") + 1 :][:2] == ["--model", "nn"] and cmd[-2:] == ["--episodes", "25"]
    # refused before anything runs: a task without an expert, more demonstrations than recorded
    with pytest.raises(ValueError, match="throw-joint-zeta has no scripted expert"):
        sw.check_arms([Arm("ndp-n5", "bc-ndp", ("--episodes", "5"))], ["throw-joint-zeta"], "x")
    with pytest.raises(ValueError, match="episodes: 500 demonstrations asked"):
        sw.check_arms([Arm("ndp-n500", "bc-ndp", ("--episodes", "500"))], ["point-mass"], "x")


def test_a_cloning_study_sweeps_and_reports(tmp_path, monkeypatch, capsys):
    from ndp.cli import main

    study = studies.Study(
        name="toy-bc",
        title="Cloning on the toy task",
        doc="NDP and the plain network cloned from 5 demonstrations, 3 epochs, one seed.",
        tasks=_toy,
        arms=_arms,
        seeds=(0,),
        steps=3,
        kind="bc",
    )
    monkeypatch.setitem(studies.STUDIES, study.name, study)
    runs = tmp_path / "runs"
    assert main(["sweep", "toy-bc", "--runs-dir", str(runs), "--jobs", "1"]) == 0
    demos = demos_file(runs, "point-mass")
    from ndp.bc.demos import load_demos

    assert load_demos(demos).n_episodes == DEMOS_EPISODES  # one recording for every run
    for label in ("ndp-n5", "nn-n5"):
        run = runs / f"point-mass-{label}-s0"
        ev = json.loads((run / "eval.json").read_text())
        assert 0.0 <= ev["success"] <= 1.0 and ev["jerk"] >= 0.0 and ev["episodes"] == 50
        assert ev["first_seed"] > int(load_demos(demos).seeds.max())  # disjoint from the demos
        assert json.loads((run / "bc.json").read_text())["episodes"] == 5
        assert json.loads((run / "run.json").read_text())["kind"] == "bc"
    capsys.readouterr()
    # finished runs are reused
    assert main(["sweep", "toy-bc", "--runs-dir", str(runs), "--jobs", "1"]) == 0
    assert capsys.readouterr().out.count("skipped") == 2
    out = tmp_path / "bc"
    assert main(["report", str(runs), "--study", "toy-bc", "--out", str(out)]) == 0
    md = out.with_suffix(".md").read_text()
    assert "Behaviour cloning: closed-loop success" in md
    rows = [r for r in md.splitlines() if r.startswith("| point-mass |")]
    assert [r.split(" | ")[1] for r in rows] == ["ndp-n5", "nn-n5"]
    assert all(r.split(" | ")[2] == "1" for r in rows)  # one seed each
