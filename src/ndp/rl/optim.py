"""Adam with global gradient-norm clipping over one flat parameter buffer.

The PPO update takes 320 optimiser steps per rollout on small networks, where the per-tensor
overhead of ``clip_grad_norm_`` and ``Adam.step`` (a dozen parameter tensors; on the CPU the
``foreach`` kernels loop over them) costs as much as the maths. :class:`FlatAdam` packs every
parameter of a module into one contiguous tensor (the module's parameters become views of it,
so the module and its ``state_dict`` are unchanged), gathers the gradients with one ``cat``,
clips them with one norm and steps one fused Adam on one tensor. The numbers are those of
``torch.nn.utils.clip_grad_norm_`` followed by ``torch.optim.Adam`` (tested).
"""

from __future__ import annotations

from typing import Any

import torch
from torch import nn


class FlatAdam:
    """Adam over all parameters of ``module``, packed into one flat buffer.

    Args:
        module: its parameters are re-pointed to views of one buffer (build it after moving the
            module to its device; do not move it afterwards).
        lr: learning rate.
        eps: Adam epsilon.
    """

    def __init__(self, module: nn.Module, lr: float, eps: float) -> None:
        self.params = [p for p in module.parameters() if p.requires_grad]
        if not self.params:
            raise ValueError("module: expected trainable parameters")
        total = sum(p.numel() for p in self.params)
        first = self.params[0]
        flat = torch.empty(total, dtype=first.dtype, device=first.device)
        off = 0
        for p in self.params:
            n = p.numel()
            flat[off : off + n].copy_(p.detach().reshape(-1))
            p.data = flat[off : off + n].view_as(p)
            off += n
        self.flat = nn.Parameter(flat)  # shares storage with every module parameter
        self.opt = torch.optim.Adam(
            [self.flat], lr=lr, eps=eps, fused=first.device.type in ("cpu", "cuda")
        )

    @property
    def param_groups(self) -> list[dict[str, Any]]:
        """The optimiser's parameter groups (set ``lr`` here)."""
        return self.opt.param_groups

    def zero_grad(self) -> None:
        """Drop the module's gradients."""
        for p in self.params:
            p.grad = None

    def clip_grad_norm(self, max_norm: float) -> torch.Tensor:
        """Gather the gradients, scale them to global norm <= ``max_norm``; returns the norm
        before clipping (as ``clip_grad_norm_``; NaN / Inf propagate into it)."""
        grads = [torch.zeros_like(p) if p.grad is None else p.grad for p in self.params]
        g = torch.cat([x.reshape(-1) for x in grads])
        norm: torch.Tensor = torch.linalg.vector_norm(g)
        g.mul_((max_norm / (norm + 1e-6)).clamp(max=1.0))
        self.flat.grad = g
        return norm

    def step(self) -> None:
        """One Adam step with the gradient of the last :meth:`clip_grad_norm`."""
        self.opt.step()

    def state_dict(self) -> dict[str, Any]:
        """The optimiser state (one flat parameter)."""
        return self.opt.state_dict()

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Load a state from :meth:`state_dict`, or from a per-parameter ``torch.optim.Adam`` over
        the same parameters in the same order (the moments are concatenated)."""
        groups = state["param_groups"]
        n_saved = sum(len(g["params"]) for g in groups)
        if n_saved == len(self.params) and n_saved > 1:
            per = [state["state"].get(i) for i in groups[0]["params"]]
            if any(s is None for s in per):
                state = {"state": {}, "param_groups": [{**groups[0], "params": [0]}]}
            else:
                state = {
                    "state": {
                        0: {
                            "step": per[0]["step"],
                            "exp_avg": torch.cat([s["exp_avg"].reshape(-1) for s in per]),
                            "exp_avg_sq": torch.cat([s["exp_avg_sq"].reshape(-1) for s in per]),
                        }
                    },
                    "param_groups": [{**groups[0], "params": [0]}],
                }
        self.opt.load_state_dict(state)


def soft_update(target: nn.Module, source: nn.Module, tau: float) -> None:
    """``target <- (1 - tau) target + tau source`` (``lerp``), every parameter in one
    ``foreach`` call (the per-tensor loop costs as much as the maths on small critics)."""
    t: list[torch.Tensor] = list(target.parameters())
    s: list[torch.Tensor] = list(source.parameters())
    if len(t) != len(s):
        raise ValueError(f"soft_update: target has {len(t)} parameters, source {len(s)}")
    with torch.no_grad():
        torch._foreach_lerp_(t, s, tau)
