"""Method registry: a new on-policy method is one head + one registration, then it trains."""

from __future__ import annotations

import json

import pytest
import torch

from ndp.cli import main as ndp_main
from ndp.policies.distributions import SubActionGaussian
from ndp.policies.heads import HEAD_BUILDERS, ActionHead, register_head
from ndp.rl.methods import METHODS, Method, register_method


class RepeatHead(ActionHead):
    """A toy method: one raw action per decision, held for the k sub-steps (action repeat)."""

    def __init__(self, k: int, action_dim: int) -> None:
        super().__init__()
        self.k, self.action_dim, self.n_params = k, action_dim, action_dim
        self.log_std = torch.nn.Parameter(torch.zeros(action_dim))

    def distribution(self, raw, y0=None, dy0=None):
        mean = raw.unsqueeze(1).expand(-1, self.k, -1)
        return SubActionGaussian(mean, self.log_std), {}


@pytest.fixture
def repeat_method():
    register_head("repeat")(lambda cfg, spec: RepeatHead(cfg.k, spec.action_dim))
    register_method(Method("ppo-repeat", "repeat", "PPO with each action held for k steps"))
    yield
    METHODS.pop("ppo-repeat")
    HEAD_BUILDERS.pop("repeat")


def test_a_registered_toy_method_trains_through_the_cli(tmp_path, repeat_method):
    run = tmp_path / "run"
    rc = ndp_main(
        [
            "rl",
            "train",
            "--task",
            "point-mass",
            "--algo",
            "ppo-repeat",
            "--k",
            "3",
            "--steps",
            "600",
            "--steps-per-update",
            "300",
            "--minibatches",
            "2",
            "--vector",
            "sync",
            "--run-dir",
            str(run),
            "--no-progress",
            "--no-tensorboard",
        ]
    )
    assert rc == 0
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["algo"] == "ppo-repeat" and cfg["policy"]["head"] == "repeat"
    assert cfg["policy"]["k"] == 3 and cfg["policy"]["n_basis"] is None
    assert (run / "checkpoint.pt").is_file()


def test_registry_rejects_duplicates_and_unknown_heads():
    with pytest.raises(ValueError, match="already registered"):
        register_method(Method("ppo", "step", "again"))
    with pytest.raises(ValueError, match="not a registered head"):
        register_method(Method("x", "nope", "no head"))
    with pytest.raises(ValueError, match="already registered"):
        register_head("ndp")(lambda cfg, spec: None)
    assert set(METHODS) >= {"ppo", "ppo-multi", "ndp"}
