"""Action heads, distributions and the k-head critic."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from ndp.dmp import DMPConfig, dmp_rollout
from ndp.envs import get_task_spec
from ndp.envs.point_mass import ACTION_SCALE, CONTROL_DT
from ndp.envs.spec import toy_spec as point_mass_spec
from ndp.policies import (
    NDPHeadConfig,
    ParamGaussian,
    PolicyConfig,
    SubActionGaussian,
    build_actor_critic,
    build_head,
    diag_gaussian_entropy,
    diag_gaussian_log_prob,
)


def _cfg(head, **kw):
    base = {"n_basis": 6, "a_z": 15.0, "dmp_steps": 35, "goal_scale": 1.0, "weight_scale": 50.0}
    if head != "ndp":
        base = {}
    return PolicyConfig(head=head, k=1 if head == "step" else 5).updated(**{**base, **kw})


def test_gaussian_log_prob_and_entropy_match_torch():
    mean = torch.randn(4, 3, 2)
    log_std = torch.tensor([0.3, -0.7])
    x = torch.randn(4, 3, 2)
    ref = torch.distributions.Normal(mean, log_std.exp())
    torch.testing.assert_close(diag_gaussian_log_prob(x, mean, log_std), ref.log_prob(x).sum(-1))
    torch.testing.assert_close(diag_gaussian_entropy(log_std, mean.shape), ref.entropy().sum(-1))


@pytest.mark.parametrize("head,k", [("step", 1), ("multi", 5), ("ndp", 5)])
def test_heads_shapes_and_per_substep_logprobs(head, k):
    spec = point_mass_spec()
    ac = build_actor_critic(6, spec, _cfg(head))
    obs = torch.randn(8, 6)
    y0, dy0 = torch.rand(8, 2) - 0.5, torch.zeros(8, 2)
    dist, _ = ac.distribution(obs, y0, dy0)
    assert isinstance(dist, SubActionGaussian)
    z = dist.sample()
    assert z.shape == (8, k, 2)
    assert dist.log_prob(z).shape == (8, k)
    assert dist.entropy().shape == (8, k)
    assert dist.actions(z).shape == (8, k, 2)
    assert ac.value(obs).shape == (8, k)
    # initial std 1
    assert torch.allclose(ac.head.log_std.exp(), torch.ones(2))


def test_ndp_head_zero_output_keeps_robot_still_and_goal_is_bounded():
    spec = point_mass_spec()
    ac = build_actor_critic(6, spec, _cfg("ndp"))
    head = ac.head
    y0 = torch.tensor([[0.2, -0.1]])
    dy0 = torch.zeros(1, 2)
    acts, goal, w = head.decode(torch.zeros(1, head.n_params), y0, dy0)
    torch.testing.assert_close(goal, y0)
    assert float(w.abs().max()) == 0.0
    assert float(acts.abs().max()) < 1e-6
    huge = torch.full((1, head.n_params), 1e6)
    acts, goal, w = head.decode(huge, y0, dy0)
    reach = 5 * ACTION_SCALE  # goal_scale 1 * k * action_scale
    assert float((goal - y0).abs().max()) <= reach + 1e-6
    assert float(w.abs().max()) <= 50.0 * reach + 1e-4  # 'amplitude' forcing: w <= s * reach
    # the means are not clipped (only the executed sample is, by the trainer) ...
    assert float(acts.abs().max()) > 1.0 and bool(torch.isfinite(acts).all())
    # ... unless asked for (the first release's form)
    clipped = build_actor_critic(6, spec, _cfg("ndp", mean_clip=True)).head
    acts_c, _, _ = clipped.decode(huge, y0, dy0)
    assert float(acts_c.abs().max()) <= 1.0


def test_ndp_mean_clip_biases_the_executed_displacement():
    """E[clip(mean + noise)] at a saturated mean: PPO-like unclipped means reach further."""
    spec = point_mass_spec()
    y0, dy0 = torch.zeros(1, 2), torch.zeros(1, 2)
    raw = torch.full((1, 14), 3.0)
    gen = torch.Generator().manual_seed(0)
    executed = {}
    for mean_clip in (True, False):
        head = build_actor_critic(6, spec, _cfg("ndp", mean_clip=mean_clip, goal_scale=2.0)).head
        dist, _ = head.distribution(raw, y0, dy0)
        z = torch.stack([dist.sample(gen) for _ in range(2000)])
        executed[mean_clip] = float(z.clamp(-1, 1).mean())
    assert executed[False] > executed[True] + 0.1


def test_ndp_head_integrates_from_physical_state_with_time_conversion():
    spec = point_mass_spec()
    cfg = _cfg("ndp", a_z=1.0, dmp_velocity="state")
    head = build_actor_critic(6, spec, cfg).head
    y0 = torch.tensor([[0.0, 0.0]])
    v = torch.tensor([[0.4, -0.2]])  # m/s (physical)
    acts, goal, w = head.decode(torch.zeros(1, head.n_params), y0, v)
    # goal = y0, w = 0: the spring only brakes the initial velocity; the first sub-step moves
    # about v * control_dt (a little less because of the spring with a_z = 1).
    first_disp = acts[0, 0] * ACTION_SCALE
    expected = v[0] * CONTROL_DT
    assert torch.all((first_disp / expected) > 0.8) and torch.all((first_disp / expected) <= 1.0)
    # Same thing computed directly with the DMP in DMP time units.
    traj = dmp_rollout(
        goal, w, y0, v * 5 * CONTROL_DT, DMPConfig(n_basis=6, a_z=1.0, steps=35, subsample=7)
    ).pos
    torch.testing.assert_close(acts, spec.inverse_controller(traj))
    # the default starts at rest: no motion at all from a zero output
    rest = build_actor_critic(6, spec, _cfg("ndp", a_z=1.0)).head
    acts0, _, _ = rest.decode(torch.zeros(1, rest.n_params), y0, v)
    assert float(acts0.abs().max()) == 0.0


def test_ndp_head_gradients_reach_actor_through_dmp():
    spec = point_mass_spec()
    ac = build_actor_critic(6, spec, _cfg("ndp"))
    obs = torch.randn(16, 6)
    y0 = torch.rand(16, 2) - 0.5
    dist, _ = ac.distribution(obs, y0, torch.zeros(16, 2))
    target = torch.full((16, 5, 2), 0.3)
    dist.log_prob(target).sum().backward()
    assert float(ac.actor.net[0].weight.grad.abs().sum()) > 0


def test_ndp_param_noise_one_logprob_per_decision():
    spec = point_mass_spec()
    ac = build_actor_critic(6, spec, _cfg("ndp", param_noise=True))
    dist, _ = ac.distribution(torch.randn(4, 6), torch.zeros(4, 2), torch.zeros(4, 2))
    assert isinstance(dist, ParamGaussian)
    z = dist.sample()
    assert z.shape == (4, ac.head.n_params) == (4, 2 * 7)
    assert dist.log_prob(z).shape == (4, 1)
    assert dist.entropy().shape == (4, 1)
    a = dist.actions(z)
    assert a.shape == (4, 5, 2) and bool(torch.isfinite(a).all())


@pytest.mark.parametrize("forcing,min_ratio", [("amplitude", 1e-2), ("goal", 0.0)])
def test_ndp_goal_and_weight_gradients_at_init(forcing, min_ratio):
    """At initialisation both the goal and the forcing weights get a gradient; with the paper's
    f proportional to (g - y0) the weights' share is tiny (g starts at y0)."""
    spec = get_task_spec("push-v3")
    torch.manual_seed(0)
    ac = build_actor_critic(39, spec, _cfg("ndp", forcing=forcing))
    raw = ac.actor(torch.randn(64, 39)).detach().requires_grad_(True)
    y0 = torch.tensor([[0.0, 0.6, 0.2, -1.0]]).expand(64, 4)
    acts, _, _ = ac.head.decode(raw, y0, torch.zeros(64, 4))
    (acts[..., :3] * torch.linspace(-1, 1, 5).view(1, 5, 1)).sum().backward()
    g_goal = float(raw.grad[:, :3].abs().mean())
    g_w = float(raw.grad[:, 4:].reshape(64, 4, 6)[:, :3].abs().mean())
    assert g_goal > 0 and g_w > 0
    ratio = g_w / g_goal
    if forcing == "amplitude":
        assert ratio > min_ratio
    else:
        assert ratio < 1e-2  # the handicap the 'amplitude' form removes


def test_ndp_gripper_direct_command_ignores_previous_noise():
    """'direct': the gripper command of every sub-step is the decision's goal, whatever the last
    sampled command (y0) was; 'dmp' (the first release) starts from it."""
    spec = get_task_spec("push-v3")
    torch.manual_seed(1)
    raw = torch.randn(3, 4 * 7)
    base = torch.tensor([[0.0, 0.6, 0.2, 0.0]]).repeat(3, 1)
    noisy = base.clone()
    noisy[:, 3] = torch.tensor([-1.0, 0.3, 1.0])
    for mode, same in (("direct", True), ("dmp", False)):
        head = build_actor_critic(39, spec, _cfg("ndp", absolute_mode=mode)).head
        a1, g1, _ = head.decode(raw, base, torch.zeros(3, 4))
        a2, _, _ = head.decode(raw, noisy, torch.zeros(3, 4))
        assert torch.equal(a1[..., 3], a2[..., 3]) is same
        torch.testing.assert_close(a1[..., :3], a2[..., :3])  # xyz unaffected
        if mode == "direct":
            torch.testing.assert_close(a1[..., 3], g1[:, 3:].expand(3, 5))


def test_metaworld_ndp_head_gripper_goal_is_absolute_and_bounded():
    spec = get_task_spec("push-v3")
    ac = build_actor_critic(39, spec, _cfg("ndp"))
    gs = ac.head.goal_scale
    assert torch.allclose(gs[:3], torch.full((3,), 5 * 0.01))
    assert math.isclose(float(gs[3]), 1.0)  # half of the gripper command range [-1, 1]
    y0 = torch.tensor([[0.0, 0.6, 0.2, -0.7], [0.0, 0.6, 0.2, 0.9]])
    dy0 = torch.tensor([[0.0, 0.0, 0.0, 50.0], [0.0, 0.0, 0.0, -50.0]])  # noisy command rates
    acts, goal, _ = ac.head.decode(torch.zeros(2, ac.head.n_params), y0, dy0)
    assert acts.shape == (2, 5, 4)
    # the gripper goal does not depend on the (unobserved) last sampled command, nor on its rate
    torch.testing.assert_close(goal[:, 3], torch.zeros(2))
    assert float(acts[..., 3].abs().max()) <= 1.0  # the command range, with or without a clip
    huge = torch.full((2, ac.head.n_params), 50.0)
    _, goal, _ = ac.head.decode(huge, y0, dy0)
    torch.testing.assert_close(goal[:, 3], torch.ones(2))
    # relative form (the release's): the goal follows y0 and spans the whole range from it
    rel = build_actor_critic(39, spec, _cfg("ndp", absolute_goal=False)).head
    _, goal, _ = rel.decode(torch.zeros(2, rel.n_params), y0, dy0)
    torch.testing.assert_close(goal[:, 3], y0[:, 3])
    assert math.isclose(float(rel.goal_scale[3]), 2.0)


def test_policy_config_rejects_bad_values():
    with pytest.raises(ValueError, match="head"):
        PolicyConfig(head="dmp")
    with pytest.raises(ValueError, match="k"):
        PolicyConfig(k=0)
    with pytest.raises(ValueError, match="n_basis"):
        NDPHeadConfig(n_basis=0)
    with pytest.raises(ValueError, match="dmp_steps: expected a positive multiple of k=5"):
        PolicyConfig(k=5, ndp=NDPHeadConfig(dmp_steps=36))
    with pytest.raises(ValueError, match="param_noise"):
        PolicyConfig(head="multi", ndp=NDPHeadConfig(param_noise=True))
    with pytest.raises(ValueError, match="forcing"):
        NDPHeadConfig(forcing="raw")
    with pytest.raises(ValueError, match="absolute_mode"):
        NDPHeadConfig(absolute_mode="plan")
    with pytest.raises(ValueError, match="dmp_state"):
        PolicyConfig(dmp_state="mocap")
    with pytest.raises(ValueError, match="hidden_gain"):
        PolicyConfig(hidden_gain=0.0)
    with pytest.raises(ValueError, match="ndp: expected an NDPHeadConfig"):
        PolicyConfig(ndp={"n_basis": 3})  # type: ignore[arg-type]


def test_ndp_fields_nest_and_the_flat_form_of_older_configs_still_reads():
    nested = PolicyConfig(k=5, ndp=NDPHeadConfig(n_basis=6, forcing="goal", dmp_steps=35))
    d = nested.to_dict()
    assert d["ndp"]["n_basis"] == 6 and "n_basis" not in d  # one place for the head's fields
    assert PolicyConfig.from_dict(d) == nested
    flat = {k: v for k, v in d.items() if k != "ndp"} | d["ndp"]  # a config.json before
    assert PolicyConfig.from_dict(flat) == nested
    assert nested.updated(n_basis=7, k=7, dmp_steps=49) == PolicyConfig(
        k=7, ndp=NDPHeadConfig(n_basis=7, forcing="goal", dmp_steps=49)
    )
    with pytest.raises(ValueError, match="n_basis given both flat and under 'ndp'"):
        PolicyConfig.from_dict({"n_basis": 3, "ndp": {"n_basis": 4}})
    with pytest.raises(ValueError, match=r"policy: .*nbasis"):
        PolicyConfig.from_dict({"nbasis": 3})
    with pytest.raises(ValueError, match="policy: no field nbasis"):
        nested.updated(nbasis=3)


def test_the_head_config_is_the_one_map_to_the_dmp_config():
    head = NDPHeadConfig(n_basis=6, a_z=15.0, dmp_steps=35, goal_scale=1.0, weight_scale=50.0,
                         rbf="linear", only_g=True)  # fmt: skip
    dmp = head.dmp_config(5)
    assert (dmp.n_basis, dmp.a_z, dmp.steps, dmp.subsample, dmp.rbf) == (6, 15.0, 35, 7, "linear")
    assert dmp.only_g and not dmp.learn_az and not dmp.scale_by_goal  # amplitude forcing
    assert dataclasses.replace(head, forcing="goal").dmp_config(5).scale_by_goal
    with pytest.raises(ValueError, match="dmp_steps: expected a multiple of k=3"):
        head.dmp_config(3)
    with pytest.raises(ValueError, match="NDP fields must be resolved"):
        NDPHeadConfig().dmp_config(5)
    # the head built from a policy config runs that DMP
    built = build_head(PolicyConfig(k=5, ndp=head), point_mass_spec())
    assert built.dmp.config == dmp


@pytest.mark.parametrize("task", ["push-v3", "throw", "point-mass"])
@pytest.mark.parametrize(
    "opts",
    [
        {},
        {"mean_clip": True},
        {"forcing": "goal"},
        {"absolute_mode": "dmp"},
        {"dmp_velocity": "state"},
        {"absolute_goal": False, "absolute_mode": "dmp"},
    ],
)
def test_fused_decode_equals_the_composed_dmp_and_controller(task, opts):
    """The folded map (DMP + inverse controller + direct command in one matmul per DoF) gives
    the composed path's actions and gradients."""
    spec = get_task_spec(task)
    torch.manual_seed(0)
    ac = build_actor_critic(spec.obs_dim, spec, _cfg("ndp", **opts))
    head = ac.head
    assert head._fused
    raw = (2.0 * torch.randn(9, head.n_params)).requires_grad_(True)
    y0 = torch.randn(9, spec.dmp_dofs) * 0.3
    dy0 = torch.randn(9, spec.dmp_dofs)
    fast, g1, w1 = head.decode(raw, y0, dy0)
    ref, g2, w2 = head.decode_reference(raw, y0, dy0)
    torch.testing.assert_close(fast, ref, rtol=1e-4, atol=1e-4)  # float32 rounding / scale
    torch.testing.assert_close(g1, g2)
    torch.testing.assert_close(w1, w2)
    weights = torch.randn_like(fast)
    (gf,) = torch.autograd.grad((fast * weights).sum(), raw)
    (gr,) = torch.autograd.grad((ref * weights).sum(), raw)
    torch.testing.assert_close(gf, gr, rtol=1e-4, atol=1e-5)


def test_ndp_checkpoints_hold_only_learned_state_and_old_ones_load():
    """Derived buffers (bounds, maps) are not saved; state dicts of earlier versions, which
    saved some of them, still load."""
    spec = get_task_spec("push-v3")
    ac = build_actor_critic(39, spec, _cfg("ndp"))
    sd = ac.state_dict()
    assert not any(k.startswith("head.") and k != "head.log_std" for k in sd)
    legacy = dict(sd)
    legacy["head.goal_scale"] = torch.ones(4)
    legacy["head.absolute_goal"] = torch.zeros(4, dtype=torch.bool)
    legacy["head.goal_center"] = torch.zeros(4)
    fresh = build_actor_critic(39, spec, _cfg("ndp"))
    fresh.load_state_dict(legacy)  # strict: no unexpected / missing keys
    assert torch.equal(fresh.head.goal_scale, ac.head.goal_scale)  # recomputed, not loaded


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_heads_and_noise_on_cuda():
    spec = get_task_spec("push-v3")
    ac = build_actor_critic(39, spec, _cfg("ndp")).cuda()
    dist, _ = ac.distribution(
        torch.randn(8, 39, device="cuda"),
        torch.zeros(8, 4, device="cuda"),
        torch.zeros(8, 4, device="cuda"),
    )
    z = dist.sample()
    assert z.device.type == "cuda" and dist.log_prob(z).shape == (8, 5)


def test_ndp_only_g_outputs_goals_only_and_equals_a_zero_forcing_dmp():
    spec = get_task_spec("push-v3")
    torch.manual_seed(3)
    full = build_actor_critic(39, spec, _cfg("ndp")).head
    only = build_actor_critic(39, spec, _cfg("ndp", only_g=True)).head
    assert only.n_params == 4 and full.n_params == 4 * 7
    raw_g = torch.randn(5, 4)
    y0 = torch.tensor([[0.0, 0.6, 0.2, -1.0]]).expand(5, 4)
    raw_full = torch.cat([raw_g, torch.zeros(5, 4 * 6)], dim=1)  # tanh(0) = 0: no forcing
    a_only, _, w = only.decode(raw_g, y0, torch.zeros(5, 4))
    a_full, _, _ = full.decode(raw_full, y0, torch.zeros(5, 4))
    torch.testing.assert_close(a_only, a_full)
    assert float(w.abs().max()) == 0.0


def test_ndp_learned_a_z_starts_at_the_preset_and_gets_a_gradient():
    spec = get_task_spec("push-v3")
    torch.manual_seed(4)
    fixed = build_actor_critic(39, spec, _cfg("ndp")).head
    learned = build_actor_critic(39, spec, _cfg("ndp", learn_az=True)).head
    assert learned.n_params == fixed.n_params + 1 and not learned._fused
    raw = torch.randn(6, fixed.n_params)
    y0 = torch.tensor([[0.0, 0.6, 0.2, -1.0]]).expand(6, 4)
    raw_az = torch.cat([raw, torch.zeros(6, 1)], dim=1).requires_grad_(True)
    preset = float(fixed.dmp.config.a_z)
    torch.testing.assert_close(learned.a_z_of(raw_az), torch.full((6,), preset))
    a_l, _, _ = learned.decode(raw_az, y0, torch.zeros(6, 4))
    a_f, _, _ = fixed.decode(raw, y0, torch.zeros(6, 4))
    torch.testing.assert_close(a_l, a_f, atol=1e-5, rtol=1e-4)  # loop vs folded map, same a_z
    a_l[..., :3].sum().backward()
    assert float(raw_az.grad[:, -1].abs().max()) > 0  # the spring constant learns
    big = learned.a_z_of(torch.full((1, learned.n_params), 100.0))
    assert 29.9 < float(big) <= 30.0  # within the clamp range


@pytest.mark.parametrize("flag", ["--only-g", "--learn-az"])
def test_ablation_switches_train_through_the_cli(tmp_path, flag):
    from ndp.cli import main

    assert main(["rl", "train", "--task", "point-mass", "--steps", "520", "--steps-per-update",
                 "512", "--minibatches", "4", "--vector", "sync", "--run-dir", str(tmp_path / "r"),
                 "--no-progress", "--no-tensorboard", flag]) == 0  # fmt: skip


@pytest.mark.parametrize("task", ["push-v3", "throw", "point-mass"])
@pytest.mark.parametrize(
    "opts",
    [
        {},
        {"mean_clip": True},
        {"forcing": "goal"},
        {"absolute_mode": "dmp"},
        {"dmp_velocity": "zero"},
        {"param_map": "linear"},
        {"param_noise": True},
    ],
)
def test_the_no_grad_decode_and_forward_equal_the_autograd_ones_bit_for_bit(task, opts):
    """Rollouts (no autograd) take the head's short form of the fused map and the MLPs' layer
    functions: the same bits as the update's path, diagnostics included."""
    spec = get_task_spec(task)
    torch.manual_seed(1)
    ac = build_actor_critic(spec.obs_dim, spec, _cfg("ndp", **opts))
    obs = 3.0 * torch.randn(7, spec.obs_dim)
    y0 = torch.randn(7, spec.dmp_dofs) * 0.3
    dy0 = torch.randn(7, spec.dmp_dofs)
    with torch.no_grad():
        raw, v = ac.actor.net(obs), ac.critic.net(obs)  # the modules themselves
        dist, aux = ac.distribution(obs, y0, dy0)
        assert torch.equal(ac.value(obs), v)
        actions, goal, weights = ac.head.decode(raw, y0, dy0)
        loose = ac.head.decode(raw, y0, dy0, bounded=False)
    ref = ac.head.decode(raw, y0, dy0)  # autograd on: the update's form
    ref_loose = ac.head.decode(raw, y0, dy0, bounded=False)
    for a, b in zip((actions, goal, weights, *loose), (*ref, *ref_loose), strict=True):
        assert torch.equal(a, b.detach())
    assert torch.equal(aux["goal_norm"], (ref[1] - y0).norm(dim=-1))
    assert torch.equal(aux["weight_norm"], ref[2].detach().flatten(1).norm(dim=-1))
    assert torch.equal(dist.mean, raw if ac.head.param_noise else actions)


def test_mlp_forward_falls_back_to_the_module_off_its_plain_form():
    """mlp_forward calls the module itself with autograd on, or for a LayerNorm / GELU MLP."""
    from ndp.nets.mlp import MLP
    from ndp.policies.actor_critic import mlp_forward

    x = torch.randn(5, 6)
    for mlp in (MLP(6, (8,), 3, "relu"), MLP(6, (8,), 3, layer_norm=True), MLP(6, (8,), 3, "gelu")):
        with torch.no_grad():
            assert torch.equal(mlp_forward(mlp, x), mlp(x))
        assert mlp_forward(mlp, x).requires_grad


@pytest.mark.parametrize(
    ("xd", "sd"), [(torch.float32, torch.float32), (torch.float64, torch.float64),
                   (torch.float32, torch.float64)]
)  # fmt: skip
def test_the_no_grad_log_prob_equals_the_autograd_one_bit_for_bit(xd, sd):
    torch.manual_seed(2)
    x, mean = (torch.randn(6, 5, 3, dtype=xd) * 7 for _ in range(2))
    x[0, 0, 0] = float("nan")
    log_std = (torch.randn(3, dtype=sd) * 3).requires_grad_(True)
    ref = diag_gaussian_log_prob(x, mean, log_std).detach()
    with torch.no_grad():
        fast = diag_gaussian_log_prob(x, mean, log_std)
    assert fast.dtype == ref.dtype and torch.equal(fast.nan_to_num(), ref.nan_to_num())
    assert torch.equal(fast.isnan(), ref.isnan())
