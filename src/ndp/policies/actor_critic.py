"""One actor-critic for PPO, PPO-multi and NDP: MLP actor + action head, MLP critic with k heads."""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch
from torch import nn
from torch.nn import functional as F

from ndp.dmp.integrate import recording
from ndp.nets.mlp import MLP
from ndp.policies.base import ActionHead, HeadOutput
from ndp.policies.config import PolicyConfig
from ndp.policies.heads import build_head

if TYPE_CHECKING:
    from ndp.schema import TaskSchema


class ActorCritic(nn.Module):
    """Actor ``obs -> raw head parameters`` followed by an action head; critic ``obs -> k values``.

    The critic's k outputs are k value heads on a shared trunk: head j estimates the value of
    the state after j sub-steps of the decision (sub-step j's value in GAE).

    Args:
        obs_dim: observation size O.
        head: the action head (defines k, A and the number of raw parameters P).
        hidden: hidden widths of both MLPs.
        activation: hidden non-linearity.
        hidden_gain: orthogonal-init gain of the hidden layers (None: the activation's).

    Shapes:
        obs [B, O]; y0, dy0 [B, D] (physical robot state, NDP only); values [B, k].
    """

    def __init__(
        self,
        obs_dim: int,
        head: ActionHead,
        hidden: tuple[int, ...] = (100, 100),
        activation: str = "tanh",
        hidden_gain: float | None = None,
    ) -> None:
        super().__init__()
        self.obs_dim = int(obs_dim)
        self.head = head
        self.k = head.k
        self.actor = MLP(
            obs_dim, hidden, head.n_params, activation, out_gain=0.01, hidden_gain=hidden_gain
        )
        self.critic = MLP(
            obs_dim, hidden, head.k, activation, out_gain=1.0, hidden_gain=hidden_gain
        )

    def distribution(
        self, obs: torch.Tensor, y0: torch.Tensor | None = None, dy0: torch.Tensor | None = None
    ) -> HeadOutput:
        """Exploration distribution over the decision's k sub-actions, plus head diagnostics."""
        return self.head.distribution(mlp_forward(self.actor, obs), y0, dy0)

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        """k value estimates [B, k] (one per sub-step of the decision)."""
        return mlp_forward(self.critic, obs)


_ACTIVATIONS = {"tanh": torch.tanh, "relu": torch.relu}
"""The hidden activations :func:`mlp_forward` applies as functions (what their modules call)."""


def mlp_forward(mlp: MLP, x: torch.Tensor) -> torch.Tensor:
    """``mlp(x)``; without autograd (rollouts), a plain MLP's layers as the functions their
    modules call (``F.linear``, the activation), without the per-module call overhead: the
    same values."""
    act = _ACTIVATIONS.get(mlp.activation.lower()) if isinstance(mlp, MLP) else None
    if act is None or mlp.layer_norm or torch.is_grad_enabled() or recording():
        out: torch.Tensor = mlp(x)
        return out
    for m in mlp.net._modules.values():
        if type(m) is nn.Linear:
            p = m._parameters
            w = p["weight"]
            assert w is not None  # (an nn.Linear's)
            x = F.linear(x, w, p["bias"])
        else:
            x = act(x)
    return x


def build_actor_critic(obs_dim: int, spec: TaskSchema, cfg: PolicyConfig) -> ActorCritic:
    """Build the actor-critic for a task spec and a resolved policy config (a field left at
    None gets the PPO family's value: :meth:`PolicyConfig.with_defaults`)."""
    cfg = cfg.with_defaults()
    assert cfg.hidden is not None and cfg.activation is not None
    return ActorCritic(
        obs_dim, build_head(cfg, spec), tuple(cfg.hidden), cfg.activation, cfg.hidden_gain
    )
