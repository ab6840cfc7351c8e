"""Study glue: arms, run directories, success area / final success, SB3 episode counting."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from ndp.experiments.study import (
    Arm,
    _check_arm,
    final_success,
    markdown_table,
    run_dir,
    success_area,
    summarise,
    train_command,
)
from ndp.sb3.runs import EpisodeCounter


def _write_run(path, xs, ys, done=True):
    path.mkdir(parents=True)
    with (path / "metrics.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["update", "global_step", "charts/success_any"])
        for i, (x, y) in enumerate(zip(xs, ys, strict=True)):
            w.writerow([i + 1, x, y])
    if done:
        (path / "done.json").write_text("{}")


def test_success_area_and_final():
    x = np.array([100.0, 200.0, 300.0, 400.0])
    # success 1 from the first logged update (step 100) on, 0 before it
    assert success_area(x, np.ones(4), 400) == pytest.approx(0.75, abs=0.01)
    assert success_area(x, np.zeros(4), 400) == 0.0
    y = np.r_[np.zeros(18), np.ones(2)]
    assert final_success(y) == 1.0  # last 10% of 20 updates
    assert final_success(np.array([0.0, 0.5])) == 0.5  # fewer than 10: the last


def test_summarise_pools_seeds_and_skips_unfinished(tmp_path):
    arms = [Arm("a", "ndp"), Arm("b", "ppo")]
    xs = np.linspace(100, 1000, 10)
    _write_run(run_dir(tmp_path, "t", arms[0], 0), xs, np.ones(10))
    _write_run(run_dir(tmp_path, "t", arms[0], 1), xs, np.zeros(10))
    _write_run(run_dir(tmp_path, "t", arms[1], 0), xs, np.ones(10), done=False)
    s = summarise(["t"], arms, [0, 1], 1000, tmp_path)
    a = s["tasks"]["t"]["a"]
    assert a["seeds"] == [0, 1] and a["final_mean"] == 0.5 and a["final_std"] == 0.5
    assert s["tasks"]["t"]["b"]["running"] == [0] and math.isnan(s["tasks"]["t"]["b"]["area_mean"])
    rows = markdown_table(s, arms, "final")
    assert "0.50 +- 0.50 (n=2)" in rows[-1] and "(running)" in rows[-1]


def test_arm_validation_and_refusal_of_another_run(tmp_path):
    with pytest.raises(ValueError, match="algo"):
        Arm("x", "dqn")
    with pytest.raises(ValueError, match="label"):
        Arm("a b", "ndp")
    with pytest.raises(ValueError, match="args"):
        Arm("s", "sb3-ppo", ("--lr", "1"))
    arm = Arm("a", "ndp", ("--mean-clip",))
    run = run_dir(tmp_path, "push-v3", arm, 0)
    _check_arm(run, arm, 1000)
    assert json.loads((run / "arm.json").read_text())["args"] == ["--mean-clip"]
    _check_arm(run, arm, 1000)  # same arm: fine
    with pytest.raises(ValueError, match="holds another run"):
        _check_arm(run, Arm("a", "ndp"), 1000)
    cmd = train_command("push-v3", arm, 3, 1000, run, vector="sync")
    assert cmd[-3:] == ["--vector", "sync", "--mean-clip"]
    assert "--seed" in cmd and cmd[cmd.index("--seed") + 1] == "3"


def test_sb3_episode_counter_is_per_env_and_per_episode():
    c = EpisodeCounter(3)
    c.step(
        np.ones(3),
        np.array([False, False, False]),
        [{"success": True}, {"success": False}, {"success": False}],
    )
    # every env ends at the same step: three episodes, env 0 succeeded earlier in its episode
    c.step(
        np.ones(3),
        np.array([True, True, True]),
        [{"success": False}, {"success": False}, {"success": True}],
    )
    n, succ, ret = c.pop()
    assert n == 3 and succ == pytest.approx(2 / 3) and ret == 2.0
    assert c.pop()[0] == 0


def test_run_killed_before_its_first_checkpoint_restarts(tmp_path, monkeypatch):
    import ndp.experiments.study as study

    arm = Arm("ppo", "ppo")
    run = run_dir(tmp_path, "point-mass", arm, 0)
    _check_arm(run, arm, 520)
    (run / "metrics.csv").write_text("update,global_step\n1,512\n")  # no checkpoint.pt
    calls = []
    monkeypatch.setattr(study.subprocess, "run", lambda cmd, **kw: calls.append(cmd))
    study.run_one("point-mass", arm, 0, 520, tmp_path, vector="sync")
    assert not (run / "metrics.csv").exists() and "--resume" not in calls[0]
