"""Every learner validates its checkpoint on load: a real save -> load round trip for SAC, TD3,
Dyn-E and the on-policy trainer, and one-line errors naming the file and the key for a missing
key, a wrong shape, NaN in a weight or in the replay and a newer schema version."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from ndp.rl.config import TrainConfig
from ndp.rl.dyne.config import DyneConfig
from ndp.rl.run import open_run, resume
from ndp.rl.sac.config import SACConfig
from ndp.rl.td3.config import TD3Config
from ndp.runs import load_checkpoint, save_checkpoint
from ndp.runs.checkpoint import SCHEMA_VERSION


def _open(tmp_path, algo, **kw):
    cfg = TrainConfig(task="point-mass", algo=algo, steps=400, seed=0,
                      run_dir=str(tmp_path / algo), progress=False, tensorboard=False,
                      vector="sync", num_envs=2, steps_per_update=100,
                      eval_every=0, checkpoint_every=1, **kw)  # fmt: skip
    return open_run(cfg)


def _first_weight(state):
    return next(k for k, v in state.items() if v.ndim == 2)


def _spoiled(section):
    """(spoil, message) pairs for a learner whose own state is under ``section``."""
    return [
        (lambda c: c[section].pop("critic_opt"), rf"{section}\.critic_opt: missing"),
        (lambda c: c.pop("global_step"), r"global_step: missing \(expected an integer\)"),
        (
            lambda c: c["model"].update({_first_weight(c["model"]): torch.zeros(1, 1)}),
            r"model\.\S+: expected shape \(\d+, \d+\), got \(1, 1\)",
        ),
        (
            lambda c: c["model"][_first_weight(c["model"])].view(-1).__setitem__(0, float("nan")),
            r"model\.\S+: holds NaN/Inf",
        ),
        (
            lambda c: c[section]["critic"][_first_weight(c[section]["critic"])].fill_(float("inf")),
            rf"{section}\.critic\.\S+: holds NaN/Inf",
        ),
        (
            lambda c: c[section]["replay"]["data"]["obs"].__setitem__((0, 0), np.nan),
            rf"{section}\.replay: column obs holds NaN/Inf",
        ),
        (lambda c: c.update(schema_version=SCHEMA_VERSION + 1), r"schema_version \d+ is newer"),
    ]


def _check_refusals(learner, ckpt, path, cases):
    for spoil, message in cases:
        bad = copy.deepcopy(ckpt)
        spoil(bad)
        with pytest.raises(ValueError, match=message) as err:
            learner.load_state_dict(bad)
        assert str(err.value).startswith(f"checkpoint {path}: ") and "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("algo", "section", "settings"),
    [
        ("sac", "sac", {"sac": SACConfig(random_steps=100, batch_size=32)}),
        ("td3", "td3", {"td3": TD3Config(random_steps=100, batch_size=32)}),
        (
            "dyne",
            "dyne",
            {
                "dyne": DyneConfig(
                    explore_steps=200, embed_updates=20, decoder_updates=20, batch_size=32
                )
            },
        ),
    ],
)
def test_an_off_policy_checkpoint_round_trips_and_a_spoiled_one_is_named(
    tmp_path, algo, section, settings
):
    opened = _open(tmp_path, algo, **settings)
    try:
        opened.train(4 if algo == "dyne" else 2)  # Dyn-E: 2 exploration iterations, 2 of TD3
        lr = opened.learner
        path = lr.run.checkpoint
        ckpt = load_checkpoint(path, kind="rl")
        assert ckpt["schema_version"] == SCHEMA_VERSION
        before = {k: v.clone() for k, v in lr.critic.state_dict().items()}
        size, grad_steps = lr.replay.size, lr.grad_steps
        lr.load_state_dict(ckpt)  # the checkpoint the current code wrote loads
        assert all(torch.equal(before[k], v) for k, v in lr.critic.state_dict().items())
        assert (lr.replay.size, lr.grad_steps) == (size, grad_steps) and size > 0
        old = {k: v for k, v in copy.deepcopy(ckpt).items() if k != "schema_version"}
        if algo == "sac":
            del old["sac"]["return_peak"]  # checkpoints before 2026-12-05 lack it
        lr.load_state_dict(old)  # a checkpoint from before the version was stored: version 1
        _check_refusals(lr, ckpt, path, _spoiled(section))
    finally:
        opened.close()


def test_a_resume_from_a_spoiled_sac_checkpoint_names_the_file(tmp_path):
    opened = _open(tmp_path, "sac", sac=SACConfig(random_steps=100, batch_size=32))
    try:
        opened.train(1)
    finally:
        opened.close()
    path = tmp_path / "sac" / "checkpoint.pt"
    ckpt = load_checkpoint(path, kind="rl")
    del ckpt["sac"]["alpha_opt"]
    save_checkpoint(path, ckpt, kind="rl")
    with pytest.raises(ValueError, match=rf"checkpoint {path}: sac\.alpha_opt: missing"):
        resume(tmp_path / "sac")


def test_an_on_policy_checkpoint_round_trips_and_a_spoiled_one_is_named(tmp_path):
    opened = _open(tmp_path, "ndp")
    try:
        opened.train(1)
        tr = opened.learner
        path = tr.ckpt_path
        ckpt = load_checkpoint(path, kind="rl")
        tr.load_state_dict(ckpt)
        tr.load_state_dict({k: v for k, v in ckpt.items() if k != "schema_version"})
        assert tr.update == 1
        _check_refusals(tr, ckpt, path, [
            (lambda c: c.pop("optimizer"), r"optimizer: missing \(expected an optimiser state\)"),
            (lambda c: c["ret_norm"].update(var=np.zeros(3)), r"ret_norm\.var: expected shape"),
            (lambda c: c["obs_norm"]["mean"].__setitem__(0, np.inf), r"obs_norm\.mean: holds NaN"),
            (lambda c: c["model"][_first_weight(c["model"])].view(-1).__setitem__(0, np.nan),
             r"model\.\S+: holds NaN/Inf"),
            (lambda c: c.update(schema_version=SCHEMA_VERSION + 1), r"is newer than"),
        ])  # fmt: skip
    finally:
        opened.close()
