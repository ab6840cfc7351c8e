"""The action-head base class: what every head (``ndp.policies.heads``, ``ndp.policies.dyne``,
a method's own) implements. Its own module so that heads defined elsewhere need not import the
head registry (which imports them back to build them)."""

from __future__ import annotations

import torch
from torch import nn

from ndp.policies.distributions import PolicyDistribution

__all__ = ["ActionHead"]


class ActionHead(nn.Module):
    """Base class. Subclasses set ``k``, ``action_dim``, ``n_params`` and ``needs_robot_state``."""

    k: int
    action_dim: int
    n_params: int
    needs_robot_state: bool = False

    def distribution(
        self,
        raw: torch.Tensor,
        y0: torch.Tensor | None = None,
        dy0: torch.Tensor | None = None,
    ) -> tuple[PolicyDistribution, dict[str, torch.Tensor]]:
        """Map the actor output [B, P] to a distribution over [B, k, A] plus diagnostics."""
        raise NotImplementedError
