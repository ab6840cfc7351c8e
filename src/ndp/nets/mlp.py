"""Multi-layer perceptron with orthogonal initialisation.

Used by the RL actor-critic (hidden [100, 100], tanh) and by the imitation-learning head that maps
CNN features to DMP parameters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import nn

_ACTIVATIONS: dict[str, type[nn.Module]] = {
    "tanh": nn.Tanh,
    "relu": nn.ReLU,
    "elu": nn.ELU,
    "gelu": nn.GELU,
    "silu": nn.SiLU,
    "identity": nn.Identity,
}


def activation_layer(name: str) -> nn.Module:
    """Return a fresh activation module by name.

    Args:
        name: one of ``tanh``, ``relu``, ``elu``, ``gelu``, ``silu``, ``identity``.

    Raises:
        ValueError: for an unknown name.
    """
    try:
        return _ACTIVATIONS[name.lower()]()
    except KeyError:
        raise ValueError(
            f"unknown activation {name!r}; choose one of {sorted(_ACTIVATIONS)}"
        ) from None


def _gain(activation: str) -> float:
    name = activation.lower()
    if name == "tanh":
        return nn.init.calculate_gain("tanh")
    if name in ("relu", "elu", "gelu", "silu"):
        return math.sqrt(2.0)
    return 1.0


class MLP(nn.Module):
    """Fully connected network ``in_dim -> hidden[0] -> ... -> out_dim``.

    Hidden layers use ``activation``; the output layer is linear. Weights are orthogonally
    initialised (gain suited to the activation for hidden layers, ``out_gain`` for the output
    layer) and biases are zero.

    Args:
        in_dim: input features.
        hidden: widths of the hidden layers (may be empty: a single linear layer).
        out_dim: output features.
        activation: hidden-layer non-linearity name (see :func:`activation_layer`).
        out_gain: orthogonal-init gain of the output layer (e.g. 0.01 for a policy mean head).
        hidden_gain: orthogonal-init gain of the hidden layers; None: the activation's.
        layer_norm: put a LayerNorm (learned scale and shift) between each hidden layer's linear
            map and its activation (the critics of RLPD / BRO); False keeps the plain MLP and
            its parameter names.

    Shapes:
        forward: ``x`` [B, in_dim] -> [B, out_dim] (any leading batch dims are allowed).
    """

    def __init__(
        self,
        in_dim: int,
        hidden: Sequence[int],
        out_dim: int,
        activation: str = "tanh",
        out_gain: float = 1.0,
        hidden_gain: float | None = None,
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        if in_dim <= 0 or out_dim <= 0 or any(h <= 0 for h in hidden):
            raise ValueError(
                f"MLP sizes must be positive: in_dim={in_dim}, hidden={list(hidden)}, "
                f"out_dim={out_dim}"
            )
        self.in_dim = int(in_dim)
        self.out_dim = int(out_dim)
        self.hidden = tuple(int(h) for h in hidden)
        self.activation = activation
        self.layer_norm = bool(layer_norm)
        gain = _gain(activation) if hidden_gain is None else float(hidden_gain)
        layers: list[nn.Module] = []
        prev = self.in_dim
        for width in self.hidden:
            lin = nn.Linear(prev, width)
            nn.init.orthogonal_(lin.weight, gain=gain)
            nn.init.zeros_(lin.bias)
            norm = [nn.LayerNorm(width)] if self.layer_norm else []
            layers += [lin, *norm, activation_layer(activation)]
            prev = width
        out = nn.Linear(prev, self.out_dim)
        nn.init.orthogonal_(out.weight, gain=out_gain)
        nn.init.zeros_(out.bias)
        layers.append(out)
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Map ``x`` [B, in_dim] to [B, out_dim]."""
        out: torch.Tensor = self.net(x)
        return out
