"""PPO loss pieces: clipped surrogate, value loss, masking, per-decision log-probs."""

from __future__ import annotations

import math

import pytest
import torch

from ndp.rl.onpolicy.losses import entropy_mean, normalize_advantages, policy_loss, value_loss


def test_policy_loss_clips_positive_and_negative_advantages():
    old = torch.zeros(1, 2)
    new = torch.log(torch.tensor([[1.5, 0.5]]))  # ratios 1.5 and 0.5
    adv = torch.tensor([[2.0, -1.0]])
    mask = torch.ones(1, 2)
    loss, kl, cf = policy_loss(new, old, adv, mask, clip=0.1)
    # min(1.5*2, 1.1*2) = 2.2 ; min(0.5*-1, 0.9*-1) = -0.9 ; loss = -(2.2 - 0.9) / 2
    assert math.isclose(float(loss), -(2.2 - 0.9) / 2, rel_tol=1e-6)
    assert float(cf) == 1.0
    expected_kl = ((0.5 - math.log(1.5)) + (-0.5 - math.log(0.5))) / 2
    assert math.isclose(float(kl), expected_kl, rel_tol=1e-6)


def test_policy_loss_masks_unexecuted_substeps():
    new = torch.tensor([[0.0, 5.0]])
    old = torch.zeros(1, 2)
    adv = torch.tensor([[1.0, 100.0]])
    loss, _, cf = policy_loss(new, old, adv, torch.tensor([[1.0, 0.0]]), clip=0.2)
    assert math.isclose(float(loss), -1.0, rel_tol=1e-6)
    assert float(cf) == 0.0


def test_policy_loss_per_decision_logprob_broadcasts_over_substeps():
    new = torch.log(torch.tensor([[1.05]]))  # one log-prob for the decision
    old = torch.zeros(1, 1)
    adv = torch.tensor([[1.0, 2.0, 3.0]])
    loss, _, _ = policy_loss(new, old, adv, torch.ones(1, 3), clip=0.1)
    assert math.isclose(float(loss), -1.05 * 2.0, rel_tol=1e-6)


def test_policy_loss_gradient_zero_when_clipped():
    new = torch.log(torch.tensor([[1.5]])).requires_grad_()
    loss, _, _ = policy_loss(new, torch.zeros(1, 1), torch.tensor([[1.0]]), torch.ones(1, 1), 0.1)
    loss.backward()
    assert float(new.grad) == 0.0


def test_value_loss_unclipped_and_clipped():
    v = torch.tensor([[1.0, 3.0]])
    old = torch.tensor([[0.0, 0.0]])
    ret = torch.tensor([[0.0, 0.0]])
    mask = torch.ones(1, 2)
    assert math.isclose(float(value_loss(v, old, ret, mask, None)), 0.5 * (1 + 9) / 2)
    # clipped at 0.5: V_clip = 0.5 -> err max((1)^2, 0.25) = 1 ; max(9, 0.25) = 9 -> same
    assert math.isclose(float(value_loss(v, old, ret, mask, 0.5)), 0.5 * (1 + 9) / 2)
    # returns far away: clipped prediction is worse -> it dominates
    ret2 = torch.tensor([[4.0, 4.0]])
    # err: (1-4)^2=9 vs (0.5-4)^2=12.25 ; (3-4)^2=1 vs (0.5-4)^2=12.25
    assert math.isclose(float(value_loss(v, old, ret2, mask, 0.5)), 0.5 * (12.25 + 12.25) / 2)
    assert math.isclose(float(value_loss(v, old, ret2, torch.tensor([[1.0, 0.0]]), None)), 0.5 * 9)


def test_entropy_mean_per_decision_counts_decisions_once():
    ent = torch.tensor([[1.0], [3.0]])
    mask = torch.tensor([[1.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    assert float(entropy_mean(ent, mask)) == 2.0
    ent_k = torch.tensor([[1.0, 2.0, 9.0], [3.0, 9.0, 9.0]])
    assert float(entropy_mean(ent_k, mask)) == 2.0


def test_normalize_advantages_over_executed_only():
    adv = torch.tensor([[1.0, 3.0, 100.0]])
    mask = torch.tensor([[1.0, 1.0, 0.0]])
    out = normalize_advantages(adv, mask)
    assert float(out[0, 2]) == 0.0
    assert math.isclose(float(out[0, 0]), -float(out[0, 1]), rel_tol=1e-6)
    assert math.isclose(float(out[0, 1]), 1.0 / math.sqrt(2.0), rel_tol=1e-5)  # unbiased std


@pytest.mark.parametrize("clip", [0.1, 0.3])
def test_fused_gaussian_loss_equals_autograd(clip):
    """The fused surrogate has the value, KL, clip fraction and gradients of the composed one
    (float64, ratios spread over both sides of the clip range, masked sub-steps)."""
    from ndp.policies.distributions import diag_gaussian_log_prob
    from ndp.rl.onpolicy.losses import gaussian_policy_loss, policy_loss

    g = torch.Generator().manual_seed(0)
    m_, k, a = 40, 5, 3
    mean = torch.randn(m_, k, a, generator=g, dtype=torch.float64, requires_grad=True)
    log_std = (0.3 * torch.randn(a, generator=g, dtype=torch.float64)).requires_grad_(True)
    z = mean.detach() + torch.randn(m_, k, a, generator=g, dtype=torch.float64)
    old = diag_gaussian_log_prob(
        z,
        mean.detach() + 0.3 * torch.randn(m_, k, a, generator=g, dtype=torch.float64),
        log_std.detach(),
    )
    adv = torch.randn(m_, k, generator=g, dtype=torch.float64)
    mask = (torch.rand(m_, k, generator=g) > 0.2).double()
    ref = policy_loss(diag_gaussian_log_prob(z, mean, log_std), old, adv, mask, clip)
    fused = gaussian_policy_loss(mean, log_std, z, old, adv, mask, clip)
    for r, f in zip(ref, fused, strict=True):
        torch.testing.assert_close(f, r)
    ratio = (diag_gaussian_log_prob(z, mean, log_std) - old).exp()
    assert bool(((ratio - 1).abs() > clip).any()) and bool(((ratio - 1).abs() < clip).any())
    gr = torch.autograd.grad(ref[0], (mean, log_std))
    gf = torch.autograd.grad(fused[0], (mean, log_std))
    for r, f in zip(gr, gf, strict=True):
        torch.testing.assert_close(f, r)
    assert torch.autograd.gradcheck(
        lambda mu, ls: gaussian_policy_loss(mu, ls, z, old, adv, mask, clip)[0], (mean, log_std)
    )


def test_flat_adam_equals_clip_grad_norm_then_adam():
    from torch import nn

    from ndp.rl.optim import FlatAdam

    def net():
        torch.manual_seed(0)
        return nn.Sequential(nn.Linear(5, 7), nn.Tanh(), nn.Linear(7, 3))

    a, b = net(), net()
    ref = torch.optim.Adam(a.parameters(), lr=1e-2, eps=1e-5)
    flat = FlatAdam(b, lr=1e-2, eps=1e-5)
    g = torch.Generator().manual_seed(1)
    for i in range(6):
        x = torch.randn(16, 5, generator=g) * (10.0 if i % 2 else 0.1)  # clipped and not
        for m, opt in ((a, ref), (b, flat)):
            loss = (m(x) ** 2).sum()
            opt.zero_grad()
            loss.backward()
            if opt is ref:
                n_ref = nn.utils.clip_grad_norm_(a.parameters(), 0.5)
                ref.step()
            else:
                n_flat = flat.clip_grad_norm(0.5)
                flat.step()
        torch.testing.assert_close(n_flat, n_ref)
        for pa, pb in zip(a.parameters(), b.parameters(), strict=True):
            torch.testing.assert_close(pb, pa)
    # the module is unchanged from outside: same state_dict keys, parameters are views
    assert list(b.state_dict()) == list(a.state_dict())
    # a per-parameter Adam state (older checkpoints) loads into the flat one
    c = net()
    fc = FlatAdam(c, lr=1e-2, eps=1e-5)
    c.load_state_dict(a.state_dict())
    fc.load_state_dict(ref.state_dict())
    torch.testing.assert_close(
        fc.state_dict()["state"][0]["exp_avg"], flat.state_dict()["state"][0]["exp_avg"]
    )
