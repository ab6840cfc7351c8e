"""TD3's pure functions (Fujimoto, van Hoof, Meger, ICML 2018), on a batch of B decisions of
P bounded action parameters in [-1, 1] (P = k A; k = 1: one action of A values). No state, no
randomness: a noise tensor is drawn by the caller and passed in.
"""

from __future__ import annotations

import torch


def exploration_action(p: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
    """Exploration: ``clip(p + noise, -1, 1)`` [E, P] of the actor's bounded action p [E, P]
    and a Gaussian draw ``noise`` [E, P] (std ``expl_noise``)."""
    return (p + noise).clamp(-1.0, 1.0)


def smoothed_target_action(p_next: torch.Tensor, noise: torch.Tensor, clip: float) -> torch.Tensor:
    """Target policy smoothing: ``clip(p' + clip(noise, -c, c), -1, 1)`` [B, P] of the target
    actor's bounded action p' [B, P] at the next state and a Gaussian draw ``noise`` [B, P]
    (std ``target_noise``), c = ``clip``."""
    return (p_next + noise.clamp(-clip, clip)).clamp(-1.0, 1.0)


def td3_target(
    ret: torch.Tensor, discount: torch.Tensor, q1_next: torch.Tensor, q2_next: torch.Tensor
) -> torch.Tensor:
    """Clipped double-Q target ``y = R + w min(Q1'(s', a~), Q2'(s', a~))`` [B]: the chunk's
    discounted return R [B] (one reward at k = 1), the bootstrap weight w [B] (gamma^n, 0 at a
    terminal state) and the target critics at the smoothed target action [B]."""
    return ret + discount * torch.minimum(q1_next, q2_next)


def critic_loss(q1: torch.Tensor, q2: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """``mse(Q1, y) + mse(Q2, y)`` (scalar) of both critics [B] against the target [B] (the
    paper's and SB3's sum of the two mean squared errors)."""
    return ((q1 - target) ** 2).mean() + ((q2 - target) ** 2).mean()


def actor_loss(q1_pi: torch.Tensor) -> torch.Tensor:
    """Deterministic policy gradient loss ``-mean Q1(s, pi(s))`` (scalar) of the first critic
    at the actor's action [B]."""
    return -q1_pi.mean()


def actor_update_due(critic_steps: int, policy_delay: int) -> bool:
    """Whether the actor and the targets update after the ``critic_steps``-th critic step
    (counted from 1): every ``policy_delay``-th one (SB3: ``n_updates % policy_delay == 0``)."""
    return critic_steps % policy_delay == 0
