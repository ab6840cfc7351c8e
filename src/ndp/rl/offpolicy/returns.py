"""The k-step return of a decision and the weight of its bootstrap, shared by the off-policy
learners (the loop computes them at insertion; SAC and TD3 targets read them)."""

from __future__ import annotations

import torch


def chunk_return(
    rewards: torch.Tensor, mask: torch.Tensor, gamma: float
) -> tuple[torch.Tensor, torch.Tensor]:
    """The discounted return of a decision's executed sub-steps, and their count.

    Args:
        rewards: [B, k] sub-step rewards.
        mask: [B, k] 1 for executed sub-steps (the rest after an episode's end).
        gamma: discount per env step.

    Returns:
        ``R`` [B] = sum_j gamma^j r_j m_j, and ``n`` [B] = sum_j m_j.
    """
    k = rewards.shape[1]
    powers = gamma ** torch.arange(k, dtype=rewards.dtype, device=rewards.device)
    return (rewards * mask * powers).sum(1), mask.sum(1)


def bootstrap_discount(n: torch.Tensor, terminal: torch.Tensor, gamma: float) -> torch.Tensor:
    """``gamma^n (1 - terminal)`` [B]: the weight of the next state's value in the target."""
    return gamma**n * (1.0 - terminal)
