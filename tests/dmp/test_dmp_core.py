"""Properties of the DMP integrators: start, convergence, ablations, batching, paths agree."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from ndp.dmp import (
    RBF_KINDS,
    DMPConfig,
    DMPLayer,
    basis_centres,
    canonical_phase,
    dmp_rollout,
    dmp_rollout_fast,
    dmp_rollout_reference,
    normalised_rbf,
)


def _inputs(b=5, d=3, n=30, dtype=torch.float64, seed=0, wscale=20.0, requires_grad=False):
    gen = torch.Generator().manual_seed(seed)
    goal = torch.randn(b, d, generator=gen, dtype=dtype)
    w = torch.randn(b, d, n, generator=gen, dtype=dtype) * wscale
    y0 = torch.randn(b, d, generator=gen, dtype=dtype)
    dy0 = torch.randn(b, d, generator=gen, dtype=dtype)
    ts = (goal, w, y0, dy0)
    if requires_grad:
        ts = tuple(t.clone().requires_grad_(True) for t in ts)
    return ts


CONFIGS = [
    DMPConfig(),
    DMPConfig(n_basis=6, a_z=10.0, steps=35, subsample=7),
    DMPConfig(n_basis=5, a_z=15.0, steps=40, subsample=8, forcing="supplement"),
    DMPConfig(n_basis=10, a_z=25.0, steps=50, tau=2.0, a_x=2.0, b_z=5.0),
    DMPConfig(n_basis=7, steps=30, dt=0.05),
    DMPConfig(n_basis=6, steps=35, only_g=True),
    DMPConfig(n_basis=6, a_z=10.0, steps=35, subsample=7, scale_by_goal=False),
] + [DMPConfig(n_basis=8, steps=60, rbf=k) for k in RBF_KINDS if k != "gaussian"]


@pytest.mark.parametrize("cfg", CONFIGS, ids=lambda c: f"N{c.n_basis}-{c.rbf}-{c.forcing}")
@pytest.mark.parametrize("path", ["reference", "fast"])
def test_starts_exactly_at_y0_and_dy0(cfg, path):
    goal, w, y0, dy0 = _inputs(n=cfg.n_basis)
    fn = dmp_rollout_reference if path == "reference" else dmp_rollout_fast
    traj = fn(goal, w, y0, dy0, cfg)
    assert traj.pos.shape == (5, cfg.n_out, 3)
    assert torch.equal(traj.pos[:, 0], y0)
    assert torch.allclose(traj.vel[:, 0], dy0, rtol=0, atol=1e-15)
    assert torch.equal(traj.acc[:, 0], torch.zeros_like(y0))


@pytest.mark.parametrize("forcing", ["released", "supplement"])
def test_zero_weights_converge_to_goal(forcing):
    # Long horizon so that the critically damped spring has settled.
    cfg = DMPConfig(n_basis=10, a_z=25.0, steps=2000, dt=0.005, forcing=forcing)
    goal, w, y0, dy0 = _inputs(n=10)
    traj = dmp_rollout(goal, torch.zeros_like(w), y0, dy0, cfg)
    assert torch.allclose(traj.pos[:, -1], goal, atol=1e-6)
    assert traj.vel[:, -1].abs().max() < 1e-4


def test_nonzero_weights_still_reach_goal_as_phase_vanishes():
    cfg = DMPConfig(n_basis=10, a_z=25.0, a_x=8.0, steps=3000, dt=0.005)
    goal, w, y0, dy0 = _inputs(n=10)
    traj = dmp_rollout(goal, w, y0, dy0, cfg)
    assert torch.allclose(traj.pos[:, -1], goal, atol=1e-4)


@pytest.mark.parametrize("method", ["loop", "fast"])
def test_only_g_equals_zero_weights(method):
    base = DMPConfig(n_basis=6, steps=35, subsample=7)
    goal, w, y0, dy0 = _inputs(n=6)
    a = dmp_rollout(goal, w, y0, dy0, dataclasses.replace(base, only_g=True), method=method)
    b = dmp_rollout(goal, torch.zeros_like(w), y0, dy0, base, method=method)
    c = dmp_rollout(goal, None, y0, dy0, dataclasses.replace(base, only_g=True), method=method)
    for fa, fb, fc in zip(a, b, c, strict=True):
        assert torch.allclose(fa, fb, atol=1e-12)
        assert torch.allclose(fa, fc, atol=1e-12)
    # and the weights really matter when the forcing term is on
    d = dmp_rollout(goal, w, y0, dy0, base, method=method)
    assert (d.pos - b.pos).abs().max() > 1e-2


@pytest.mark.parametrize("kind", RBF_KINDS)
@pytest.mark.parametrize("n", [1, 5, 30])
def test_every_rbf_kind_is_normalised(kind, n):
    c, h = basis_centres(n, 1.0)
    x = canonical_phase(DMPConfig(steps=300))[1:]
    phi = normalised_rbf(x, c, h, kind)
    assert phi.shape == (300, n)
    assert torch.allclose(phi.sum(-1), torch.ones(300, dtype=phi.dtype), atol=1e-12)
    if kind != "linear":  # linear is 0 at its own centre; others strictly positive
        assert (phi > 0).all()


def test_centres_and_widths_follow_the_paper():
    c, h = basis_centres(4, 2.0)
    expect_c = np.exp(-2.0 * np.linspace(0, 1, 4))
    np.testing.assert_allclose(c.numpy(), expect_c)
    np.testing.assert_allclose(h.numpy(), 4**1.5 / (expect_c * 2.0))


def test_each_gaussian_peaks_at_its_centre():
    c, h = basis_centres(10, 1.0)
    phi = normalised_rbf(c, c, h, "gaussian")  # evaluate at every centre
    assert phi.argmax(-1).tolist() == list(range(10))


@pytest.mark.parametrize("method", ["loop", "fast"])
def test_batch_invariance(method):
    cfg = DMPConfig(n_basis=6, steps=35, subsample=7)
    goal, w, y0, dy0 = _inputs(b=7, n=6, dtype=torch.float64)
    full = dmp_rollout(goal, w, y0, dy0, cfg, method=method)
    for i in range(7):
        one = dmp_rollout(
            goal[i : i + 1], w[i : i + 1], y0[i : i + 1], dy0[i : i + 1], cfg, method=method
        )
        for f_full, f_one in zip(full, one, strict=True):
            torch.testing.assert_close(f_full[i : i + 1], f_one, rtol=1e-12, atol=1e-12)
    # changing the other samples leaves sample 0 alone
    w2 = w.clone()
    w2[1:] *= 3.0
    other = dmp_rollout(goal, w2, y0, dy0, cfg, method=method)
    assert torch.equal(other.pos[0], full.pos[0])
    assert (other.pos[1] - full.pos[1]).abs().max() > 1e-3


@pytest.mark.parametrize("cfg", CONFIGS, ids=lambda c: f"N{c.n_basis}-{c.rbf}-{c.forcing}")
@pytest.mark.parametrize(
    "dtype,tol", [(torch.float32, 1e-5), (torch.float64, 1e-10)], ids=["f32", "f64"]
)
def test_fast_path_equals_reference_loop_values_and_gradients(cfg, dtype, tol):
    # Magnitudes typical of the use cases (unit-scale states, weights of tens).
    inputs_a = _inputs(n=cfg.n_basis, dtype=dtype, requires_grad=True, wscale=5.0)
    inputs_b = tuple(t.detach().clone().requires_grad_(True) for t in inputs_a)
    ref = dmp_rollout_reference(*inputs_a, cfg)
    fast = dmp_rollout_fast(*inputs_b, cfg)
    for name, fr, ff in zip(("pos", "vel", "acc"), ref, fast, strict=True):
        scale = max(1.0, fr.abs().max().item())
        err = (fr - ff).abs().max().item() / scale
        assert err < tol, f"{name}: relative difference {err:.2e} >= {tol}"
    gen = torch.Generator().manual_seed(1)
    cot = [torch.randn(fr.shape, generator=gen, dtype=dtype) for fr in ref]
    loss_r = sum((fr * c).sum() for fr, c in zip(ref[:2], cot, strict=False))
    loss_f = sum((ff * c).sum() for ff, c in zip(fast[:2], cot, strict=False))
    grads_r = torch.autograd.grad(loss_r, inputs_a, allow_unused=True)
    grads_f = torch.autograd.grad(loss_f, inputs_b, allow_unused=True)
    for name, gr, gf in zip(("goal", "weights", "y0", "dy0"), grads_r, grads_f, strict=True):
        if gr is None:
            assert gf is None or gf.abs().max() == 0
            continue
        scale = max(1.0, gr.abs().max().item())
        err = (gr - gf).abs().max().item() / scale
        assert err < tol, f"d/d{name}: relative difference {err:.2e} >= {tol}"


def test_gradcheck_float64_both_paths():
    cfg = DMPConfig(n_basis=4, a_z=10.0, steps=20, subsample=4)
    inputs = _inputs(b=2, d=2, n=4, requires_grad=True, wscale=1.0)

    for fn in (dmp_rollout_reference, dmp_rollout_fast):

        def f(g, w, y0, dy0, fn=fn):
            t = fn(g, w, y0, dy0, cfg)
            return t.pos, t.vel, t.acc

        assert torch.autograd.gradcheck(f, inputs, eps=1e-6, atol=1e-7, rtol=1e-6)


def test_learned_az_is_clamped_and_differentiable():
    cfg = DMPConfig(n_basis=6, steps=35, subsample=7, learn_az=True)
    goal, w, y0, dy0 = _inputs(b=3, n=6)
    a_z = torch.tensor([0.01, 12.0, 100.0], dtype=torch.float64, requires_grad=True)
    layer = DMPLayer(cfg)
    traj = layer(goal, w, y0, dy0, a_z=a_z)
    fixed = [
        dmp_rollout(
            goal[i : i + 1],
            w[i : i + 1],
            y0[i : i + 1],
            dy0[i : i + 1],
            dataclasses.replace(cfg, learn_az=False, a_z=v),
        )
        for i, v in enumerate([0.5, 12.0, 30.0])
    ]
    for i, f in enumerate(fixed):
        torch.testing.assert_close(traj.pos[i : i + 1], f.pos, rtol=1e-10, atol=1e-10)
    traj.pos.sum().backward()
    assert a_z.grad is not None
    assert a_z.grad[0] == 0 and a_z.grad[2] == 0  # clamped ends carry no gradient
    assert a_z.grad[1] != 0
    # learned a_z needs the per-sample tensor, and a fixed-a_z config refuses one
    with pytest.raises(ValueError, match="a_z"):
        layer(goal, w, y0, dy0)
    with pytest.raises(ValueError, match="a_z"):
        DMPLayer(n_basis=6)(goal, w, y0, dy0, a_z=a_z)


def test_per_dof_learned_az():
    cfg = DMPConfig(n_basis=6, steps=35, learn_az=True)
    goal, w, y0, dy0 = _inputs(b=2, d=3, n=6)
    a_z = torch.tensor([[5.0, 10.0, 20.0], [25.0, 25.0, 25.0]], dtype=torch.float64)
    traj = dmp_rollout(goal, w, y0, dy0, cfg, a_z=a_z)
    for j, v in enumerate([5.0, 10.0, 20.0]):
        ref = dmp_rollout(
            goal[:1, j : j + 1],
            w[:1, j : j + 1],
            y0[:1, j : j + 1],
            dy0[:1, j : j + 1],
            dataclasses.replace(cfg, learn_az=False, a_z=v),
        )
        torch.testing.assert_close(traj.pos[:1, :, j : j + 1], ref.pos)


def test_subsampling_picks_every_l_th_step():
    full_cfg = DMPConfig(n_basis=6, steps=35)
    sub_cfg = dataclasses.replace(full_cfg, subsample=7)
    goal, w, y0, dy0 = _inputs(n=6)
    full = dmp_rollout(goal, w, y0, dy0, full_cfg)
    sub = dmp_rollout(goal, w, y0, dy0, sub_cfg)
    assert sub.pos.shape[1] == 6
    for ff, fs in zip(full, sub, strict=True):
        torch.testing.assert_close(ff[:, ::7], fs)


def test_layer_is_parameter_free_and_follows_dtype():
    layer = DMPLayer(n_basis=6, steps=35, subsample=7)
    assert list(layer.parameters()) == []
    for dtype in (torch.float32, torch.float64):
        goal, w, y0, dy0 = _inputs(n=6, dtype=dtype)
        out = layer(goal, w, y0, dy0)
        assert out.pos.dtype == dtype and out.pos.device == goal.device
    assert "n_basis=6" in repr(layer)


@pytest.mark.parametrize("learn_az", [False, True])
def test_meta_tensors_infer_shapes_and_device_is_refused_at_once(learn_az):
    cfg = DMPConfig(n_basis=6, steps=35, subsample=7, learn_az=learn_az)
    with torch.device("meta"):
        layer = DMPLayer(cfg)  # checks on: meta tensors hold no values to check
        goal, y0, dy0 = (torch.zeros(4, 3) for _ in range(3))
        w = torch.zeros(4, 3, 6)
        a_z = torch.zeros(4) if learn_az else None
    out = layer(goal, w, y0, dy0, a_z=a_z)
    for t in out:
        assert t.is_meta and t.shape == (4, cfg.n_out, 3)
    if not learn_az:
        pos = layer.positions(goal, w, y0, dy0)
        assert pos.is_meta and pos.shape == (4, cfg.n_out, 3)
    for name in ("device", "dtype"):
        with pytest.raises(ValueError, match=f"^{name}: DMPLayer holds no parameters"):
            DMPLayer(cfg, **{name: "meta"})


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_cuda_matches_cpu():
    cfg = DMPConfig(n_basis=6, steps=35, subsample=7)
    goal, w, y0, dy0 = _inputs(n=6, dtype=torch.float32)
    cpu = dmp_rollout(goal, w, y0, dy0, cfg)
    gpu = dmp_rollout(goal.cuda(), w.cuda(), y0.cuda(), dy0.cuda(), cfg)
    assert gpu.pos.is_cuda
    torch.testing.assert_close(gpu.pos.cpu(), cpu.pos, rtol=1e-5, atol=1e-5)


def test_positions_only_equal_the_full_rollout():
    from ndp.dmp import DMPLayer, dmp_positions

    cfg = DMPConfig(n_basis=6, a_z=10.0, steps=35, subsample=7)
    g = torch.Generator().manual_seed(0)
    goal, y0, dy0 = (torch.randn(8, 4, generator=g) for _ in range(3))
    w = torch.randn(8, 4, 6, generator=g)
    full = dmp_rollout(goal, w, y0, dy0, cfg)
    torch.testing.assert_close(dmp_positions(goal, w, y0, dy0, cfg), full.pos)
    torch.testing.assert_close(DMPLayer(cfg).positions(goal, w, y0, dy0), full.pos)
    torch.testing.assert_close(full.pos[:, 0], y0)  # the RL head relies on it


def test_config_refuses_divergent_euler_settings():
    from ndp.dmp.config import euler_step_radius

    # the cases: a_z = 400 at 50 steps (dt 0.02, a_z dt = 8) and a_z = 1e6
    for a_z, steps in ((400.0, 50), (1e6, 300)):
        with pytest.raises(ValueError, match="diverges"):
            DMPConfig(a_z=a_z, steps=steps)
    DMPConfig(a_z=150.0, steps=50)  # a_z dt = 3 < 4: bounded
    assert euler_step_radius(100.0, 25.0, 1.0, 0.04) == pytest.approx(1.0)  # the boundary
    # a learned a_z is checked at the top of its clamp range
    with pytest.raises(ValueError, match="a_z"):
        DMPConfig(steps=5, learn_az=True, az_range=(0.5, 30.0), subsample=1)
    # and the bound is the real one: just below it the rollout stays finite, above it explodes
    g = torch.ones(1, 1)
    cfg = DMPConfig(a_z=190.0, steps=50)
    w = torch.zeros(1, 1, cfg.n_basis)
    y = dmp_rollout(g, w, torch.zeros(1, 1), cfg=cfg).pos
    assert float(y.abs().max()) < 10.0


@pytest.mark.parametrize("b,d", [(0, 2), (3, 0)])
@pytest.mark.parametrize("method", ["fast", "loop"])
def test_empty_batch_or_dof_gives_empty_results(b, d, method):
    cfg = DMPConfig(n_basis=5, steps=10)
    traj = dmp_rollout(torch.zeros(b, d), torch.zeros(b, d, 5), torch.zeros(b, d), cfg=cfg,
                       method=method)  # fmt: skip
    for t in (traj.pos, traj.vel, traj.acc):
        assert t.shape == (b, 11, d)


def test_finite_inputs_that_overflow_are_caught_at_the_outputs():
    cfg = DMPConfig(n_basis=5, steps=10, scale_by_goal=False)
    w = torch.full((1, 1, 5), 2.5e38)  # finite (their sum is not); the accelerations overflow
    with pytest.raises(FloatingPointError, match="outputs: the rollout is not finite"):
        DMPLayer(cfg)(torch.ones(1, 1), w, torch.zeros(1, 1))
    with pytest.raises(FloatingPointError, match="outputs"):
        dmp_rollout(torch.ones(1, 1), w, torch.zeros(1, 1), cfg=cfg, method="loop", check=True)
    big = DMPConfig(n_basis=5, steps=10)  # scale_by_goal: w * (g - y0) itself overflows
    with pytest.raises(FloatingPointError, match=r"w \* \(g - y0\) overflow"):
        DMPLayer(big)(torch.full((1, 1), 1e20), torch.full((1, 1, 5), 1e20), torch.zeros(1, 1))


def _torch_calls(fn):
    """Names of the torch functions and tensor methods ``fn`` calls."""
    from torch.overrides import TorchFunctionMode

    calls: list[str] = []

    class Record(TorchFunctionMode):
        def __torch_function__(self, func, types, args=(), kwargs=None):
            calls.append(getattr(func, "__name__", str(func)))
            return func(*args, **(kwargs or {}))

    with Record():
        fn()
    return calls


@pytest.mark.parametrize("positions", [False, True])
def test_the_finite_check_is_one_small_reduction_over_the_inputs(positions):
    # the default check must not reduce the [B, n_out, D] outputs on the common path (that cost
    # the layer 2x at B=256, D=7, N=10, 100 steps): one max |u| over the packed inputs bounds them
    cfg = DMPConfig(n_basis=10, steps=100)
    goal, w, y0, dy0 = _inputs(b=8, d=7, n=10, dtype=torch.float32)
    checked, unchecked = DMPLayer(cfg), DMPLayer(cfg, check_finite=False)
    call = "positions" if positions else "forward"
    for layer in (checked, unchecked):  # warm the caches (linear map, its gain)
        getattr(layer, call)(goal, w, y0, dy0)
    with_check = _torch_calls(lambda: getattr(checked, call)(goal, w, y0, dy0))
    without = _torch_calls(lambda: getattr(unchecked, call)(goal, w, y0, dy0))
    extra = list(with_check)
    for name in without:
        extra.remove(name)
    assert "isfinite" not in with_check, with_check
    # one reduction (amax of |u|, [B * D, N + 3]) read back once; attribute reads aside
    assert [n for n in extra if n in ("abs", "amax", "__float__")] == ["abs", "amax", "__float__"]
    assert set(extra) <= {"abs", "amax", "__float__", "detach", "numel", "__get__"}, extra
    # and the bound is sound: near the dtype's limit the outputs are checked exactly; the
    # layer never returns a non-finite rollout from finite inputs
    raw = DMPConfig(n_basis=5, steps=10, scale_by_goal=False)
    for scale in (1e30, 1e36, 1e37, 1e38, 2.5e38, 3.4e38):
        for sign in (1.0, -1.0):
            args = (torch.ones(2, 1), torch.full((2, 1, 5), sign * scale), torch.zeros(2, 1))
            try:
                out = getattr(DMPLayer(raw), call)(*args)
            except FloatingPointError as exc:
                assert "outputs" in str(exc)
                continue
            for t in out if isinstance(out, tuple) else (out,):
                assert torch.isfinite(t).all(), (scale, sign)
    if not positions:  # the accelerations overflow here (tests above: the message)
        with pytest.raises(FloatingPointError, match="outputs"):
            DMPLayer(raw)(torch.ones(1, 1), torch.full((1, 1, 5), 2.5e38), torch.zeros(1, 1))
    # NaN / Inf in any input, or in w * (g - y0), still raise naming the culprit
    for i, name in enumerate(("goal", "weights", "y0", "dy0")):
        bad = [t.clone() for t in (goal, w, y0, dy0)]
        bad[i].view(-1)[3] = float("nan") if i % 2 else float("-inf")
        with pytest.raises(FloatingPointError, match=name):
            getattr(checked, call)(*bad)


def test_a_misspelt_layer_override_names_the_close_field():
    with pytest.raises(ValueError, match=r"^n_basiss: not a DMPConfig field; close names: n_basis"):
        DMPLayer(n_basiss=3)
    with pytest.raises(ValueError, match=r"^colour: not a DMPConfig field; known: n_basis, a_z"):
        DMPLayer(colour="red")
    assert DMPLayer(DMPConfig(n_basis=4), steps=20).config.steps == 20  # real fields still work
