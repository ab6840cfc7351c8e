"""AR(1) (discretised Ornstein-Uhlenbeck) exploration noise: its statistics, its log-probs, and
its use by the trainer (ndp.policies.distributions.AR1SubActionGaussian)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy.stats import multivariate_normal

from ndp.policies.config import PolicyConfig
from ndp.policies.distributions import AR1SubActionGaussian, SubActionGaussian, correlate


def _chain(rho: float, decisions: int, k: int = 5, batch: int = 4000, std: float = 0.5):
    """Noise of ``decisions`` consecutive decisions, the carry continued as the trainer does."""
    gen = torch.Generator().manual_seed(0)
    mean = torch.zeros(batch, k, 2)
    log_std = torch.full((2,), math.log(std))
    carry = torch.randn(batch, 2, generator=gen)
    out = []
    for _ in range(decisions):
        d = AR1SubActionGaussian(mean, log_std, carry, rho)
        z = d.sample(gen)
        out.append(z)
        carry = d.last_noise(z)
    return torch.cat(out, dim=1).numpy()  # [batch, decisions * k, 2]


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.8, 0.95])
def test_noise_is_stationary_with_geometric_autocorrelation_across_decisions(rho):
    x = _chain(rho, decisions=4)  # 20 env steps: within and across decisions
    assert np.abs(x.mean()) < 0.01
    np.testing.assert_allclose(x.std(axis=0), 0.5, rtol=0.05)  # the std at every step
    for lag in (1, 2, 5, 7):  # lag 5, 7 cross a decision boundary
        a, b = x[:, :-lag].reshape(-1), x[:, lag:].reshape(-1)
        corr = float(np.corrcoef(a, b)[0, 1])
        assert corr == pytest.approx(rho**lag, abs=0.02), lag


def test_log_prob_is_the_conditional_joint_density():
    """Summed over the k sub-steps, the per-sub-step log-probs are the joint Gaussian density of
    the decision given the carry: mean rho^(j+1) std carry, covariance std^2 (rho^|i-j| -
    rho^(i+j+2)) per action dimension."""
    k, rho, std = 5, 0.7, 0.3
    gen = torch.Generator().manual_seed(1)
    mean = torch.randn(3, k, 2, generator=gen, dtype=torch.float64)
    log_std = torch.full((2,), math.log(std), dtype=torch.float64)
    carry = torch.randn(3, 2, generator=gen, dtype=torch.float64)
    d = AR1SubActionGaussian(mean, log_std, carry, rho)
    z = d.sample(gen)
    got = d.log_prob(z).sum(-1).numpy()
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    cov = std**2 * (rho ** np.abs(i - j) - rho ** (i + j + 2))
    for b in range(3):
        want = 0.0
        for a in range(2):
            mu = mean[b, :, a].numpy() + std * rho ** (np.arange(k) + 1) * carry[b, a].item()
            want += multivariate_normal(mu, cov).logpdf(z[b, :, a].numpy())
        assert got[b] == pytest.approx(want, rel=1e-9)


def test_rho_zero_is_the_white_gaussian_and_gradients_reach_the_mean():
    mean = torch.randn(2, 5, 3, requires_grad=True)
    log_std = torch.zeros(3, requires_grad=True)
    white = SubActionGaussian(mean, log_std)
    z = white.sample()
    ar = correlate(white, torch.randn(2, 3), 0.0)
    torch.testing.assert_close(ar.log_prob(z), white.log_prob(z))
    torch.testing.assert_close(ar.entropy(), white.entropy())
    ar.log_prob(z).sum().backward()
    assert mean.grad is not None and float(mean.grad.abs().sum()) > 0


def test_ar1_is_refused_where_it_does_not_apply():
    with pytest.raises(ValueError, match="noise: 'ar1' needs a Gaussian around each sub-action"):
        PolicyConfig(head="hold", k=5, noise="ar1")
    with pytest.raises(ValueError, match="noise_corr: expected a number in \\[0, 1\\)"):
        PolicyConfig(noise="ar1", noise_corr=1.0)
    with pytest.raises(ValueError, match="noise: expected one of white, ar1"):
        PolicyConfig(noise="pink")
    # an option nothing reads is refused, not ignored (--noise white --noise-corr 0.5)
    with pytest.raises(ValueError, match=r"^noise_corr: only 'ar1' noise reads it"):
        PolicyConfig(noise="white", noise_corr=0.5)
    assert PolicyConfig(noise="white").noise_corr == 0.8  # the default stays accepted


def test_noise_corr_without_ar1_is_refused_on_the_command_line(capsys):
    from ndp.cli import main

    code = main(["rl", "train", "--task", "point-mass", "--algo", "ppo", "--noise-corr", "0.5",
                 "--steps", "64", "--run-dir", "/nonexistent/never-created"])  # fmt: skip
    assert code != 0
    err = capsys.readouterr().err
    assert "noise_corr: only 'ar1' noise reads it" in err and "Traceback" not in err


@pytest.mark.parametrize("algo", ["ppo", "ppo-multi", "ndp"])
def test_trainer_with_ar1_noise_has_consistent_log_probs(tmp_path, algo):
    """A short run with --noise ar1 trains; before the first update the update's recomputed
    log-probs equal the rollout's (the carry is stored with each decision)."""
    from ndp.rl.config import TrainConfig
    from ndp.rl.run import open_run

    cfg = TrainConfig(
        task="point-mass", algo=algo, steps=800, num_envs=2, vector="sync", seed=0,
        run_dir=str(tmp_path / "r"), progress=False, tensorboard=False, eval_every=0,
        policy=PolicyConfig(noise="ar1", noise_corr=0.9),
    )  # fmt: skip
    opened = open_run(cfg)
    tr = opened.learner
    try:
        batch = tr.collect()
        assert batch["carry"] is not None and batch["carry"].shape[1] == tr.spec.action_dim
        dist, _ = tr.model.distribution(batch["obs"], batch["y0"], batch["dy0"])
        again = tr._explore(dist, batch["carry"]).log_prob(batch["z"])
        torch.testing.assert_close(again, batch["logp"], atol=2e-5, rtol=1e-5)
        tr.learn(batch)
    finally:
        opened.close()
