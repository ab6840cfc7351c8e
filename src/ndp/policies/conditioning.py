"""The conditioning of an action head's map from raw outputs to sub-actions (issue 59).

The actor's last layer gives ``raw`` [B, P]; the head turns it into the decision's k
sub-action means [B, k, A]. Its Jacobian per decision,

    J_b = d mean_b / d raw_b      [M, P],  M = k * A  (the means flattened sub-step major),

is what a PPO gradient step in the actor's output goes through: a direction of the chunk with a
small singular value needs a large raw change (and, late in training, a large actor weight
change) to move, one with a large singular value moves at once. This module holds the pure
numerical functions; :meth:`ndp.policies.heads.NDPHead.raw_jacobians` gives the NDP head's J and
the Jacobian of its map without the elementwise bound, and ``ndp rl diagnose --jacobian``
(:mod:`ndp.rl.diagnose`) reads them along rollouts.

**Reachable directions.** Some rows of J never depend on the raw outputs independently: the
gripper of Meta-World, whose command is the goal itself at all k sub-steps (k equal rows, rank
1), or the k sub-steps of a DoF driven by 1 + N outputs when 1 + N > k. Their directions are not
reachable by any raw change, so the condition number is taken over the reachable ones only:
the rank r is the numerical rank of the *map's* Jacobian ``J_map`` (the head's Jacobian with
respect to its bounded parameters, i.e. with every tanh slope replaced by 1; equal to J at
raw = 0), by NumPy's ``matrix_rank`` rule: the singular values above
``max(M, P) * eps(dtype) * s_max``. The condition number of J is then ``s_1 / s_r`` of J's own
singular values, so a saturated tanh (slope near 0) shows as a large condition number instead
of removing a direction (``map_condition``, the same ratio of ``J_map``, separates the two).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

SATURATION_SLOPE = 0.07
"""A raw output u counts as saturated when its tanh slope ``1 - tanh(u)^2`` is below this
(|u| > 1.996)."""


def raw_jacobian(decode: Callable[[torch.Tensor], torch.Tensor], raw: torch.Tensor) -> torch.Tensor:
    """Jacobian of a per-decision map at each decision of a batch, by reverse-mode autograd.

    Decision b's outputs must depend on ``raw[b]`` only (true of every action head: no batch
    statistics), so one backward pass of an output summed over the batch gives that output's
    row for every decision at once: M backward passes in all.

    Args:
        decode: ``raw`` [B, P] -> outputs [B, ...] (flattened to [B, M]), differentiable.
        raw: the point [B, P] (its dtype is the computation's; float64 for checks).

    Returns:
        [B, M, P]: ``J[b, i, p] = d out[b, i] / d raw[b, p]`` (zero where an output does not
        depend on an input).
    """
    if raw.dim() != 2:
        raise ValueError(f"raw: expected shape [B, P], got {tuple(raw.shape)}")
    x = raw.detach().clone().requires_grad_(True)
    with torch.enable_grad():
        out = decode(x)
        if out.shape[0] != x.shape[0]:
            raise ValueError(
                f"decode: expected outputs [B, ...] with B = {x.shape[0]}, got {tuple(out.shape)}"
            )
        out = out.reshape(x.shape[0], -1)
        m = out.shape[1]
        rows = []
        for i in range(m):
            (g,) = torch.autograd.grad(
                out[:, i].sum(), x, retain_graph=i < m - 1, allow_unused=True
            )
            rows.append(torch.zeros_like(x) if g is None else g)
    return torch.stack(rows, dim=1)


def numerical_rank(singular_values: torch.Tensor, m: int, p: int) -> torch.Tensor:
    """Rank of matrices [M, P] from their singular values [..., min(M, P)] (descending), by
    NumPy's ``matrix_rank`` rule: the count above ``max(M, P) * eps(dtype) * s_max``.

    Returns:
        [...] int64 ranks.
    """
    eps = torch.finfo(singular_values.dtype).eps
    tol = max(m, p) * eps * singular_values[..., :1]
    return (singular_values > tol).sum(-1)


def whitening_transform(jac: torch.Tensor) -> tuple[torch.Tensor, int]:
    """The fixed raw-output transform W [P, P] that makes a map with Jacobian ``jac`` [M, P]
    isotropic on its reachable subspace.

    With ``jac = U S V^T`` (rank r, :func:`numerical_rank`) and V_r the first r right singular
    vectors,

        W = V_r S_r^-1 V_r^T + (I - V_r V_r^T),

    so that ``jac @ W = U_r V_r^T``: its r nonzero singular values are all 1 (unit noise in the
    new raw outputs is unit noise over the reachable directions of the chunk), and W is the
    identity on the null space of ``jac`` (directions that move no sub-action keep their
    scale). W is symmetric and invertible (eigenvalues 1 / s_i and 1).

    Args:
        jac: [M, P], float64 for a transform that is exact to rounding.

    Returns:
        (W [P, P] in ``jac``'s dtype, r).
    """
    if jac.dim() != 2:
        raise ValueError(f"jac: expected shape [M, P], got {tuple(jac.shape)}")
    m, p = jac.shape
    _, s, vh = torch.linalg.svd(jac, full_matrices=False)
    r = int(numerical_rank(s, m, p))
    if r == 0:
        raise ValueError("jac: expected a map with at least one reachable direction, got rank 0")
    v = vh[:r].T  # [P, r]
    eye = torch.eye(p, dtype=jac.dtype, device=jac.device)
    return v @ torch.diag(1.0 / s[:r]) @ v.T + (eye - v @ v.T), r


@dataclass(frozen=True)
class Conditioning:
    """Per-decision conditioning of a head's map (shapes: B decisions, R = min(M, P))."""

    singular_values: torch.Tensor
    """[B, R] singular values of J, descending."""
    map_singular_values: torch.Tensor
    """[B, R] singular values of ``J_map`` (the map without the elementwise bound)."""
    rank: torch.Tensor
    """[B] reachable directions r (numerical rank of ``J_map``)."""
    condition: torch.Tensor
    """[B] ``s_1 / s_r`` of J (inf where s_r is 0)."""
    map_condition: torch.Tensor
    """[B] ``s_1 / s_r`` of ``J_map``."""
    goal_share: torch.Tensor
    """[B] share of ``|J|_F^2`` in the goal columns."""
    weight_share: torch.Tensor
    """[B] share of ``|J|_F^2`` in the forcing-weight columns."""


def conditioning(
    jac: torch.Tensor, map_jac: torch.Tensor, goal_cols: slice, weight_cols: slice
) -> Conditioning:
    """Singular values, reachable rank and condition number of J, and its Frobenius shares.

    Args:
        jac: J [B, M, P].
        map_jac: ``J_map`` [B, M, P], J with the elementwise bound's slopes replaced by 1 (J
            itself for a head without one): it decides the reachable rank (module docstring).
        goal_cols: the goal columns of P.
        weight_cols: the forcing-weight columns of P (an empty slice when there are none).
    """
    if jac.dim() != 3 or map_jac.shape != jac.shape:
        raise ValueError(
            f"jac, map_jac: expected two [B, M, P] of one shape, got {tuple(jac.shape)} and "
            f"{tuple(map_jac.shape)}"
        )
    _, m, p = jac.shape
    s = torch.linalg.svdvals(jac)
    s_map = torch.linalg.svdvals(map_jac)
    rank = numerical_rank(s_map, m, p)
    idx = (rank - 1).clamp(min=0).unsqueeze(-1)
    condition = s[:, 0] / s.gather(-1, idx).squeeze(-1)
    map_condition = s_map[:, 0] / s_map.gather(-1, idx).squeeze(-1)
    sq = jac.pow(2)
    total = sq.sum((1, 2))
    return Conditioning(
        singular_values=s,
        map_singular_values=s_map,
        rank=rank,
        condition=condition,
        map_condition=map_condition,
        goal_share=sq[:, :, goal_cols].sum((1, 2)) / total,
        weight_share=sq[:, :, weight_cols].sum((1, 2)) / total,
    )


def saturated_fraction(pre: torch.Tensor, threshold: float = SATURATION_SLOPE) -> torch.Tensor:
    """Fraction of the pre-tanh values ``pre`` [B, Q] whose slope ``1 - tanh(u)^2`` is below
    ``threshold``, per decision [B] (NaN where Q = 0)."""
    if pre.dim() != 2:
        raise ValueError(f"pre: expected shape [B, Q], got {tuple(pre.shape)}")
    if not 0.0 < threshold <= 1.0:
        raise ValueError(f"threshold: expected a slope in (0, 1], got {threshold!r}")
    slope = 1.0 - torch.tanh(pre).pow(2)
    return (slope < threshold).to(pre.dtype).mean(-1)
