"""The conditioning of the NDP head's map (issue 59): its Jacobian, the diagnostic's condition
number, and the 'linear' and 'whitened' parameter maps."""

from __future__ import annotations

import copy
import math

import pytest
import torch

from ndp.envs import get_task_spec
from ndp.policies import PolicyConfig, build_actor_critic
from ndp.policies.conditioning import (
    conditioning,
    numerical_rank,
    raw_jacobian,
    saturated_fraction,
    whitening_transform,
)

PUSH = {"n_basis": 6, "a_z": 10.0, "dmp_steps": 35, "goal_scale": 2.0, "weight_scale": 25.0}
"""push-v3's resolved preset (k = 5, D = 4, N = 6: P = 28 raw outputs, 20 sub-action means)."""
THROW = {"n_basis": 5, "a_z": 5.0, "dmp_steps": 35, "goal_scale": 2.0, "weight_scale": 6.25}


def _head(task: str, preset: dict, **kw):
    frame = {"dmp_state": "measured", "dmp_velocity": "state"}
    cfg = PolicyConfig(head="ndp", k=5, **frame).updated(**preset, **kw)
    torch.manual_seed(0)
    spec = get_task_spec(task)
    return build_actor_critic(spec.obs_dim, spec, cfg).head


def _central_differences(f, x: torch.Tensor, h: float) -> torch.Tensor:
    """[B, M, P] by central differences of a per-decision map f: [B, P] -> [B, ...]."""
    cols = []
    for p in range(x.shape[1]):
        e = torch.zeros_like(x)
        e[:, p] = h
        cols.append((f(x + e) - f(x - e)).reshape(x.shape[0], -1) / (2 * h))
    return torch.stack(cols, dim=-1)


def _state(b: int, d: int, seed: int) -> tuple[torch.Tensor, ...]:
    g = torch.Generator().manual_seed(seed)
    y0, dy0 = (torch.randn(b, d, generator=g, dtype=torch.float64) * s for s in (0.1, 0.3))
    return y0, dy0


@pytest.mark.parametrize(
    ("task", "preset", "kw"),
    [
        ("push-v3", PUSH, {}),
        ("throw", THROW, {}),
        ("push-v3", PUSH, {"forcing": "goal", "absolute_mode": "dmp"}),  # bilinear, composed
        ("push-v3", PUSH, {"param_map": "linear"}),
        ("push-v3", PUSH, {"param_map": "whitened"}),
    ],
)
def test_the_head_jacobian_agrees_with_central_differences_in_float64(task, preset, kw):
    """J = d means / d raw of the head (autograd, batched over decisions) equals central finite
    differences of the same head in float64, to 1e-7 (h = 1e-5: truncation ~h^2 |f'''|, rounding
    ~1e-16 |f| / h); J_map is J with the tanh slopes divided out."""
    head = _head(task, preset, **kw)
    twin = copy.deepcopy(head).double()
    p, d = head.n_params, head.dmp_dofs
    y0, dy0 = _state(6, d, seed=1)
    raw = torch.randn(6, p, dtype=torch.float64, generator=torch.Generator().manual_seed(2))
    raw = raw * 0.8
    jac, map_jac = head.raw_jacobians(raw, y0, dy0)
    assert jac.shape == (6, head.k * head.action_dim, p) and jac.dtype == torch.float64
    fd = _central_differences(lambda r: twin.decode(r, y0, dy0)[0], raw, 1e-5)
    torch.testing.assert_close(jac, fd, rtol=1e-7, atol=1e-7)
    if head.param_map == "tanh":
        slope = 1.0 - torch.tanh(raw[:, : head.n_mapped]) ** 2
        torch.testing.assert_close(
            jac[..., : head.n_mapped], map_jac[..., : head.n_mapped] * slope[:, None]
        )
    elif head.param_map == "whitened":
        torch.testing.assert_close(jac, map_jac @ head.whitening)
    else:
        torch.testing.assert_close(jac, map_jac)


def test_raw_jacobian_is_per_decision_and_refuses_bad_shapes():
    a = torch.tensor([[1.0, 2.0], [3.0, 4.0], [0.0, 0.0]], dtype=torch.float64)
    raw = torch.randn(4, 2, dtype=torch.float64)
    jac = raw_jacobian(lambda r: torch.sin(r) @ a.T, raw)
    want = a[None] * torch.cos(raw)[:, None, :]
    torch.testing.assert_close(jac, want)
    with pytest.raises(ValueError, match="raw: expected shape"):
        raw_jacobian(lambda r: r, torch.zeros(3))
    with pytest.raises(ValueError, match="decode: expected outputs"):
        raw_jacobian(lambda r: r.sum(0, keepdim=True), torch.zeros(3, 2))


def test_the_condition_number_of_a_constructed_map_with_a_known_answer():
    """decode(raw) = A tanh(raw), A [5, 4] of singular values 4, 2, 1, 0 (a zero row, a repeated
    one): 3 reachable directions, condition 4 at raw = 0. A raw output at tanh slope 0.01
    along the direction of the singular value 1 gives J's singular values 4, 2, 0.01 (the map's
    stay 4, 2, 1): condition 400, map condition 4, one of four outputs saturated."""
    q = torch.linalg.qr(
        torch.randn(4, 4, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    )[0]
    base = torch.diag(torch.tensor([4.0, 2.0, 1.0, 0.0], dtype=torch.float64))  # rows 0-3
    a = torch.cat((base, base[1:2] * 0.0), dim=0)  # [5, 4], row 4 zero: not reachable
    rot = torch.zeros(5, 5, dtype=torch.float64)
    rot[:4, :4], rot[4, 4] = q, 1.0  # rotate the rows: same singular values

    def decode(raw: torch.Tensor) -> torch.Tensor:
        return torch.tanh(raw) @ (rot @ a).T

    zero = torch.zeros(1, 4, dtype=torch.float64)
    sat = zero.clone()
    sat[0, 2] = math.atanh(math.sqrt(0.99))  # slope 1 - tanh^2 = 0.01 on the s = 1 column
    raw = torch.cat((zero, sat))
    jac = raw_jacobian(decode, raw)
    map_jac = (rot @ a).expand(2, 5, 4)
    c = conditioning(jac, map_jac, slice(0, 1), slice(1, 4))
    assert c.rank.tolist() == [3, 3]
    torch.testing.assert_close(c.condition, torch.tensor([4.0, 400.0], dtype=torch.float64))
    torch.testing.assert_close(c.map_condition, torch.tensor([4.0, 4.0], dtype=torch.float64))
    torch.testing.assert_close(
        c.singular_values[1, :3], torch.tensor([4.0, 2.0, 0.01], dtype=torch.float64)
    )
    torch.testing.assert_close(c.goal_share[0], torch.tensor(16.0 / 21.0, dtype=torch.float64))
    assert saturated_fraction(raw).tolist() == [0.0, 0.25]
    assert int(numerical_rank(torch.tensor([3.0, 1e-20]), 5, 4)) == 1
    with pytest.raises(ValueError, match="threshold"):
        saturated_fraction(raw, threshold=0.0)


def test_push_v3_at_raw_zero_reproduces_the_measured_spectrum():
    """push-v3 (k = 5, D = 4, N = 6): 28 raw outputs, 20 means, 16 reachable directions (per
    xyz DoF 5 of its 7 columns' directions; the gripper's 5 equal rows are one direction of
    singular value sqrt(5) * half range = sqrt(5)); per xyz DoF 5.05, 0.98, 0.44, 0.14, 0.030:
    condition 168.4; the goal columns hold 94 % of |J|_F^2."""
    head = _head("push-v3", PUSH)
    zero = torch.zeros(1, head.n_params)
    jac, map_jac = head.raw_jacobians(zero, torch.zeros(1, 4), torch.zeros(1, 4))
    c = conditioning(jac, map_jac, slice(0, 4), slice(4, 28))
    assert jac.shape == (1, 20, 28) and int(c.rank) == 16
    s = c.singular_values[0]
    assert abs(float(s[3]) - math.sqrt(5.0)) < 1e-9  # the gripper
    xyz = torch.cat((s[:3], s[4:16])).reshape(5, 3)  # three equal blocks
    torch.testing.assert_close(xyz, xyz[:, :1].expand(5, 3))
    torch.testing.assert_close(
        xyz[:, 0],
        torch.tensor([5.0495, 0.97754, 0.43982, 0.13571, 0.029979], dtype=torch.float64),
        rtol=1e-4,
        atol=0,
    )
    assert abs(float(c.condition) - 168.437) < 1e-2 and 0.93 < float(c.goal_share) < 0.94


def test_whitening_transform_makes_the_reachable_singular_values_one():
    g = torch.Generator().manual_seed(3)
    left = torch.randn(7, 3, dtype=torch.float64, generator=g)
    right = torch.randn(3, 9, dtype=torch.float64, generator=g)
    jac = left @ torch.diag(torch.tensor([50.0, 1.0, 0.01], dtype=torch.float64)) @ right
    w, r = whitening_transform(jac)
    assert r == 3
    s = torch.linalg.svdvals(jac @ w)
    torch.testing.assert_close(s[:3], torch.ones(3, dtype=torch.float64), rtol=1e-10, atol=1e-10)
    assert float(s[3:].abs().max()) < 1e-10
    torch.testing.assert_close(w, w.T)  # symmetric: (J^T J)^(+1/2) plus the null projector
    null = torch.linalg.svd(jac)[2][3:].T  # [9, 6] null directions of J
    torch.testing.assert_close(w @ null, null)  # identity there
    assert torch.linalg.matrix_rank(w) == 9
    with pytest.raises(ValueError, match="rank 0"):
        whitening_transform(torch.zeros(3, 4, dtype=torch.float64))


@pytest.mark.parametrize(("task", "preset", "rank"), [("push-v3", PUSH, 16), ("throw", THROW, 35)])
def test_the_whitened_head_is_isotropic_on_the_reachable_chunk_directions(task, preset, rank):
    """At raw = 0 (and, the map being affine, at any raw and state) the whitened head's
    Jacobian has r singular values 1 and the rest 0: unit raw noise is unit chunk noise."""
    head = _head(task, preset, param_map="whitened")
    assert head.whitening_rank == rank and head.whitening.dtype == torch.float64
    d = head.dmp_dofs
    zero = torch.zeros(1, head.n_params, dtype=torch.float64)
    y0, dy0 = _state(4, d, seed=5)
    raw = torch.cat((zero, 3.0 * torch.randn(3, head.n_params, dtype=torch.float64)))
    jac, map_jac = head.raw_jacobians(raw, y0, dy0)
    s = torch.linalg.svdvals(jac)
    torch.testing.assert_close(
        s[:, :rank], torch.ones(4, rank, dtype=torch.float64), rtol=1e-9, atol=1e-9
    )
    assert s[:, rank:].numel() == 0 or float(s[:, rank:].abs().max()) < 1e-9
    c = conditioning(jac, map_jac, slice(0, d), slice(d, head.n_mapped))
    assert c.rank.tolist() == [rank] * 4 and float((c.condition - 1).abs().max()) < 1e-9


def test_the_linear_map_has_the_tanh_jacobian_at_raw_zero_and_no_bound():
    tanh, linear = _head("push-v3", PUSH), _head("push-v3", PUSH, param_map="linear")
    zero = torch.zeros(1, 28)
    state = torch.zeros(1, 4)
    torch.testing.assert_close(
        tanh.raw_jacobians(zero, state, state)[0], linear.raw_jacobians(zero, state, state)[0]
    )
    raw = torch.zeros(1, 28)
    raw[0, 0], raw[0, 3] = 3.0, -2.0  # x goal 3 bounds out, gripper below its range
    _, goal, _ = linear.decode(raw, state, state)
    reach = 5 * 0.01
    torch.testing.assert_close(
        goal[0, 0], torch.tensor(3.0 * 2.0 * reach)
    )  # goal_scale * reach * raw
    assert float(goal[0, 3]) == -2.0  # centre 0 + half range 1 * raw: executed clipped to -1
    _, goal_t, _ = tanh.decode(raw, state, state)
    assert float(goal_t[0, 0]) < 2.0 * reach and float(goal_t[0, 3]) > -1.0


def test_the_default_map_is_unchanged_and_saves_no_new_state():
    """The default ('tanh') head gives the outputs main gave at this seed (recorded at df3911a)
    and its state dict is as before; 'whitened' adds one saved buffer."""
    cfg = PolicyConfig(head="ndp", k=5, dmp_state="measured", dmp_velocity="state").updated(**PUSH)
    assert cfg.ndp.param_map == "tanh"
    spec = get_task_spec("push-v3")
    torch.manual_seed(0)
    ac = build_actor_critic(39, spec, cfg)
    with torch.no_grad():
        for p in ac.actor.parameters():
            p.normal_(0, 0.5)
    g = torch.Generator().manual_seed(1)
    obs = torch.randn(3, 39, generator=g)
    y0, dy0 = torch.randn(3, 4, generator=g) * 0.2, torch.randn(3, 4, generator=g) * 0.2
    dist, _ = ac.distribution(obs, y0, dy0)
    got = dist.actions(dist.mode()).detach()
    want = torch.tensor(
        [
            [2.16595292, 2.14401507, 1.98949504, 0.99568498],
            [2.53856802, 3.49260402, 2.70273399, 0.99568498],
            [1.79748905, 2.88803792, 1.35999000, 0.99568498],
            [1.29620194, 1.58182800, 0.37761500, 0.99568498],
            [0.63625699, 0.41835800, -0.08392900, 0.99568498],
        ]
    )
    torch.testing.assert_close(got[0], want, rtol=1e-6, atol=1e-6)
    assert abs(float(got.abs().sum()) - 75.10772705078125) < 1e-4
    assert [k for k in ac.state_dict() if k.startswith("head.")] == ["head.log_std"]
    white = build_actor_critic(39, spec, cfg.updated(param_map="whitened"))
    assert [k for k in white.state_dict() if k.startswith("head.")] == [
        "head.log_std",
        "head.whitening",
    ]


def test_a_loaded_whitening_is_the_saved_one_not_a_recomputed_one():
    a = _head("push-v3", PUSH, param_map="whitened")
    b = _head("push-v3", PUSH, param_map="whitened")
    state = a.state_dict()
    state["whitening"] = state["whitening"] * 2.0  # a W from elsewhere (another version)
    b.load_state_dict(state)
    torch.testing.assert_close(b.whitening, a.whitening * 2.0)


def test_param_map_options_are_checked():
    from ndp.policies.config import PARAM_MAPS, NDPHeadConfig
    from ndp.policies.heads import PARAM_MAPS as HEAD_PARAM_MAPS

    assert PARAM_MAPS == HEAD_PARAM_MAPS
    with pytest.raises(ValueError, match="param_map: expected one of tanh, linear, whitened"):
        NDPHeadConfig(param_map="softsign")
    with pytest.raises(ValueError, match="param_map: 'whitened' needs forcing='amplitude'"):
        NDPHeadConfig(param_map="whitened", forcing="goal")
    with pytest.raises(ValueError, match="param_map: 'whitened'"):
        NDPHeadConfig(param_map="whitened", learn_az=True)
    NDPHeadConfig(param_map="linear", forcing="goal", learn_az=True)  # a linear map takes both
    with pytest.raises(ValueError, match="param_map: 'linear' needs the 'ndp' head"):
        PolicyConfig(head="ndp-squashed").updated(param_map="linear")
