"""The 2021 release's first-held PPO ratio (``--first-held-ratio release``) against ours."""

from __future__ import annotations

import math

import pytest
import torch

from ndp.policies import NDPHeadConfig, PolicyConfig
from ndp.policies.distributions import SubActionGaussian
from ndp.rl.config import PPOConfig, TrainConfig
from ndp.rl.onpolicy.losses import release_first_held
from ndp.rl.run import open_run


def _normal_logpdf(x: torch.Tensor, mean: torch.Tensor, std: torch.Tensor) -> torch.Tensor:
    """Sum over the last axis of log N(x; mean, std^2), written out (no library density)."""
    var = std**2
    return (-((x - mean) ** 2) / (2 * var) - torch.log(std) - 0.5 * math.log(2 * math.pi)).sum(-1)


def _batch() -> tuple[SubActionGaussian, SubActionGaussian, torch.Tensor]:
    g = torch.Generator().manual_seed(0)
    B, k, A = 6, 5, 3
    log_std = torch.tensor([-0.3, 0.1, -0.7], dtype=torch.float64)
    old = SubActionGaussian(torch.randn(B, k, A, generator=g, dtype=torch.float64), log_std)
    new = SubActionGaussian(
        old.mean + 0.3 * torch.randn(B, k, A, generator=g, dtype=torch.float64), log_std + 0.05
    )
    z = old.sample(g)
    return old, new, z


def test_release_ratio_is_the_release_formula_and_differs_from_ours():
    """On a constructed batch: the release pairing gives pi_j,new(a_0) / pi_0,old(a_0) at every
    sub-step j (checked against the density written out), ours pi_j,new(a_j) / pi_j,old(a_j);
    the two differ at every sub-step but the first."""
    old, new, z = _batch()
    logp_old = old.log_prob(z)
    own = torch.exp(new.log_prob(z) - logp_old)
    z_rel, logp_rel = release_first_held(z, logp_old)
    release = torch.exp(new.log_prob(z_rel) - logp_rel)

    a0 = z[:, 0]  # the executed sample [B, A]
    std_new, std_old = new.log_std.exp(), old.log_std.exp()
    for j in range(z.shape[1]):
        log_new = _normal_logpdf(a0, new.mean[:, j], std_new)
        want = torch.exp(log_new - _normal_logpdf(a0, old.mean[:, 0], std_old))
        torch.testing.assert_close(release[:, j], want)
        want_own = torch.exp(
            _normal_logpdf(z[:, j], new.mean[:, j], std_new)
            - _normal_logpdf(z[:, j], old.mean[:, j], std_old)
        )
        torch.testing.assert_close(own[:, j], want_own)
    torch.testing.assert_close(release[:, 0], own[:, 0])  # sub-step 0: the same pair
    assert bool(((release[:, 1:] - own[:, 1:]).abs() > 1e-3).all())
    # the inputs are left as they were
    assert not torch.equal(z[:, 1], z[:, 0])


def test_release_first_held_refuses_bad_shapes():
    with pytest.raises(ValueError, match=r"z, logp: expected shapes \[B, k, A\] and \[B, k\]"):
        release_first_held(torch.zeros(2, 5, 3), torch.zeros(2, 4))


def _cfg(tmp_path, **kw):
    base = {
        "task": "point-mass",
        "algo": "ppo-multi",
        "steps": 1000,
        "num_envs": 2,
        "run_dir": str(tmp_path / "run"),
        "progress": False,
        "tensorboard": False,
        "vector": "sync",
        "execution": "first-held",
        "steps_per_update": 500,
        "ppo": PPOConfig(minibatches=2, lr=1e-3),
    }
    return TrainConfig(**{**base, **kw})


@pytest.mark.parametrize("algo", ["ppo-multi", "ndp"])
def test_trainer_stores_the_executed_sample_at_every_sub_step(tmp_path, algo):
    """With the option, the rollout stores a_0 and log pi_0,old(a_0) at every sub-step, so the
    update's ratio is the release's; the executed actions are unchanged (sub-action 0)."""
    opened = open_run(_cfg(tmp_path, algo=algo, first_held_ratio="release"))
    try:
        batch = opened.learner.collect()
        opened.learner.learn(batch)
    finally:
        opened.close()
    z, logp = batch["z"], batch["logp"]
    assert torch.equal(z, z[:, :1].expand_as(z))
    assert torch.equal(logp, logp[:, :1].expand_as(logp))


def test_own_ratio_keeps_each_sub_steps_sample(tmp_path):
    opened = open_run(_cfg(tmp_path))
    try:
        batch = opened.learner.collect()
    finally:
        opened.close()
    assert not torch.equal(batch["z"][:, 1], batch["z"][:, 0])


def test_release_ratio_is_refused_where_it_means_nothing(tmp_path):
    with pytest.raises(ValueError, match=r"first_held_ratio: 'release' .* execution='first-held'"):
        TrainConfig(task="point-mass", algo="ppo-multi", first_held_ratio="release")
    with pytest.raises(ValueError, match="first_held_ratio: expected one of own, release"):
        TrainConfig(task="point-mass", execution="first-held", first_held_ratio="first")
    param = PolicyConfig(ndp=NDPHeadConfig(param_noise=True))
    with pytest.raises(ValueError, match="first_held_ratio: 'release' pairs sub-step"):
        open_run(_cfg(tmp_path, algo="ndp", first_held_ratio="release", policy=param))
