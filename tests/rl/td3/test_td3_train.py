"""TD3 end to end: a tiny real run on reach-v3 writes metrics and a checkpoint that eval and
load_policy read, resume continues it, --help lists its options, bad input is one line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ndp.cli import main as ndp_main
from ndp.rl.methods import POLICY_CHECKPOINT_KEYS
from ndp.runs import load_checkpoint, read_metrics

COMMON = ["--task", "reach-v3", "--algo", "td3", "--num-envs", "2", "--horizon", "50",
          "--steps-per-update", "100", "--td3-random-steps", "100", "--td3-batch-size", "32",
          "--eval-every", "0", "--no-progress", "--no-tensorboard", "--vector", "sync",
          "--checkpoint-every", "1"]  # fmt: skip


def test_a_tiny_td3_run_trains_resumes_and_evaluates(tmp_path, capsys):
    run = tmp_path / "td3"
    assert ndp_main(["rl", "train", *COMMON, "--steps", "300", "--run-dir", str(run)]) == 0
    ckpt = load_checkpoint(run, kind="rl")
    assert set(POLICY_CHECKPOINT_KEYS) <= set(ckpt)
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["algo"] == "td3" and cfg["policy"]["k"] == 1
    assert cfg["policy"]["hidden"] == [400, 300] and cfg["policy"]["activation"] == "relu"
    assert cfg["td3"]["batch_size"] == 32 and cfg["td3"]["lr"] == 1e-3
    rows = read_metrics(run)
    assert [r["update"] for r in rows] == [1, 2, 3]
    last = rows[-1]
    # learning starts with the decision round that completes the 100 random env steps (its
    # 2 env steps count, as in SAC): 202 critic steps, every second one updates the actor
    assert last["td3/gradient_steps"] == 202 and last["td3/actor_updates"] == 101
    assert last["td3/replay"] == 300
    assert math.isfinite(last["losses/value"]) and math.isfinite(last["losses/policy"])
    assert math.isfinite(last["td3/q"])
    assert ckpt["td3"]["replay"]["size"] == 300

    assert ndp_main(["rl", "train", "--resume", str(run), "--steps", "400"]) == 0
    end = load_checkpoint(run, kind="rl")
    assert end["global_step"] == 400 and end["td3"]["replay"]["size"] == 400
    assert end["td3"]["grad_steps"] == 302 and end["td3"]["actor_updates"] == 151
    assert [r["update"] for r in read_metrics(run)] == [1, 2, 3, 4]

    capsys.readouterr()
    assert ndp_main(["rl", "eval", str(run), "--episodes", "1", "--mode", "deterministic"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["episodes"] == 1 and 0.0 <= out["success_any"] <= 1.0

    import ndp

    policy = ndp.load_policy(run)
    a = policy.act(np.zeros(39), deterministic=True)
    assert a.shape == (1, 4) and np.all(np.abs(a) <= 1.0)


def test_help_lists_the_td3_options(capsys):
    assert ndp_main(["rl", "train", "--help"]) == 0
    text = capsys.readouterr().out
    for flag in ("--td3-lr", "--td3-batch-size", "--td3-policy-delay", "--td3-target-noise",
                 "--td3-target-noise-clip", "--td3-expl-noise", "--td3-random-steps",
                 "--td3-init"):  # fmt: skip
        assert flag in text, flag
    assert "TD3 settings (--algo td3 only)." in text


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--td3-policy-delay", "0"], "policy_delay: expected an integer >= 1, got 0"),
        (["--td3-lr", "abc"], "--td3-lr"),
        (["--steps", "200", "--td3-random-steps", "5000"],
         "steps: --algo td3 takes its first gradient step after"),
        (["--k", "5"], "k: --algo td3 decides every 1 env step(s) on point-mass, got k=5"),
    ],
)  # fmt: skip
def test_bad_input_is_one_line_naming_the_argument(tmp_path, capsys, argv, message):
    run = tmp_path / "bad"
    rc = ndp_main(["rl", "train", "--task", "point-mass", "--algo", "td3", "--run-dir", str(run),
                   "--no-progress", "--no-tensorboard", "--vector", "sync", *argv])  # fmt: skip
    assert rc != 0
    err = capsys.readouterr().err
    assert message in err and not run.exists()


def test_options_of_td3_given_to_another_method_are_named():
    from ndp.rl.config import TrainConfig, unused_method_options
    from ndp.rl.td3.config import TD3Config

    cfg = TrainConfig(task="point-mass", algo="sac", td3=TD3Config(lr=3e-4))
    assert unused_method_options(cfg) == ["td3.lr=0.0003"]
    assert unused_method_options(TrainConfig(task="point-mass", algo="td3", td3=TD3Config())) == []


def _widest_ratio(module) -> float:
    """max over linear layers of max|w| * sqrt(fan_in): <= 1 under PyTorch's default init."""
    import torch

    return max(
        float(m.weight.detach().abs().max()) * m.in_features**0.5
        for m in module.modules()
        if isinstance(m, torch.nn.Linear)
    )


def test_td3_init_torch_gives_every_linear_layer_pytorchs_default_and_its_targets_copy_it(
    tmp_path,
):
    import torch

    from ndp.rl.config import TrainConfig, resolve_config
    from ndp.rl.run import RLRecipe
    from ndp.rl.td3.config import TD3Config
    from ndp.runs.driver import Run

    def opened(init: str) -> Run:
        cfg = TrainConfig(task="point-mass", algo="td3", num_envs=1, vector="sync",
                          run_dir=str(tmp_path / init), td3=TD3Config(init=init))  # fmt: skip
        return Run(RLRecipe(resolve_config(cfg)))

    with opened("orthogonal") as ortho, opened("torch") as plain:
        a, b = ortho.learner, plain.learner
        assert _widest_ratio(b.model.actor) <= 1 + 1e-6 and _widest_ratio(b.critic) <= 1 + 1e-6
        assert _widest_ratio(a.critic) > 1.0  # orthogonal, gain sqrt(2) for ReLU: wider
        for live, target in ((b.model, b.actor_target), (b.critic, b.critic_target)):
            for p, q in zip(live.parameters(), target.parameters(), strict=True):
                assert torch.equal(p, q)
    with pytest.raises(ValueError, match=r"^init: expected one of orthogonal, torch, got 'x'$"):
        TD3Config(init="x")  # type: ignore[arg-type]
