"""SAC's losses and targets as pure functions (shapes: B decisions, k sub-steps).

With a chunk of k actions executed open-loop from state s_t, the critic scores the chunk,
Q(s_t, a_t..a_{t+k-1}), and is trained on the k-step discounted return (Q-chunking)::

    R_t = sum_{j < n} gamma^j r_{t+j}                    (n <= k sub-steps executed)
    y_t = R_t + gamma^n (1 - terminal) [ min_i Q'_i(s_{t+n}, c') - alpha log pi(c' | s_{t+n}) ]

with c' ~ pi(. | s_{t+n}) and the targets Q'_i the critics' slow copies. A time-limit end
bootstraps (terminal = 0; s_{t+n} the final observation), a true termination does not. At
k = 1 this is SAC's one-step target. The actor minimises ``alpha log pi - min_i Q_i``; the
temperature minimises ``-log(alpha) (log pi + target_entropy)``.
"""

from __future__ import annotations

import torch

from ndp.rl.offpolicy.returns import bootstrap_discount as bootstrap_discount  # re-exported:
from ndp.rl.offpolicy.returns import chunk_return as chunk_return  # the shared loop's
from ndp.rl.optim import soft_update

__all__ = [
    "actor_loss",
    "alpha_loss",
    "bootstrap_discount",
    "chunk_return",
    "critic_loss",
    "critic_target",
    "soft_update",
]


def critic_target(
    ret: torch.Tensor,
    discount: torch.Tensor,
    q1_next: torch.Tensor,
    q2_next: torch.Tensor,
    logp_next: torch.Tensor,
    alpha: torch.Tensor | float,
) -> torch.Tensor:
    """The soft target ``y`` [B] (no gradient) from the chunk return [B], the bootstrap weight
    [B], the target critics' values [B] of a fresh next chunk and its log-prob [B]."""
    with torch.no_grad():
        soft = torch.minimum(q1_next, q2_next) - alpha * logp_next
        return ret + discount * soft


def critic_loss(q1: torch.Tensor, q2: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """``0.5 (mse(q1, y) + mse(q2, y))``: both critics [B] against the target [B]."""
    return 0.5 * (((q1 - target) ** 2).mean() + ((q2 - target) ** 2).mean())


def actor_loss(
    logp: torch.Tensor, q1_pi: torch.Tensor, q2_pi: torch.Tensor, alpha: torch.Tensor | float
) -> torch.Tensor:
    """``mean(alpha log pi - min(q1, q2))`` over a reparameterised sample's log-prob [B] and
    the critics' values of it [B]."""
    return (alpha * logp - torch.minimum(q1_pi, q2_pi)).mean()


def alpha_loss(log_alpha: torch.Tensor, logp: torch.Tensor, target_entropy: float) -> torch.Tensor:
    """The temperature's loss ``-mean(log_alpha (log pi + target_entropy))`` (log-probs [B]
    detached)."""
    return -(log_alpha * (logp.detach() + target_entropy)).mean()
