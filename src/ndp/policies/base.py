"""The action-head base class and the head registry: what every head (``ndp.policies.heads``,
``ndp.policies.dyne``, ``ndp.policies.squashed``, a method's own) implements and registers
with. Their own module so that heads defined elsewhere need not import ``ndp.policies.heads``
(which imports them back, so that importing it registers every built-in head)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import torch
from torch import nn

from ndp.policies.distributions import PolicyDistribution

if TYPE_CHECKING:
    from ndp.policies.config import PolicyConfig
    from ndp.schema import TaskSchema

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


HEAD_BUILDERS: dict[str, HeadBuilder] = {}
"""Head name -> ``build(policy_cfg, spec) -> ActionHead`` (see :func:`register_head`)."""
SINGLE_STEP_HEADS: set[str] = set()
"""Heads that run one action per decision (k = 1)."""


HeadBuilder = Callable[["PolicyConfig", "TaskSchema"], "ActionHead"]
"""``build(resolved policy config, task schema) -> ActionHead`` (:func:`register_head`)."""


def decision_k(cfg: PolicyConfig) -> int:
    """``cfg.k`` of a resolved policy config (sub-steps per decision).

    Raises:
        ValueError: ``k`` is still None (the config was not resolved:
            ``ndp.rl.config.resolve_config`` or ``PolicyConfig.with_defaults`` set it).
    """
    if cfg.k is None:
        raise ValueError("policy config: k must be resolved (see ndp.rl.config.resolve_config)")
    return cfg.k


def register_head(
    name: str, single_step: bool = False
) -> Callable[
    [HeadBuilder],
    HeadBuilder,
]:
    """Register an action head builder under ``name`` (a decorator).

    Args:
        name: the ``PolicyConfig.head`` value that selects it.
        single_step: the head emits one action per decision (k is forced to 1).
    """

    def deco(
        fn: HeadBuilder,
    ) -> HeadBuilder:
        if name in HEAD_BUILDERS:
            raise ValueError(f"name: head {name!r} is already registered")
        HEAD_BUILDERS[name] = fn
        if single_step:
            SINGLE_STEP_HEADS.add(name)
        return fn

    return deco
