"""The action-head base class and the head registry: what every head (``ndp.policies.heads``,
``ndp.policies.dyne``, ``ndp.policies.squashed``, a method's own) implements and registers
with. Their own module so that heads defined elsewhere need not import ``ndp.policies.heads``
(which imports them back, so that importing it registers every built-in head)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import torch
from torch import nn

from ndp.policies.distributions import PolicyDistribution

__all__ = ["HEAD_BUILDERS", "SINGLE_STEP_HEADS", "ActionHead", "HeadOutput", "register_head"]


HeadOutput = tuple[PolicyDistribution, dict[str, torch.Tensor]]
"""What :meth:`ActionHead.distribution` returns: the distribution over the decision's k
sub-actions and the head's diagnostics (name -> [B] tensors; empty during updates)."""


class ActionHead(nn.Module):
    """Base class. Subclasses set ``k``, ``action_dim``, ``n_params`` and ``needs_robot_state``."""

    k: int
    action_dim: int
    n_params: int
    needs_robot_state: bool = False

    def distribution(
        self, raw: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> HeadOutput:
        """Map the actor output [B, P] to a distribution over [B, k, A] plus diagnostics."""
        raise NotImplementedError


HEAD_BUILDERS: dict[str, Callable[[Any, Any], ActionHead]] = {}
"""Head name -> ``build(policy_cfg, spec) -> ActionHead`` (see :func:`register_head`)."""
SINGLE_STEP_HEADS: set[str] = set()
"""Heads that run one action per decision (k = 1)."""


def register_head(
    name: str, single_step: bool = False
) -> Callable[[Callable[[Any, Any], ActionHead]], Callable[[Any, Any], ActionHead]]:
    """Register an action head builder under ``name`` (a decorator).

    Args:
        name: the ``PolicyConfig.head`` value that selects it.
        single_step: the head emits one action per decision (k is forced to 1).
    """

    def deco(fn: Callable[[Any, Any], ActionHead]) -> Callable[[Any, Any], ActionHead]:
        if name in HEAD_BUILDERS:
            raise ValueError(f"name: head {name!r} is already registered")
        HEAD_BUILDERS[name] = fn
        if single_step:
            SINGLE_STEP_HEADS.add(name)
        return fn

    return deco
