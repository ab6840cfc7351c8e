"""Canonical system and radial basis functions of the forcing term.

Notation (see :mod:`ndp.dmp`): x is the phase of the canonical system, c_i and h_i the centres
and inverse widths of the N basis functions, e_i = (x - c_i)^2.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import torch

if TYPE_CHECKING:  # annotations only: config validates kinds against this module's table
    from ndp.dmp.config import DMPConfig

RBF_FUNCTIONS: dict[str, Callable[[torch.Tensor], torch.Tensor]] = {
    "gaussian": lambda he: torch.exp(-he),
    "multiquadric": lambda he: torch.sqrt(1.0 + he),
    "inverse_quadric": lambda he: 1.0 / (1.0 + he),
    "inverse_multiquadric": lambda he: 1.0 / torch.sqrt(1.0 + he),
    "linear": lambda he: he,
}
"""Radial basis kinds: name -> psi as a function of h (x - c)^2 (the one table of kinds: adding
a kind is one entry here; ``DMPConfig.rbf`` accepts every name in it)."""
RBF_KINDS = tuple(RBF_FUNCTIONS)


def canonical_phase(cfg: DMPConfig, dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Phase x_t of the canonical system at every integration step.

    x_0 = 1 and x_t = x_{t-1} - a_x * x_{t-1} / tau * dt (explicit Euler).

    Returns:
        x: [T + 1], ``x[0] == 1``.
    """
    decay = 1.0 - cfg.a_x * cfg.step_dt / cfg.tau
    return decay ** torch.arange(cfg.steps + 1, dtype=dtype)


def basis_centres(
    n_basis: int, a_x: float, dtype: torch.dtype = torch.float64
) -> tuple[torch.Tensor, torch.Tensor]:
    """Centres c_i = exp(-a_x * linspace(0, 1, N)) and inverse widths h_i = N^1.5 / (c_i a_x).

    Returns:
        (c, h): each [N].
    """
    c = torch.exp(-a_x * torch.linspace(0.0, 1.0, n_basis, dtype=dtype))
    h = n_basis**1.5 / (c * a_x)
    return c, h


def rbf(x: torch.Tensor, c: torch.Tensor, h: torch.Tensor, kind: str) -> torch.Tensor:
    """Unnormalised basis values psi_i(x).

    Args:
        x: phase, any shape [...].
        c, h: centres and inverse widths [N].
        kind: one of :data:`ndp.dmp.config.RBF_KINDS`.

    Returns:
        psi: [..., N].
    """
    fn = RBF_FUNCTIONS.get(kind)
    if fn is None:
        raise ValueError(f"kind: expected one of {', '.join(RBF_FUNCTIONS)}, got {kind!r}")
    return fn(h * (x.unsqueeze(-1) - c) ** 2)


def normalised_rbf(x: torch.Tensor, c: torch.Tensor, h: torch.Tensor, kind: str) -> torch.Tensor:
    """Normalised basis psi_i(x) / sum_j psi_j(x), rows summing to 1.

    The gaussian kind is evaluated as a softmax of -h e, which is the same quantity but cannot
    underflow to 0/0 far from every centre.

    Returns:
        phi: [..., N].
    """
    if kind == "gaussian":
        return torch.softmax(-h * (x.unsqueeze(-1) - c) ** 2, dim=-1)
    psi = rbf(x, c, h, kind)
    return psi / psi.sum(dim=-1, keepdim=True)


def forcing_features(cfg: DMPConfig, dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Per-step forcing features F[t-1, i] = phi_i(x_t) * x_t for t = 1..T.

    The forcing term at step t is f_t = sum_i F[t-1, i] * w_i * (g - y0): the basis is evaluated
    at the phase AFTER the canonical update of that step (the released integration order).

    Returns:
        F: [T, N].
    """
    x = canonical_phase(cfg, dtype)[1:]
    c, h = basis_centres(cfg.n_basis, cfg.a_x, dtype)
    return normalised_rbf(x, c, h, cfg.rbf) * x.unsqueeze(-1)


def duration(cfg: DMPConfig) -> float:
    """Length of one rollout in DMP time: steps * dt."""
    return cfg.steps * cfg.step_dt


def final_phase(cfg: DMPConfig) -> float:
    """Phase at the end of a rollout, x_T."""
    return math.pow(1.0 - cfg.a_x * cfg.step_dt / cfg.tau, cfg.steps)
