"""The off-policy learners' twin critics.

:class:`TwinQ` is two :class:`ndp.nets.mlp.MLP` passes (the learners' critics).
:class:`BatchedTwinQ` is the same function with each layer of both critics stacked into one
weight [2, in, out] and evaluated by one ``torch.baddbmm``: its ``state_dict`` is
:class:`TwinQ`'s (``q1.net.*``, ``q2.net.*``, same shapes), so the two load each other's
weights; the numbers agree to float reassociation (tested to 1e-6). It is not the learners'
default: on a CPU core it was no faster (``benchmarks/sac_step.py``,
``docs/results/sac_throughput/sac_step.md``).
"""

from __future__ import annotations

import itertools
from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from ndp.nets.mlp import MLP, activation_layer


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


class BatchedTwinQ(nn.Module):
    """:class:`TwinQ` as an ensemble of two: layer ``j``'s weights of both critics are one
    parameter ``weight{j}`` [2, in, out] (the transposed ``nn.Linear`` weights, stacked) and
    ``bias{j}`` [2, 1, out]; with ``layer_norm`` the hidden layers' LayerNorm scale and shift
    are ``ln_weight{j}``, ``ln_bias{j}`` [2, 1, out]. One ``baddbmm`` per layer serves both
    critics. Its ``state_dict`` holds :class:`TwinQ`'s keys and shapes (converted on save and
    load), so checkpoints of either load into the other; the optimiser's state does not
    carry over (6 tensors here, 12 there for two hidden layers).

    Built with :class:`TwinQ`'s arguments (fresh weights: those of a :class:`TwinQ` built
    with the same global RNG state) or from one by :meth:`from_twin`.
    """

    def __init__(
        self,
        obs_dim: int,
        in_dim: int,
        hidden: tuple[int, ...],
        activation: str,
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        self.hidden = tuple(int(h) for h in hidden)
        self.layer_norm = bool(layer_norm)
        self.act = activation_layer(activation)
        widths = [obs_dim + in_dim, *self.hidden, 1]
        for j, (w_in, w_out) in enumerate(itertools.pairwise(widths)):
            self.register_parameter(f"weight{j}", nn.Parameter(torch.empty(2, w_in, w_out)))
            self.register_parameter(f"bias{j}", nn.Parameter(torch.empty(2, 1, w_out)))
            if self.layer_norm and j < len(self.hidden):
                self.register_parameter(f"ln_weight{j}", nn.Parameter(torch.ones(2, 1, w_out)))
                self.register_parameter(f"ln_bias{j}", nn.Parameter(torch.zeros(2, 1, w_out)))
        # TwinQ's initialisation, then its weights copied in
        twin = TwinQ(obs_dim, in_dim, hidden, activation, layer_norm)
        self.load_state_dict(twin.state_dict())

    @classmethod
    def from_twin(cls, twin: TwinQ) -> BatchedTwinQ:
        """A :class:`BatchedTwinQ` holding ``twin``'s weights."""
        q = twin.q1
        out = cls(q.in_dim, 0, q.hidden, q.activation, q.layer_norm)  # only the sum counts
        out.load_state_dict(twin.state_dict())
        return out

    # ------------------------------------------------------------------ TwinQ's layout
    def _step(self) -> int:
        return 3 if self.layer_norm else 2  # linear, [norm,] activation

    def _twin_names(self) -> list[tuple[str, str, bool]]:
        """(own parameter, TwinQ's name without ``q{i}.``, transposed) for every tensor."""
        n = len(self.hidden)
        names = []
        for j in range(n + 1):
            lin = j * self._step()
            names += [(f"weight{j}", f"net.{lin}.weight", True),
                      (f"bias{j}", f"net.{lin}.bias", False)]  # fmt: skip
            if self.layer_norm and j < n:
                names += [(f"ln_weight{j}", f"net.{lin + 1}.weight", False),
                          (f"ln_bias{j}", f"net.{lin + 1}.bias", False)]  # fmt: skip
        return names

    def _save_to_state_dict(
        self, destination: dict[str, Any], prefix: str, keep_vars: bool
    ) -> None:
        for i in range(2):  # TwinQ's order: all of q1, then all of q2
            for own, twin, transposed in self._twin_names():
                p = getattr(self, own)
                p = p if keep_vars else p.detach()
                t = p[i].t() if transposed else p[i, 0]
                destination[f"{prefix}q{i + 1}.{twin}"] = t if keep_vars else t.contiguous()

    def _load_from_state_dict(
        self,
        state_dict: dict[str, Any],
        prefix: str,
        local_metadata: dict[str, Any],
        strict: bool,
        missing_keys: list[str],
        unexpected_keys: list[str],
        error_msgs: list[str],
    ) -> None:
        for own, twin, transposed in self._twin_names():
            p = getattr(self, own)
            for i in range(2):
                key = f"{prefix}q{i + 1}.{twin}"
                if key not in state_dict:
                    missing_keys.append(key)
                    continue
                t = state_dict[key]
                t = t.t() if transposed else t.unsqueeze(0)
                if t.shape != p.shape[1:]:
                    error_msgs.append(
                        f"size mismatch for {key}: copying a param with shape "
                        f"{tuple(state_dict[key].shape)}, the shape in the current model is "
                        f"{tuple(p[i].t().shape if transposed else p.shape[2:])}"
                    )
                    continue
                with torch.no_grad():
                    p[i].copy_(t)
        if strict:
            known = {f"{prefix}q{i + 1}.{twin}" for _, twin, _ in self._twin_names()
                     for i in range(2)}  # fmt: skip
            unexpected_keys += [
                k
                for k in state_dict
                if k.startswith(prefix) and k not in known and not k.startswith(f"{prefix}act.")
            ]

    # ------------------------------------------------------------------ forward
    def forward(self, obs: torch.Tensor, c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.cat([obs, c], dim=-1)
        h = x.unsqueeze(0).expand(2, -1, -1)  # [2, B, in]
        n = len(self.hidden)
        for j in range(n + 1):
            h = torch.baddbmm(getattr(self, f"bias{j}"), h, getattr(self, f"weight{j}"))
            if j < n:
                if self.layer_norm:
                    h = F.layer_norm(h, h.shape[-1:])
                    h = torch.addcmul(getattr(self, f"ln_bias{j}"), h,
                                      getattr(self, f"ln_weight{j}"))  # fmt: skip
                h = self.act(h)
        return h[0, :, 0], h[1, :, 0]
