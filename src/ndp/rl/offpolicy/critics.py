"""The off-policy learners' twin critics."""

from __future__ import annotations

import torch
from torch import nn

from ndp.nets.mlp import MLP


class TwinQ(nn.Module):
    """Two critics ``Q_i(s, c)`` [B] of a state [B, O] and its action input [B, C]
    (``layer_norm``: LayerNorm after each hidden linear map, :class:`ndp.nets.mlp.MLP`)."""

    def __init__(
        self,
        obs_dim: int,
        in_dim: int,
        hidden: tuple[int, ...],
        activation: str,
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        self.q1 = MLP(obs_dim + in_dim, hidden, 1, activation, layer_norm=layer_norm)
        self.q2 = MLP(obs_dim + in_dim, hidden, 1, activation, layer_norm=layer_norm)

    def forward(self, obs: torch.Tensor, c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.cat([obs, c], dim=-1)
        return self.q1(x)[:, 0], self.q2(x)[:, 0]
