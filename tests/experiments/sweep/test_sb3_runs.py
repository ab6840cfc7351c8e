"""The Stable-Baselines3 runs of the experiment layer: SB3's PPO with NDPPolicy and with its
MlpPolicy on the chunked env, as run dirs that sweeps and reports read (study ``sb3-ndp``)."""

from __future__ import annotations

import json
import math

import pytest

from ndp.experiments.report import report
from ndp.experiments.run_kinds import EXTERNAL_METHODS, SB3_EVAL_EPISODES, kind_of_algo
from ndp.experiments.studies import STUDIES
from ndp.experiments.study import Arm, train_command
from ndp.runs import read_metrics
from ndp.sb3 import runs as sb3_ppo
from ndp.sb3.runs import SB3_K, SB3_METHODS, SB3RunConfig, train_sb3


@pytest.fixture
def threads_restored():
    import torch

    n = torch.get_num_threads()
    yield
    torch.set_num_threads(n)  # train_sb3 runs one torch thread


def test_the_sb3_kind_lists_every_method_of_the_trainer():
    assert EXTERNAL_METHODS == SB3_METHODS  # the literal kept for a fast ndp --help
    assert {kind_of_algo(m).name for m in SB3_METHODS} == {"sb3"}


def test_sweep_commands_name_the_method_and_evaluation_for_the_chunked_methods(tmp_path):
    ppo = train_command("push-v3", Arm("sb3-ppo", "sb3-ppo"), 0, 1000, tmp_path / "a")
    assert "--method" not in ppo and "--eval-episodes" not in ppo  # as it always was
    cmd = train_command("point-mass", Arm("sb3-ndp", "sb3-ndp"), 1, 1000, tmp_path / "b")
    i, j = cmd.index("--method"), cmd.index("--eval-episodes")
    assert cmd[i + 1] == "sb3-ndp" and cmd[j + 1] == str(SB3_EVAL_EPISODES)
    assert [a.algo for a in STUDIES["sb3-ndp"].arm_specs()] == ["sb3-ndp", "sb3-multi"]


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        (
            {"method": "sb3-ddpg"},
            "method: expected one of sb3-ppo, sb3-ndp, sb3-multi, sb3-sac, sb3-td3",
        ),
        ({"method": "sb3-ppo", "k": 5}, "k: sb3-ppo runs one env step per decision"),
        ({"method": "sb3-ndp", "k": 0}, "k: expected an integer >= 1"),
        ({"eval_episodes": -1}, "eval_episodes: expected an integer >= 0"),
        ({"steps": 0}, "steps: expected an integer >= 1"),
    ],
)
def test_run_config_refuses_bad_values(kw, match):
    with pytest.raises(ValueError, match=match):
        SB3RunConfig(**{"task": "point-mass", "steps": 100, **kw})


def test_configs_written_before_the_methods_read_as_sb3_ppo():
    old = {"task": "push-v3", "steps": 1000, "seed": 0, "num_envs": 4, "horizon": None,
           "run_dir": "x"}  # fmt: skip
    cfg = SB3RunConfig.from_dict(old)
    assert (cfg.method, cfg.k, cfg.eval_episodes) == ("sb3-ppo", 1, 0)


def test_command_line_errors_name_the_argument(tmp_path, capsys):
    with pytest.raises(SystemExit):
        sb3_ppo.main(["--task", "point-mass", "--steps", "10", "--run-dir", str(tmp_path / "r"),
                      "--method", "sb3-ppo", "--k", "3"])  # fmt: skip
    assert "k: sb3-ppo runs one env step per decision" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("method", ["sb3-ndp", "sb3-multi"])
def test_a_chunked_sb3_run_logs_env_steps_evaluates_and_reports(
    method, tmp_path, threads_restored, monkeypatch
):
    import tempfile

    tmp = tmp_path / "tmp"  # where SB3's default logger would make a folder per learn() call
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    run = tmp_path / "runs" / f"point-mass-{method}-s0"
    train_sb3("point-mass", 2000, 0, run, num_envs=2, method=method, eval_episodes=2)
    assert not [p.name for p in tmp.iterdir() if p.name.startswith("SB3-")]  # nothing left behind
    rows = read_metrics(run)
    # one row per rollout: 128 decisions x 2 envs x k env steps
    assert [r["global_step"] for r in rows] == [128 * 2 * SB3_K, 2 * 128 * 2 * SB3_K]
    assert all(0.0 <= r["charts/success_any"] <= 1.0 for r in rows if r["charts/episodes"])
    manifest = json.loads((run / "run.json").read_text())
    assert manifest["label"] == method and manifest["finished"] and manifest["done"] == 2560
    cfg = json.loads((run / "config.json").read_text())
    assert (cfg["method"], cfg["k"], cfg["eval_episodes"]) == (method, SB3_K, 2)
    ev = json.loads((run / "eval-det-e2.json").read_text())
    assert ev["episodes"] == 2 and ev["deterministic"] and 0.0 <= ev["success_any"] <= 1.0
    assert math.isfinite(ev["return"]) and ev["return"] < 0  # the toy task's costs
    # the report reads the run's own evaluation (ndp rl eval cannot act with an SB3 run) ...
    res = report([tmp_path / "runs"], tmp_path / "rep", "cmd", eval_episodes=2, plots=False)
    (row,) = res["rows"]
    assert row["method"] == method and row["det_success_mean"] == ev["success_any"]
    # ... and gives no number, rather than evaluating, for a count the run was not evaluated at
    res = report([tmp_path / "runs"], tmp_path / "rep3", "cmd", eval_episodes=3, plots=False)
    assert math.isnan(res["rows"][0]["det_success_mean"])
    assert not (run / "eval-det-e3.json").exists()


def test_each_sb3_method_is_one_row_and_the_rows_give_the_old_settings():
    """The run reads a method's row (env, wrapper, model, rollout), never its name: one row per
    method, and the settings each method had before the table."""
    from ndp.rl.config import RunConfig
    from ndp.sb3.runs import PER_STEP_METHODS, SB3_METHOD_ROWS, SB3_SAC_ROLLOUT, rollout_decisions

    assert tuple(SB3_METHOD_ROWS) == SB3_METHODS
    assert set(PER_STEP_METHODS) == {"sb3-ppo", "sb3-sac", "sb3-td3"}
    assert [m for m, row in SB3_METHOD_ROWS.items() if row.robot_state] == ["sb3-ndp"]
    cfg = lambda m: SB3RunConfig("push-v3", 1000, method=m, k=1 if m in PER_STEP_METHODS else 5)  # noqa: E731
    assert rollout_decisions(cfg("sb3-ppo")) == RunConfig.steps_per_update
    assert rollout_decisions(cfg("sb3-ndp")) == rollout_decisions(cfg("sb3-multi")) == 128 * 4
    assert rollout_decisions(cfg("sb3-sac")) == rollout_decisions(cfg("sb3-td3")) == SB3_SAC_ROLLOUT
