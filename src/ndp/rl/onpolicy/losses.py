"""PPO loss pieces over chunked decisions (pure functions; shapes stated).

Per-sub-action log-probs are [M, k], each with its sub-step's advantage. With parameter-space
exploration there is one log-prob per decision [M, 1]; the trainer then passes the decision's own
GAE advantage ``A[:, :1]`` (it carries every reward of the decision, (gamma lambda)^l weighted)
and ``mask[:, :1]``, so each decision is one clipped term. Every mean is over executed entries.
"""

from __future__ import annotations

import math
from typing import Any

import torch


def masked_mean(x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean of ``x`` over entries where ``mask`` is 1 (``x`` broadcastable to ``mask``)."""
    x = x.expand_as(mask)
    return (x * mask).sum() / mask.sum().clamp_min(1.0)


def policy_loss(
    new_logp: torch.Tensor,
    old_logp: torch.Tensor,
    adv: torch.Tensor,
    mask: torch.Tensor,
    clip: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Clipped surrogate loss.

    Args:
        new_logp: [M, L] log-probs under the current policy (L = k, or 1 per decision).
        old_logp: [M, L] log-probs at collection time.
        adv: [M, L] advantages (L = k, or 1 per decision).
        mask: [M, L] executed sub-steps (or decisions).
        clip: epsilon.

    Returns:
        ``(loss, approx_kl, clipfrac)``: ``-mean(min(rho A, clip(rho, 1-eps, 1+eps) A))``, the
        estimator ``mean((rho - 1) - log rho)`` and the fraction of clipped ratios.
    """
    logratio = (new_logp - old_logp).expand_as(adv)
    ratio = logratio.exp()
    surr = torch.minimum(ratio * adv, ratio.clamp(1.0 - clip, 1.0 + clip) * adv)
    loss = -masked_mean(surr, mask)
    with torch.no_grad():
        approx_kl = masked_mean((ratio - 1.0) - logratio, mask)
        clipfrac = masked_mean(((ratio - 1.0).abs() > clip).float(), mask)
    return loss, approx_kl, clipfrac


def release_first_held(z: torch.Tensor, logp: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The 2021 release's pairing under first-held execution, applied to a rollout decision.

    The release ran only sub-action 0 of a decision (held k steps) and stored, at every sub-step
    j, that executed sample a_0 with its log-prob under sub-step 0's distribution; its update
    scored the stored a_0 under sub-step j's distribution. Storing ``z`` and ``logp`` as returned
    here makes :func:`policy_loss` (and the fused Gaussian loss) compute the release's ratio
    ``pi_j,new(a_0) / pi_0,old(a_0)`` at sub-step j.

    Args:
        z: [B, k, A] the decision's samples (sub-step j's own a_j in row j).
        logp: [B, k] their log-probs at collection time, log pi_j,old(a_j).

    Returns:
        ``(z', logp')``: z' [B, k, A] with every row the executed a_0; logp' [B, k] with every
        entry log pi_0,old(a_0). Fresh tensors (the inputs are not changed).
    """
    if z.dim() != 3 or logp.dim() != 2 or logp.shape != z.shape[:2]:
        raise ValueError(
            f"z, logp: expected shapes [B, k, A] and [B, k], got {tuple(z.shape)} and "
            f"{tuple(logp.shape)}"
        )
    return z[:, :1].expand_as(z).clone(), logp[:, :1].expand_as(logp).clone()


def value_loss(
    values: torch.Tensor,
    old_values: torch.Tensor,
    returns: torch.Tensor,
    mask: torch.Tensor,
    clip: float | None,
) -> torch.Tensor:
    """``0.5 * mean((V - R)^2)`` over executed sub-steps, optionally clipped around the old V.

    Args:
        values: [M, k] current value heads.
        old_values: [M, k] values at collection time.
        returns: [M, k] GAE returns.
        mask: [M, k].
        clip: None, or epsilon: ``max((V - R)^2, (V_old + clip(V - V_old, -eps, eps) - R)^2)``.
    """
    err = (values - returns).pow(2)
    if clip is not None:
        v_clip = old_values + (values - old_values).clamp(-clip, clip)
        err = torch.maximum(err, (v_clip - returns).pow(2))
    return 0.5 * masked_mean(err, mask)


def entropy_mean(entropy: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean entropy [M, L] over executed sub-steps (L = 1: per decision, counted once)."""
    if entropy.shape[1] == 1:
        return masked_mean(entropy, mask[:, :1])
    return masked_mean(entropy, mask)


def normalize_advantages(adv: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """``(A - mean) / (std + 1e-8)`` over executed sub-steps; 0 elsewhere."""
    n = mask.sum().clamp_min(1.0)
    mean = (adv * mask).sum() / n
    var = ((adv - mean).pow(2) * mask).sum() / (n - 1.0).clamp_min(1.0)
    return (adv - mean) / (var.sqrt() + 1e-8) * mask


class _GaussianSurrogate(torch.autograd.Function):
    """Fused clipped surrogate of a diagonal Gaussian (forward and hand-written backward).

    Same value and gradient as ``policy_loss(diag_gaussian_log_prob(z, mean, log_std), ...)``
    (tested against autograd in float64), in one autograd node instead of about twenty: the
    update runs 320 of these per rollout, where the eager per-op overhead dominates.
    """

    @staticmethod
    def forward(
        ctx: Any,
        mean: torch.Tensor,
        log_std: torch.Tensor,
        z: torch.Tensor,
        old_logp: torch.Tensor,
        adv: torch.Tensor,
        mask: torch.Tensor,
        clip: float,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        inv_std = torch.exp(-log_std)
        u = (z - mean) * inv_std  # [M, k, A]
        logp = (-0.5 * u * u - log_std).sum(-1) - u.shape[-1] * _HALF_LOG_2PI  # [M, k]
        logratio = logp - old_logp
        ratio = logratio.exp()
        s1 = ratio * adv
        s2 = ratio.clamp(1.0 - clip, 1.0 + clip) * adv
        n = mask.sum().clamp_min(1.0)
        loss = -(torch.minimum(s1, s2) * mask).sum() / n
        # d loss / d logp: the unclipped branch is the minimum (ties: inside the clip range,
        # where autograd's min + clamp also pass the whole gradient)
        g_logp = -(mask / n) * adv * ratio * (s1 <= s2)
        ctx.save_for_backward(u, inv_std, g_logp)
        ctx.log_std_shape = log_std.shape
        approx_kl = (((ratio - 1.0) - logratio) * mask).sum() / n
        clipfrac = (((ratio - 1.0).abs() > clip).to(mask.dtype) * mask).sum() / n
        ctx.mark_non_differentiable(approx_kl, clipfrac)
        return loss, approx_kl, clipfrac

    @staticmethod
    def backward(
        ctx: Any, g_loss: torch.Tensor, _g_kl: torch.Tensor, _g_cf: torch.Tensor
    ) -> tuple[torch.Tensor | None, ...]:
        u, inv_std, g_logp = ctx.saved_tensors
        g = (g_logp * g_loss).unsqueeze(-1)  # [M, k, 1]
        g_mean = g * u * inv_std  # d logp / d mean = u / std
        g_ls = g * (u * u - 1.0)  # d logp / d log_std = u^2 - 1
        g_log_std = g_ls.sum_to_size(ctx.log_std_shape)
        return g_mean, g_log_std, None, None, None, None, None


_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


def gaussian_policy_loss(
    mean: torch.Tensor,
    log_std: torch.Tensor,
    z: torch.Tensor,
    old_logp: torch.Tensor,
    adv: torch.Tensor,
    mask: torch.Tensor,
    clip: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """:func:`policy_loss` of per-sub-action diagonal Gaussians, fused (one autograd node).

    Args:
        mean: [M, k, A] sub-action means (differentiable).
        log_std: [A] (or broadcastable to ``mean``) log standard deviations (differentiable).
        z: [M, k, A] the rollout's samples.
        old_logp, adv, mask, clip: as for :func:`policy_loss`, per sub-step (L = k; old_logp:
            the samples' log-probs at collection time).

    Returns:
        ``(loss, approx_kl, clipfrac)`` as :func:`policy_loss`.
    """
    apply = _GaussianSurrogate.apply  # untyped in torch's stubs
    out = apply(mean, log_std, z, old_logp, adv, mask, float(clip))  # type: ignore[no-untyped-call]
    loss, approx_kl, clipfrac = out
    return loss, approx_kl, clipfrac
