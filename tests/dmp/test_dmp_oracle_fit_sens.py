"""Independent checks: a NumPy oracle, analytic sensitivities, least-squares fit, bad input."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from ndp.dmp import (
    DMPConfig,
    DMPLayer,
    check_finite,
    dmp_rollout,
    dmp_sensitivities,
    fit_dmp,
)


def numpy_dmp(goal, w, y0, dy0, n, a_z, b_z, a_x, tau, dt, steps, kind, forcing, scale=True):
    """One degree of freedom, written from the equations with scalars only (the oracle)."""
    centres = np.exp(-a_x * np.linspace(0.0, 1.0, n))
    widths = n**1.5 / centres / a_x
    x, y, z = 1.0, y0, tau * dy0
    ys = [y]
    for _ in range(steps):
        x += -a_x * x / tau * dt
        psi = []
        for c, h in zip(centres, widths, strict=True):
            e = h * (x - c) ** 2
            psi.append(
                {
                    "gaussian": np.exp(-e),
                    "multiquadric": np.sqrt(1 + e),
                    "inverse_quadric": 1 / (1 + e),
                    "inverse_multiquadric": 1 / np.sqrt(1 + e),
                    "linear": e,
                }[kind]
            )
        f = sum(p * wi for p, wi in zip(psi, w, strict=True)) / sum(psi) * x
        if scale:
            f *= goal - y0
        if forcing == "released":
            dz = (a_z * (b_z * (goal - y) - z) + f) / tau
        else:
            dz = a_z * (b_z * (goal - y) - z + f) / tau
        y, z = y + z / tau * dt, z + dz * dt
        ys.append(y)
    return np.array(ys)


@pytest.mark.parametrize(
    "cfg",
    [
        DMPConfig(n_basis=30, a_z=25.0, steps=300),
        DMPConfig(n_basis=6, a_z=10.0, steps=35, forcing="supplement"),
        DMPConfig(n_basis=5, a_z=5.0, steps=40, tau=0.7, a_x=1.5, rbf="inverse_multiquadric"),
        DMPConfig(n_basis=7, a_z=15.0, b_z=3.0, steps=50, dt=0.03, rbf="multiquadric"),
        DMPConfig(n_basis=30, a_z=25.0, steps=300, scale_by_goal=False),
    ],
    ids=["il", "rl-supplement", "imq", "mq-bz", "unscaled"],
)
@pytest.mark.parametrize("method", ["loop", "fast"])
def test_matches_independent_numpy_oracle(cfg, method):
    rng = np.random.default_rng(3)
    b, d, n = 2, 2, cfg.n_basis
    goal, y0, dy0 = rng.normal(size=(b, d)), rng.normal(size=(b, d)), rng.normal(size=(b, d))
    w = rng.normal(size=(b, d, n)) * 10
    t = [torch.as_tensor(a) for a in (goal, w, y0, dy0)]
    out = dmp_rollout(*t, cfg, method=method).pos.numpy()
    for i in range(b):
        for j in range(d):
            ref = numpy_dmp(
                goal[i, j],
                w[i, j],
                y0[i, j],
                dy0[i, j],
                n,
                cfg.a_z,
                cfg.bz,
                cfg.a_x,
                cfg.tau,
                cfg.step_dt,
                cfg.steps,
                cfg.rbf,
                cfg.forcing,
                cfg.scale_by_goal,
            )
            np.testing.assert_allclose(out[i, :, j], ref, rtol=1e-10, atol=1e-10)


SENS_CFGS = [
    DMPConfig(n_basis=6, a_z=10.0, steps=35, subsample=7),
    DMPConfig(n_basis=8, a_z=25.0, steps=60, forcing="supplement", rbf="inverse_quadric"),
    DMPConfig(n_basis=6, a_z=10.0, steps=35, scale_by_goal=False),
]


@pytest.mark.parametrize("cfg", SENS_CFGS, ids=["released", "supplement", "unscaled"])
def test_analytic_sensitivities_equal_autograd_and_finite_differences(cfg):
    gen = torch.Generator().manual_seed(5)
    b, d, n = 2, 2, cfg.n_basis
    goal = torch.randn(b, d, generator=gen, dtype=torch.float64)
    w = torch.randn(b, d, n, generator=gen, dtype=torch.float64) * 5
    y0 = torch.randn(b, d, generator=gen, dtype=torch.float64)
    dy0 = torch.randn(b, d, generator=gen, dtype=torch.float64)
    dy_dw, dy_dg = dmp_sensitivities(goal, w, y0, dy0, cfg)
    assert dy_dw.shape == (b, cfg.n_out, d, n) and dy_dg.shape == (b, cfg.n_out, d)

    # autograd: the full Jacobian of positions w.r.t. (goal, w)
    def pos(g, ww):
        return dmp_rollout(g, ww, y0, dy0, cfg).pos

    jg, jw = torch.autograd.functional.jacobian(pos, (goal, w))  # [B,T,D,B,D], [B,T,D,B,D,N]
    for i in range(b):
        for j in range(d):
            torch.testing.assert_close(jg[i, :, j, i, j], dy_dg[i, :, j], rtol=1e-9, atol=1e-9)
            torch.testing.assert_close(jw[i, :, j, i, j], dy_dw[i, :, j], rtol=1e-9, atol=1e-9)
    # degrees of freedom and samples are independent
    assert jg[0, :, 0, 0, 1].abs().max() == 0 and jg[0, :, 0, 1, 0].abs().max() == 0

    # central finite differences
    eps = 1e-6
    for i, j, k in [(0, 0, 0), (1, 1, n - 1), (0, 1, n // 2)]:
        wp, wm = w.clone(), w.clone()
        wp[i, j, k] += eps
        wm[i, j, k] -= eps
        fd = (pos(goal, wp) - pos(goal, wm))[i, :, j] / (2 * eps)
        torch.testing.assert_close(fd, dy_dw[i, :, j, k], rtol=1e-6, atol=1e-7)
        gp, gm = goal.clone(), goal.clone()
        gp[i, j] += eps
        gm[i, j] -= eps
        fd = (pos(gp, w) - pos(gm, w))[i, :, j] / (2 * eps)
        torch.testing.assert_close(fd, dy_dg[i, :, j], rtol=1e-6, atol=1e-7)


def test_sensitivities_with_learned_az_match_autograd():
    cfg = DMPConfig(n_basis=5, steps=30, learn_az=True)
    gen = torch.Generator().manual_seed(2)
    goal = torch.randn(3, 1, generator=gen, dtype=torch.float64)
    w = torch.randn(3, 1, 5, generator=gen, dtype=torch.float64, requires_grad=True)
    y0 = torch.zeros(3, 1, dtype=torch.float64)
    a_z = torch.tensor([5.0, 10.0, 20.0], dtype=torch.float64)
    dy_dw, _ = dmp_sensitivities(goal, w.detach(), y0, None, cfg, a_z=a_z)
    pos = dmp_rollout(goal, w, y0, None, cfg, a_z=a_z).pos
    (g,) = torch.autograd.grad(pos[:, -1, 0].sum(), w)
    torch.testing.assert_close(g[:, 0], dy_dw[:, -1, 0], rtol=1e-10, atol=1e-12)


def _min_jerk_demo(n_out: int) -> torch.Tensor:
    """Smooth 2-D demos on [0, 1]: a 3/4 circle, an S-curve and a straight line, in pixels."""
    t = torch.linspace(0, 1, n_out, dtype=torch.float64)
    s = 10 * t**3 - 15 * t**4 + 6 * t**5
    circle = torch.stack(
        [20 + 8 * torch.cos(1.5 * np.pi * s), 20 + 8 * torch.sin(1.5 * np.pi * s)], -1
    )
    scurve = torch.stack([10 + 20 * s, 20 + 6 * torch.sin(2 * np.pi * s)], -1)
    line = torch.stack([5 + 30 * s, 30 - 20 * s], -1)
    return torch.stack([circle, scurve, line])


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("scale_by_goal", [True, False])
def test_fit_then_rollout_reproduces_smooth_demonstrations(dtype, scale_by_goal):
    cfg = DMPConfig(n_basis=30, a_z=25.0, steps=300, scale_by_goal=scale_by_goal)
    demo = _min_jerk_demo(cfg.n_out).to(dtype)
    goal, w = fit_dmp(demo, cfg)
    assert goal.dtype == dtype and w.shape == (3, 2, 30)
    rec = dmp_rollout(goal, w, demo[:, 0], None, cfg).pos
    mse = ((rec.double() - demo.double()) ** 2).sum(-1).mean(-1)  # px^2 per sample
    assert mse.max() < 1e-2, mse
    # too few basis functions cannot: the fit is genuinely a fit
    small = dataclasses.replace(cfg, n_basis=2)
    g2, w2 = fit_dmp(demo, small)
    rec2 = dmp_rollout(g2, w2, demo[:, 0], None, small).pos
    assert ((rec2.double() - demo.double()) ** 2).sum(-1).mean() > 10 * mse.max()


def test_fit_recovers_parameters_of_a_dmp_generated_trajectory_in_position():
    cfg = DMPConfig(n_basis=6, a_z=10.0, steps=35)
    gen = torch.Generator().manual_seed(0)
    goal = torch.randn(4, 3, generator=gen, dtype=torch.float64)
    w = torch.randn(4, 3, 6, generator=gen, dtype=torch.float64)
    y0 = torch.randn(4, 3, generator=gen, dtype=torch.float64)
    dy0 = torch.randn(4, 3, generator=gen, dtype=torch.float64)
    demo = dmp_rollout(goal, w, y0, dy0, cfg).pos
    g_fit, w_fit = fit_dmp(demo, cfg, dy0=dy0, ridge=0.0)
    torch.testing.assert_close(g_fit, goal, rtol=1e-6, atol=1e-6)
    torch.testing.assert_close(w_fit, w, rtol=1e-4, atol=1e-4)
    # with the goal given, only the weights are solved for
    g2, w2 = fit_dmp(demo, cfg, dy0=dy0, goal=goal, ridge=0.0)
    assert torch.equal(g2, goal)
    torch.testing.assert_close(w2, w, rtol=1e-4, atol=1e-4)


def _wiggly_demo(n_out: int, b: int = 6) -> torch.Tensor:
    """Pen-like strokes [b, n_out, 2] with sharp turns near the end (what the late, badly
    conditioned basis functions are for)."""
    t = torch.linspace(0.0, 1.0, n_out, dtype=torch.float64)
    k = torch.arange(1, b + 1, dtype=torch.float64).unsqueeze(-1)
    x = 10 * torch.sin(2 * torch.pi * k * t**2) + 3 * t
    y = 8 * torch.cos(3 * torch.pi * k * t**3) - 5 * t
    return torch.stack([x, y], -1)


def test_fit_at_zero_ridge_reaches_the_least_squares_minimum_at_n30():
    # The position map is ~1e13-conditioned at N = 30: normal equations (cond ~1e26) gave a
    # fit 35% worse than least squares, and one that changed with the thread count.
    cfg = DMPConfig(n_basis=30, a_z=25.0, steps=300)
    demo = _wiggly_demo(cfg.n_out)
    goal, w = fit_dmp(demo, cfg, ridge=0.0)
    rec = dmp_rollout(goal, w, demo[:, 0], None, cfg).pos
    ours = ((rec - demo) ** 2).sum((1, 2))
    # oracle: NumPy's SVD least squares on the same affine map, the residual it leaves
    from ndp.dmp import linear_map_f64

    m = linear_map_f64(cfg)[:, : cfg.n_out]
    a = m[: cfg.n_basis + 1].T
    y = demo.numpy()
    rhs = y - y[:, :1] * m[cfg.n_basis + 1][None, :, None]
    best = []
    for i in range(len(y)):
        sol, *_ = np.linalg.lstsq(a, rhs[i], rcond=None)
        best.append(((a @ sol - rhs[i]) ** 2).sum())
    np.testing.assert_allclose(ours.numpy(), np.array(best), rtol=1e-6, atol=1e-9)


def test_fit_does_not_depend_on_the_thread_count():
    cfg = DMPConfig(n_basis=30, a_z=25.0, steps=300)
    demo = _wiggly_demo(cfg.n_out, b=64)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        g1, w1 = fit_dmp(demo, cfg, ridge=0.0)
        torch.set_num_threads(max(2, before))
        g2, w2 = fit_dmp(demo, cfg, ridge=0.0)
    finally:
        torch.set_num_threads(before)
    r1 = dmp_rollout(g1, w1, demo[:, 0], None, cfg).pos
    r2 = dmp_rollout(g2, w2, demo[:, 0], None, cfg).pos
    # the residual (what `ndp il floor` reports) is the same; the parameters may move along
    # the map's near-null directions, which barely move the trajectory
    e1, e2 = ((r1 - demo) ** 2).sum((1, 2)), ((r2 - demo) ** 2).sum((1, 2))
    torch.testing.assert_close(e1, e2, rtol=1e-6, atol=0)
    torch.testing.assert_close(r1, r2, rtol=0, atol=1e-3)


# ------------------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "kwargs,word",
    [
        ({"n_basis": 0}, "n_basis"),
        ({"n_basis": 2.5}, "n_basis"),
        ({"steps": 0}, "steps"),
        ({"dt": 0.0}, "dt"),
        ({"dt": -0.1}, "dt"),
        ({"tau": 0.0}, "tau"),
        ({"tau": float("nan")}, "tau"),
        ({"a_z": 0.0}, "a_z"),
        ({"a_z": -5.0}, "a_z"),
        ({"b_z": -1.0}, "b_z"),
        ({"a_x": 0.0}, "a_x"),
        ({"rbf": "cubic"}, "rbf"),
        ({"forcing": "inside"}, "forcing"),
        ({"subsample": 7, "steps": 30}, "subsample"),
        ({"az_range": (5.0, 1.0)}, "az_range"),
        ({"dt": 2.0, "steps": 10}, "dt"),
    ],
)
def test_bad_config_names_the_argument(kwargs, word):
    with pytest.raises(ValueError, match=word):
        DMPConfig(**kwargs)


def test_bad_shapes_name_the_argument():
    layer = DMPLayer(n_basis=4, steps=10)
    g, y0 = torch.zeros(2, 3), torch.zeros(2, 3)
    w = torch.zeros(2, 3, 4)
    cases = [
        ((torch.zeros(2), w, y0), "goal"),
        ((g, torch.zeros(2, 3, 5), y0), "weights"),
        ((g, torch.zeros(3, 3, 4), y0), "weights"),
        ((g, w, torch.zeros(2, 2)), "y0"),
        ((g, w, y0, torch.zeros(2, 3, 1)), "dy0"),
        ((g, w.double(), y0), "weights"),
        ((g.long(), w, y0), "goal"),
        ((g, None, y0), "weights"),
        (([[0.0]], w, y0), "goal"),
    ]
    for args, word in cases:
        with pytest.raises(ValueError, match=word):
            layer(*args)
    with pytest.raises(ValueError, match="method"):
        dmp_rollout(g, w, y0, cfg=layer.config, method="rk4")


def test_non_finite_inputs_raise_by_default_and_check_is_available():
    layer = DMPLayer(n_basis=4, steps=10)
    g, y0, w = torch.zeros(2, 3), torch.zeros(2, 3), torch.zeros(2, 3, 4)
    bad = w.clone()
    bad[1, 2, 3] = float("nan")
    with pytest.raises(FloatingPointError, match="weights"):
        layer(g, bad, y0)
    with pytest.raises(FloatingPointError, match="goal"):
        layer(torch.full_like(g, float("inf")), w, y0)
    with pytest.raises(FloatingPointError, match="y0"):
        check_finite(goal=g, y0=torch.full_like(y0, float("nan")))
    # the unchecked path exists for callers that check themselves, and NaN propagates visibly
    out = DMPLayer(n_basis=4, steps=10, check_finite=False)(g, bad, y0)
    assert torch.isnan(out.pos).any()


def test_fit_bad_input():
    cfg = DMPConfig(n_basis=4, steps=10)
    with pytest.raises(ValueError, match="demo"):
        fit_dmp(torch.zeros(2, 5, 2), cfg)
    with pytest.raises(ValueError, match="demo"):
        fit_dmp(torch.full((2, 11, 2), float("nan")), cfg)
    with pytest.raises(ValueError, match="cfg"):
        fit_dmp(torch.zeros(2, 11, 2), dataclasses.replace(cfg, only_g=True))
    for bad in (-1e-3, float("nan"), float("inf"), "0.1", True):
        with pytest.raises(ValueError, match="ridge"):
            fit_dmp(torch.zeros(2, 11, 2), cfg, ridge=bad)


def test_unscaled_forcing_equals_scaled_forcing_with_amplitude_weights():
    """scale_by_goal=False with w' = w (g - y0) is the same DMP as the paper's form with w."""
    scaled = DMPConfig(n_basis=6, a_z=10.0, steps=35, subsample=7)
    unscaled = dataclasses.replace(scaled, scale_by_goal=False)
    gen = torch.Generator().manual_seed(4)
    goal, y0 = torch.randn(3, 2, generator=gen), torch.randn(3, 2, generator=gen)
    w = torch.randn(3, 2, 6, generator=gen)
    a = dmp_rollout(goal, w, y0, None, scaled).pos
    b = dmp_rollout(goal, w * (goal - y0).unsqueeze(-1), y0, None, unscaled).pos
    torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5)
    # and its gradients stay finite where g == y0 (no division anywhere)
    goal_eq = y0.clone().requires_grad_(True)
    amp = torch.randn(3, 2, 6, generator=gen, requires_grad=True)
    dmp_rollout(goal_eq, amp, y0, None, unscaled).pos.square().sum().backward()
    assert torch.isfinite(goal_eq.grad).all() and amp.grad.abs().sum() > 0
