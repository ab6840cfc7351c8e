"""The NDP head's parameter maps ('linear', 'whitened') through training, resume, loading and
export, and ``ndp rl diagnose --jacobian`` (issue 59)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

import ndp
from ndp.cli import main as ndp_main
from ndp.experiments.diagnose import main as diagnose_main
from ndp.rl.config import TrainConfig, resolve_config, unused_head_options
from ndp.runs import load_checkpoint, read_metrics
from policy_fixtures import fixture_policy

TRAIN = ["--steps-per-update", "512", "--minibatches", "4", "--vector", "sync",
         "--no-progress", "--no-tensorboard"]  # fmt: skip


def _train(run, task, steps, *extra):
    argv = ["rl", "train", "--task", task, "--steps", str(steps), "--run-dir", str(run)]
    assert ndp_main([*argv, *TRAIN, *extra]) == 0


@pytest.mark.parametrize("param_map", ["linear", "whitened"])
def test_a_param_map_trains_resumes_loads_and_exports(tmp_path, param_map, capsys):
    run = tmp_path / "run"
    _train(run, "point-mass", 1040, "--param-map", param_map)
    assert json.loads((run / "config.json").read_text())["policy"]["ndp"]["param_map"] == param_map
    ck = load_checkpoint(run, kind="rl")
    pol = ndp.load_policy(run)
    head = pol.model.head
    assert head.param_map == param_map
    if param_map == "whitened":  # saved with the weights, unchanged by the updates
        saved = ck["model"]["head.whitening"]
        assert saved.dtype == torch.float64 and saved.shape == (head.n_mapped, head.n_mapped)
        fresh = ndp.policies.build_actor_critic(pol.spec.obs_dim, pol.spec, pol.cfg.policy).head
        assert torch.equal(saved, fresh.whitening)
    else:
        assert "head.whitening" not in ck["model"]
    assert ndp_main(["rl", "train", "--resume", str(run), "--steps", "1560"]) == 0
    assert [int(r["update"]) for r in read_metrics(run)] == [1, 2, 3]
    pol = ndp.load_policy(run)
    env = pol.make_env()
    obs, info = env.reset(seed=0)
    act = pol.act(obs, info)
    env.close()
    low, high = np.asarray(pol.spec.action_low), np.asarray(pol.spec.action_high)
    assert act.shape == (5, pol.spec.action_dim) and np.all((act >= low) & (act <= high))
    out = pol.export(tmp_path / "export")
    again = ndp.load_policy(out)
    assert again.model.head.param_map == param_map
    np.testing.assert_array_equal(again.act(obs, info), act)
    pytest.importorskip("onnxruntime")
    onnx_dir = pol.export(tmp_path / "onnx", format="onnx")  # checked against act to 1e-5
    np.testing.assert_allclose(ndp.load_policy(onnx_dir).act(obs, info), act, atol=1e-5, rtol=0)


def test_push_v3_smoke_with_the_whitened_map(tmp_path):
    run = tmp_path / "push"
    _train(run, "push-v3", 520, "--param-map", "whitened", "--param-noise")
    rows = read_metrics(run)
    assert len(rows) == 1 and np.isfinite(float(rows[0]["losses/policy"]))
    assert float(rows[0]["losses/approx_kl"]) > 0  # the update moved the policy
    assert ndp.load_policy(run).model.head.whitening_rank == 16


def test_a_method_without_the_ndp_head_names_the_param_map_and_does_not_use_it():
    cfg = TrainConfig(task="point-mass", algo="ppo")
    cfg = TrainConfig(task="point-mass", algo="ppo", policy=cfg.policy.updated(param_map="linear"))
    assert unused_head_options(cfg) == ["param_map='linear'"]
    assert resolve_config(cfg).policy.ndp.param_map == "tanh"
    with pytest.raises(ValueError, match="param_map: 'whitened' needs the 'ndp' head"):
        resolve_config(TrainConfig(task="point-mass", algo="ndp-sac",
                                   policy=cfg.policy.updated(param_map="whitened")))  # fmt: skip


def _diagnose(argv, capsys):
    capsys.readouterr()
    assert ndp_main(["rl", "diagnose", *argv]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.filterwarnings("ignore:Constant")
def test_rl_diagnose_jacobian_reads_fresh_and_trained_policies(tmp_path, capsys):
    png = tmp_path / "spectra.png"
    push = str(fixture_policy("push-v3-ndp"))
    argv = ["--jacobian", push, "--task", "push-v3", "--set", "param_map=whitened"]
    out = _diagnose([*argv, "--episodes", "1", "--png", str(png)], capsys)
    trained, white = out["jacobian"]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out["png"] == str(png)
    # the trained fixture: the map at raw = 0 (condition 168.4 over 16 directions), the fresh
    # network near it, the trained policy's tanh slopes make it worse (its map's own is unchanged)
    assert trained["raw0"]["rank"] == 16 and abs(trained["raw0"]["condition"] - 168.437) < 0.01
    assert abs(trained["init"]["condition"]["median"] - 168.44) < 0.5
    t = trained["trained"]
    assert t["decisions"] == 30 and t["map_condition"]["max"] == trained["raw0"]["condition"]
    assert t["condition"]["median"] > 2 * trained["raw0"]["condition"]
    assert t["saturated"]["all"]["max"] > 0
    # the whitened head: condition 1 everywhere, no tanh to saturate
    assert white["param_map"] == "whitened" and white["raw0"]["saturated"] is None
    assert white["raw0"]["condition"] == 1.0 and white["init"]["condition"]["max"] == 1.0
    assert white["raw0"]["map_condition"] == trained["raw0"]["condition"]
    old = tmp_path / "old.png"  # the earlier entry point takes the same options
    assert (
        diagnose_main(["--jacobian", "--task", "point-mass", "--episodes", "1", "--png", str(old)])
        == 0
    )
    assert old.is_file()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--png", "x.png", "--task", "point-mass"], "--png: the figure is of the --jacobian"),
        (["zoo:push-v3-ndp", "--task", "point-mass"], "the handicap diagnostic reads one policy"),
        (["zoo:push-v3-ndp", "--set", "mean_clip=true"], "set: the overrides are of a fresh"),
        ([], "runs: give a trained policy"),
        (["--jacobian", "--task", "point-mass", "--algo", "ppo"], "reads the NDP head"),
        (["--jacobian", "--task", "point-mass", "--episodes", "0"], "episodes: expected"),
    ],
)
def test_rl_diagnose_refuses_with_one_line(argv, message, capsys):
    assert ndp_main(["rl", "diagnose", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
