"""VICES methods: resolution onto the torque-actuated rows, smoke training and evaluation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ndp.cli import main as ndp_main
from ndp.envs.torque import JacoTorqueEnv, MetaWorldTorqueEnv
from ndp.rl.config import TrainConfig, resolve_config
from ndp.rl.methods import METHODS


@pytest.mark.parametrize(
    ("algo", "task", "row", "head", "k"),
    [
        ("vices", "push-v3", "push-v3-osc", "step", 1),
        ("vices", "throw", "throw-joint", "step", 1),
        ("vices", "throw-joint-zeta", "throw-joint-zeta", "step", 1),
        ("vices-pos", "throw", "throw-osc", "step", 1),
        ("vices-pos", "pick-joint-zeta", "pick-osc-zeta", "step", 1),
        ("vices-low-freq", "throw", "throw-joint-k5", "hold", 5),
        ("vices-low-freq", "push-v3", "push-v3-osc-k5", "hold", 5),
    ],
)
def test_vices_methods_resolve_to_the_torque_rows(algo, task, row, head, k):
    cfg = resolve_config(TrainConfig(task=task, algo=algo))
    assert cfg.task == row and cfg.policy.head == head and cfg.k == k
    assert resolve_config(cfg) == cfg  # idempotent (resume, eval)
    assert {"vices", "vices-pos", "vices-low-freq"} <= set(METHODS)


def test_vices_needs_a_task_with_a_torque_variant():
    with pytest.raises(ValueError, match="torque-actuated"):
        resolve_config(TrainConfig(task="point-mass", algo="vices"))


@pytest.mark.parametrize(
    ("algo", "task", "cls"),
    [
        ("vices", "push-v3", MetaWorldTorqueEnv),
        ("vices", "throw", JacoTorqueEnv),
        ("vices-low-freq", "throw", JacoTorqueEnv),
    ],
)
def test_smoke_training_with_bounded_actions_then_eval(
    tmp_path, monkeypatch, capsys, algo, task, cls
):
    seen: list[float] = []
    step = cls.step

    def spy(self, action):
        seen.append(float(np.max(np.abs(action))))
        return step(self, action)

    monkeypatch.setattr(cls, "step", spy)
    run = tmp_path / "run"
    argv = ["rl", "train", "--task", task, "--algo", algo, "--steps", "600"]
    argv += ["--steps-per-update", "300", "--minibatches", "2", "--vector", "sync"]
    argv += ["--run-dir", str(run), "--no-progress", "--no-tensorboard", "--horizon", "50"]
    assert ndp_main(argv) == 0
    assert seen and max(seen) <= 1.0  # every action reaching the simulator is bounded
    metrics = (run / "metrics.csv").read_text().splitlines()
    head = metrics[0].split(",")
    last = dict(zip(head, metrics[-1].split(","), strict=True))
    assert float(last["ctrl/nonfinite"]) == 0.0 and float(last["ctrl/gains_clipped"]) == 0.0
    assert np.isfinite(float(last["ctrl/torque_saturated"]))
    capsys.readouterr()
    assert ndp_main(["rl", "eval", str(run), "--episodes", "1", "--mode", "deterministic"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["episodes"] == 1 and out["episode_length"] == 50
