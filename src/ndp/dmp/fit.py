"""Least-squares fit of DMP parameters (g, w) to demonstrated trajectories.

Positions are affine in (v, g) with v = w * (g - y0) (see :func:`ndp.dmp.linear_map_f64`):

    y_t = P^v_t v + P^g_t g + P^y0_t y0 + P^dy0_t dy0.

Given a demonstration on the DMP's reported time grid, y0 = its first point and dy0 known, the
fit solves the linear least-squares problem for (v, g) (or for v alone with a given goal) with a
small ridge term, by SVD of the design (stable at the map's ~1e13 condition number; the normal
equations are not), then recovers w = v / (g - y0), or w = v when ``cfg.scale_by_goal`` is False.
When g is close to y0 (a closed loop such as a "0") the forcing term's scale g - y0 is small and
the weights grow accordingly: a property of the (g - y0) scaling, which ``scale_by_goal=False``
removes.
"""

from __future__ import annotations

import math

import torch

from ndp.dmp.config import DMPConfig
from ndp.dmp.integrate import _linear_map_f64


def fit_dmp(
    demo: torch.Tensor,
    cfg: DMPConfig | None = None,
    dy0: torch.Tensor | None = None,
    goal: torch.Tensor | None = None,
    ridge: float = 1e-8,
    min_scale: float = 1e-6,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Fit goal and weights so that the DMP rollout reproduces ``demo``.

    Args:
        demo: demonstrated positions [B, n_out, D] on the reported grid of ``cfg``
            (n_out = steps // subsample + 1); ``demo[:, 0]`` is used as y0.
        cfg: integrator settings (fixed a_z; ``only_g`` is not fittable for weights).
        dy0: start velocity [B, D] (``None``: zeros, a demonstration starting at rest).
        goal: optional fixed goal [B, D]; if ``None`` the goal is fitted jointly.
        ridge: Tikhonov weight on the forcing coefficients, relative to their mean curvature.
        min_scale: |g - y0| is floored at this value (keeping its sign) when recovering w.

    Returns:
        (goal [B, D], weights [B, D, N]) in the dtype and device of ``demo``.
    """
    cfg = cfg or DMPConfig()
    _check_fit_args(demo, cfg, ridge)
    b, t1, d = demo.shape
    n = cfg.n_basis
    m = torch.as_tensor(_linear_map_f64(cfg, None)[:, :t1].copy())  # [N + 3, n_out] positions
    y = demo.detach().to(torch.float64, copy=True).cpu()
    y0 = y[:, 0]  # [B, D]
    dy0_ = torch.zeros_like(y0) if dy0 is None else dy0.detach().to(torch.float64).cpu()
    if dy0_.shape != (b, d):
        raise ValueError(f"dy0: expected shape {(b, d)}, got {tuple(dy0_.shape)}")
    # Residual after the known inputs: [B, D, n_out].
    rhs = y.transpose(1, 2) - y0.unsqueeze(-1) * m[n + 1] - dy0_.unsqueeze(-1) * m[n + 2]
    if goal is None:
        design = m[: n + 1].T  # [n_out, N + 1]: columns v_1..v_N, g
    else:
        if goal.shape != (b, d):
            raise ValueError(f"goal: expected shape {(b, d)}, got {tuple(goal.shape)}")
        g_fixed = goal.detach().to(torch.float64).cpu()
        rhs = rhs - g_fixed.unsqueeze(-1) * m[n]
        design = m[:n].T  # [n_out, N]
    sol = _ridge_lstsq(design, rhs.reshape(b * d, t1).T, n, ridge)  # [B * D, K]
    sol = sol.reshape(b, d, -1)
    v = sol[..., :n]
    g = sol[..., n] if goal is None else g_fixed
    if not cfg.scale_by_goal:
        return g.to(demo), v.to(demo)
    scale = g - y0
    sign = torch.where(scale >= 0, 1.0, -1.0).to(scale)
    scale = torch.where(scale.abs() < min_scale, sign * min_scale, scale)
    w = v / scale.unsqueeze(-1)
    return g.to(demo), w.to(demo)


def _check_fit_args(demo: torch.Tensor, cfg: DMPConfig, ridge: float) -> None:
    """Refuse a config without fittable weights, a malformed demonstration or a bad ridge."""
    if cfg.learn_az:
        raise ValueError("cfg: fit_dmp needs a fixed a_z (learn_az=False)")
    if cfg.only_g:
        raise ValueError("cfg: fit_dmp fits forcing weights; only_g=True has none")
    if not isinstance(demo, torch.Tensor) or demo.ndim != 3 or not demo.is_floating_point():
        raise ValueError("demo: expected a floating-point tensor [B, n_out, D]")
    t1 = demo.shape[1]
    if t1 != cfg.n_out:
        raise ValueError(
            f"demo: expected {cfg.n_out} points per trajectory (steps // subsample + 1), got {t1}"
        )
    if not bool(torch.isfinite(demo).all()):
        raise ValueError("demo: expected finite values, found NaN or Inf")
    if (
        isinstance(ridge, bool)
        or not isinstance(ridge, (int, float))
        or not 0.0 <= ridge < math.inf
    ):
        raise ValueError(f"ridge: expected a finite number >= 0, got {ridge!r}")


def _ridge_lstsq(design: torch.Tensor, rhs: torch.Tensor, n: int, ridge: float) -> torch.Tensor:
    """Ridge least squares ``design [n_out, K] @ x = rhs [n_out, M]``, transposed: [M, K]."""
    # The map is badly conditioned (late basis functions barely move the trajectory: the
    # condition number of `design` is ~1e13 at N = 30), so a ridge term penalises the forcing
    # coefficients v (never the goal), scaled to their block. The regularised problem is solved
    # as an augmented least-squares problem [design; sqrt(reg)] by SVD (gelsd), never through
    # the normal equations: those square the condition number (past 1e16 at N >= 20), so with
    # a small or zero ridge their solution, and the fit's residual, would depend on rounding
    # (the thread count, the BLAS). With ridge = 0 the result is the minimum-norm least-squares
    # solution, singular values below eps * (n_out + N + 1) of the largest treated as zero.
    k = design.shape[1]
    reg = torch.zeros(k, dtype=design.dtype)
    reg[:n] = ridge * (design[:, :n] ** 2).sum(0).mean()
    a_aug = torch.cat([design, torch.diag(reg.sqrt())], 0)  # [n_out + K, K]
    b_aug = torch.cat([rhs, torch.zeros(k, rhs.shape[1], dtype=rhs.dtype)], 0)
    sol: torch.Tensor = torch.linalg.lstsq(a_aug, b_aug, driver="gelsd").solution.T
    return sol
