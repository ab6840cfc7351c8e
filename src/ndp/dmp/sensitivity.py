"""Analytic sensitivities of DMP positions to the weights and the goal (supplement 1.3).

Differentiating the Euler recursion of :mod:`ndp.dmp.integrate` gives recursions of the same
form. For weight w_i (per degree of freedom) with W = dy/dw_i and W^z = dz/dw_i:

    W_t   = W_{t-1} + W^z_{t-1} / tau * dt
    W^z_t = W^z_{t-1} + dt * (a_z * (-b_z W_{t-1} - W^z_{t-1}) + phi_i(x_t) x_t (g - y0)) / tau

and for the goal with G = dy/dg, G^z = dz/dg:

    G_t   = G_{t-1} + G^z_{t-1} / tau * dt
    G^z_t = G^z_{t-1} + dt * (a_z * (b_z (1 - G_{t-1}) - G^z_{t-1}) + sum_j phi_j w_j x_t) / tau

with W_0 = W^z_0 = G_0 = G^z_0 = 0 (released form; the supplement form scales the forcing
derivative by a_z as well).
"""

from __future__ import annotations

import torch

from ndp.dmp.basis import normalised_rbf
from ndp.dmp.config import DMPConfig
from ndp.dmp.integrate import euler_step, phase_basis, reported, spring_constants, validate_inputs


def dmp_sensitivities(
    goal: torch.Tensor,
    weights: torch.Tensor | None,
    y0: torch.Tensor,
    dy0: torch.Tensor | None = None,
    cfg: DMPConfig | None = None,
    a_z: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Analytic dy_t/dw_i and dy_t/dg at every reported step.

    Args:
        goal, weights, y0, dy0, cfg, a_z: as for :func:`ndp.dmp.dmp_rollout_reference`.

    Returns:
        (dy_dw, dy_dg): [B, n_out, D, N] and [B, n_out, D]. Degrees of freedom are independent,
        so dy[b, t, d] depends only on w[b, d, :] and g[b, d].
    """
    cfg = cfg or DMPConfig()
    goal, weights, y0, dy0, a_z_t = validate_inputs(cfg, goal, weights, y0, dy0, a_z)
    az, bz = spring_constants(cfg, a_z_t)
    tau, dt = cfg.tau, cfg.step_dt
    az_w = az.unsqueeze(-1) if isinstance(az, torch.Tensor) else az
    bz_w = bz.unsqueeze(-1) if isinstance(bz, torch.Tensor) else bz

    w_y = torch.zeros_like(weights)
    w_z = torch.zeros_like(weights)
    g_y = torch.zeros_like(goal)
    g_z = torch.zeros_like(goal)
    out_w, out_g = [w_y], [g_y]
    for x, phi in phase_basis(cfg, goal, normalised_rbf):
        if cfg.only_g:
            df_dw = torch.zeros_like(weights)
            df_dg = torch.zeros_like(goal)
        else:
            if cfg.scale_by_goal:
                df_dw = phi * x * (goal - y0).unsqueeze(-1)  # [B, D, N]
                df_dg = (weights @ phi) * x  # [B, D]
            else:
                df_dw = (phi * x).expand_as(weights)
                df_dg = torch.zeros_like(goal)
        # the transformation system's Euler step on the derivative states (dg/dw = 0, dg/dg = 1)
        w_y, w_z, _ = euler_step(w_y, w_z, 0.0, df_dw, az_w, bz_w, tau, dt, cfg.forcing)
        g_y, g_z, _ = euler_step(g_y, g_z, 1.0, df_dg, az, bz, tau, dt, cfg.forcing)
        out_w.append(w_y)
        out_g.append(g_y)
    dy_dw, dy_dg = reported(cfg, out_w, out_g)
    return dy_dw, dy_dg
