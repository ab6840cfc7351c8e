"""Smoke runs of all three methods on a Meta-World task and on Throw (one tiny update each)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ndp.rl.config import PPOConfig, TrainConfig
from ndp.rl.run import open_run
from ndp.runs import read_metrics


@pytest.mark.parametrize("task", ["push-v3", "throw"])
@pytest.mark.parametrize("algo", ["ndp", "ppo", "ppo-multi"])
def test_smoke_real_tasks(tmp_path, task, algo, record_actions):
    cfg = TrainConfig(
        task=task,
        algo=algo,
        steps=100,
        num_envs=2,
        horizon=25,
        run_dir=str(tmp_path / "r"),
        progress=False,
        tensorboard=False,
        steps_per_update=100,
        ppo=PPOConfig(minibatches=2, epochs=2),
    )
    opened = open_run(cfg)
    tr = opened.learner
    try:
        seen = record_actions(tr.envs)
        metrics = opened.train()
    finally:
        opened.close()
    acts = np.concatenate(seen)
    assert acts.shape[1:] == (tr.k, tr.spec.action_dim)
    assert acts.min() >= -1.0 and acts.max() <= 1.0  # bounded before the simulator
    assert metrics["charts/episodes"] >= 2 and metrics["charts/episode_length"] == 25
    for key in ("losses/policy", "losses/value", "charts/episode_return"):
        assert math.isfinite(metrics[key]), key
    if algo == "ndp":
        assert metrics["dmp/goal_norm"] > 0 and math.isfinite(metrics["dmp/weight_norm"])
    assert len(read_metrics(tmp_path / "r" / "metrics.csv")) == 1
