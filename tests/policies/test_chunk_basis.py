"""PPO-multi's chunk bases (``--chunk-basis``): each basis' shape and properties, the 'dmp'
basis against the NDP head itself, the refusals, and the 'none' default left as it was."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from ndp.policies import MultiHead, PolicyConfig, build_actor_critic
from ndp.policies.chunk_basis import (
    basis_file_bytes,
    bspline_basis,
    bspline_knots,
    check_basis_file,
    check_columns,
    dct_basis,
    pca_basis,
    read_basis_file,
)
from ndp.policies.heads import ChunkBasisHead, build_head
from ndp.rl.config import TrainConfig, resolve_config, unused_basis_options, unused_head_options
from ndp.rl.envs import resolve_task


def _resolved(task: str, algo: str = "ppo-multi", **policy) -> TrainConfig:
    return resolve_config(TrainConfig(task=task, algo=algo, policy=PolicyConfig.from_dict(policy)))


def _head(task: str, **policy):
    cfg = _resolved(task, **policy)
    return build_head(cfg.policy, resolve_task(cfg.task).spec), cfg


# ------------------------------------------------------------------ the bases themselves


@pytest.mark.parametrize(("k", "p"), [(7, 7), (10, 7), (20, 6), (3, 1)])
def test_dct_basis_is_orthonormal_and_the_dct_ii(k, p):
    from scipy.fft import dct

    b = dct_basis(k, p)
    assert b.shape == (k, p)
    np.testing.assert_allclose(b.T @ b, np.eye(p), atol=1e-12)
    # scipy's orthonormal DCT-II of the unit vectors: row j is the j-th basis vector
    np.testing.assert_allclose(b, dct(np.eye(k), type=2, norm="ortho", axis=0).T[:, :p], atol=1e-12)
    np.testing.assert_allclose(b[:, 0], np.full(k, 1 / np.sqrt(k)))  # column 0: the constant


def test_bspline_knots_are_clamped_and_uniform():
    np.testing.assert_allclose(
        bspline_knots(7), [0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1], rtol=0, atol=0
    )
    np.testing.assert_allclose(bspline_knots(4), [0, 0, 0, 0, 1, 1, 1, 1])
    with pytest.raises(ValueError, match=r"columns: a clamped B-spline basis of degree 3 needs"):
        bspline_knots(3)


@pytest.mark.parametrize(("k", "p"), [(7, 7), (10, 7), (10, 6), (25, 7), (4, 4)])
def test_bspline_basis_is_a_partition_of_unity_clamped_and_full_rank(k, p):
    from scipy.interpolate import BSpline

    b = bspline_basis(k, p)
    assert b.shape == (k, p)
    np.testing.assert_allclose(b.sum(axis=1), 1.0, atol=1e-12)  # partition of unity
    assert (b >= 0).all()
    np.testing.assert_allclose(b[0], np.eye(p)[0], atol=1e-12)  # clamped: the ends are
    np.testing.assert_allclose(b[-1], np.eye(p)[-1], atol=1e-12)  # the end coefficients
    assert np.linalg.matrix_rank(b) == p
    t = np.arange(k) / (k - 1)
    want = BSpline.design_matrix(t, bspline_knots(p), 3).toarray()  # an independent evaluation
    np.testing.assert_allclose(b, want, atol=1e-12)


def test_pca_basis_recovers_the_subspace_of_the_chunks():
    rng = np.random.default_rng(0)
    k, a, p = 10, 3, 4
    q = np.linalg.qr(rng.normal(size=(k, p)))[0]  # a p-dim subspace of R^k per DoF
    chunks = np.einsum("kp,mpa->mka", q, rng.normal(size=(200, p, a)))
    basis, sing, explained = pca_basis(chunks, p)
    assert basis.shape == (a, k, p) and sing.shape == (a, k) and explained.shape == (a,)
    for d in range(a):
        np.testing.assert_allclose(basis[d].T @ basis[d], np.eye(p), atol=1e-10)
        np.testing.assert_allclose(basis[d] @ basis[d].T, q @ q.T, atol=1e-10)  # same span
        top = np.abs(basis[d]).argmax(axis=0)
        assert (basis[d][top, np.arange(p)] > 0).all()  # the sign convention
    np.testing.assert_allclose(explained, 1.0)
    _, _, part = pca_basis(chunks, 2)
    assert (part < 1.0).all()
    with pytest.raises(ValueError, match=r"chunks: expected \[M, k, A\]"):
        pca_basis(chunks[0], p)


@pytest.mark.parametrize("fn", [dct_basis, bspline_basis])
def test_a_basis_cannot_have_more_columns_than_k(fn):
    with pytest.raises(ValueError, match=r"chunk_basis: the '\w+' basis has 1 \+ n_basis = 7"):
        fn(5, 7)
    with pytest.raises(ValueError, match=r"more than the k = 5 sub-steps"):
        check_columns("dmp", 7, 5)


@pytest.mark.parametrize("basis", ["dct", "bspline", "dmp", "pca"])
def test_too_many_columns_are_refused_when_the_config_is_resolved(basis, tmp_path):
    # point-mass: n_basis 6 -> 7 columns; k = 5 (the default) has fewer sub-steps
    extra = {"chunk_basis_file": str(tmp_path / "none.npz")} if basis == "pca" else {}
    with pytest.raises(ValueError, match=r"^chunk_basis: the '\w+' basis has 1 \+ n_basis = 7 "):
        _resolved("point-mass", chunk_basis=basis, **extra)
    cfg = _resolved("point-mass", chunk_basis="dct", n_basis=4)  # 5 columns fit k = 5
    assert (cfg.policy.k, cfg.policy.ndp.n_basis) == (5, 4)


# ------------------------------------------------------------------ the config


def test_bad_basis_options_are_refused_in_one_line():
    with pytest.raises(ValueError, match=r"^chunk_basis: expected one of none, dmp, dct"):
        PolicyConfig(chunk_basis="fourier")
    with pytest.raises(ValueError, match=r"^chunk_basis_file: expected a file for chunk_basis"):
        PolicyConfig(chunk_basis="pca")
    with pytest.raises(ValueError, match=r"^chunk_basis_file: expected a file for chunk_basis"):
        PolicyConfig(chunk_basis="dct", chunk_basis_file="b.npz")
    with pytest.raises(ValueError, match=r"^chunk_basis: the 'dmp' basis is the NDP head's"):
        _resolved("point-mass", k=10, chunk_basis="dmp", forcing="goal")
    with pytest.raises(ValueError, match=r"only_g=True"):
        _resolved("point-mass", k=10, chunk_basis="dmp", only_g=True)


def test_none_is_ppo_multi_unchanged():
    cfg = _resolved("push-v3")
    assert cfg.policy.chunk_basis == "none" and cfg.policy.chunk_basis_file is None
    assert cfg.policy.ndp.n_basis is None  # no DMP field resolved, as before
    spec = resolve_task("push-v3").spec
    model = build_actor_critic(spec.obs_dim, spec, cfg.policy)
    assert type(model.head) is MultiHead and model.head.n_params == 5 * 4
    assert sorted(model.head.state_dict()) == ["log_std"]  # no buffer added to old checkpoints
    # a config written before the option reads as 'none'
    old = cfg.to_dict()
    del old["policy"]["chunk_basis"], old["policy"]["chunk_basis_file"]
    assert TrainConfig.from_dict(old) == cfg


def test_the_basis_is_cleared_for_other_methods_and_named_in_a_note():
    asked = TrainConfig(task="point-mass", algo="ndp", policy=PolicyConfig(chunk_basis="dct"))
    assert unused_basis_options(asked) == ["chunk_basis='dct'"]
    assert resolve_config(asked).policy.chunk_basis == "none"
    multi = dataclasses.replace(asked, algo="ppo-multi")
    assert unused_basis_options(multi) == []
    # n_basis is read by a basis (its columns), a_z only by the 'dmp' one
    pol = PolicyConfig(k=10, chunk_basis="dct").updated(n_basis=4, a_z=7.0)
    assert unused_head_options(dataclasses.replace(multi, policy=pol)) == ["a_z=7.0"]
    pol = pol.updated(chunk_basis="dmp", mean_clip=True)
    dmp = dataclasses.replace(multi, policy=pol)
    assert unused_head_options(dmp) == ["mean_clip=True"]  # the mean is PPO-multi's
    assert resolve_config(dmp).policy.ndp.mean_clip is False  # config.json says what ran
    plain = PolicyConfig().updated(n_basis=4)  # PPO-multi without a basis reads no N
    assert unused_head_options(dataclasses.replace(multi, policy=plain)) == ["n_basis=4"]


# ------------------------------------------------------------------ the head


@pytest.mark.parametrize("basis", ["dct", "bspline"])
def test_a_fixed_basis_head_maps_its_coefficients_through_the_basis(basis):
    head, cfg = _head("push-v3", k=10, chunk_basis=basis)
    assert isinstance(head, ChunkBasisHead) and not head.needs_robot_state
    assert cfg.policy.ndp.n_basis == 6 and head.n_params == 4 * 7  # D (1 + N), as NDP's head
    b = (dct_basis if basis == "dct" else bspline_basis)(10, 7)
    c = torch.randn(3, 4, 7)
    mean = head.distribution(c.reshape(3, 28))[0].mode()
    want = np.einsum("kp,bap->bka", b, c.numpy().astype(np.float64))
    np.testing.assert_allclose(mean.numpy(), want, atol=1e-5)
    assert sorted(head.state_dict()) == ["basis", "log_std", "offset", "offset_dy0", "offset_y0"]


DMP_CASES = {
    # the measured frame with its velocity (a state-dependent offset), the direct gripper
    "push-v3": ("push-v3", {}),
    "throw": ("throw", {}),  # the commanded joints at rest, 7 DoF, N = 5
    "point-mass": ("point-mass", {}),
    # the gripper as a DMP from the last command (an offset in y0), the commanded state
    "push-v3-gripper-dmp": (
        "push-v3",
        {"absolute_mode": "dmp", "dmp_state": "commanded", "dmp_velocity": "state"},
    ),
}


@pytest.mark.parametrize("name", list(DMP_CASES))
def test_the_dmp_basis_is_the_ndp_heads_chunk_without_tanh(name):
    task, kw = DMP_CASES[name]
    k = 10
    basis_head, cfg = _head(task, k=k, chunk_basis="dmp", **kw)
    ndp_cfg = _resolved(task, algo="ndp", k=k, **kw)
    # the same DMP, bounds and frame as the NDP method's
    fields = ("n_basis", "a_z", "dmp_steps", "goal_scale", "weight_scale", "forcing", "rbf")
    assert {f: getattr(cfg.policy.ndp, f) for f in fields} == {
        f: getattr(ndp_cfg.policy.ndp, f) for f in fields
    }
    assert (cfg.policy.dmp_state, cfg.policy.dmp_velocity) == (
        ndp_cfg.policy.dmp_state,
        ndp_cfg.policy.dmp_velocity,
    )
    spec = resolve_task(task).spec
    ndp_head = build_head(ndp_cfg.policy, spec)
    d, n = spec.dmp_dofs, ndp_cfg.policy.ndp.n_basis
    gen = torch.Generator().manual_seed(1)
    b = 16
    c = (torch.rand(b, d, 1 + n, generator=gen, dtype=torch.float64) * 2 - 1) * 0.9
    y0 = torch.rand(b, d, generator=gen, dtype=torch.float64) * 0.6 - 0.3
    dy0 = torch.rand(b, d, generator=gen, dtype=torch.float64) * 0.4 - 0.2
    # the NDP head itself, untouched: raw = atanh(c), so that tanh(raw) = c
    raw = torch.cat((c[:, :, 0], c[:, :, 1:].reshape(b, d * n)), dim=1).atanh()
    f32 = {"dtype": torch.float32}
    want, _, _ = ndp_head.decode(raw.to(**f32), y0.to(**f32), dy0.to(**f32))
    got = basis_head.distribution(c.reshape(b, -1).to(**f32), y0.to(**f32), dy0.to(**f32))[0]
    assert basis_head.needs_robot_state
    assert float(want.abs().max()) > 0.5  # the chunks are not trivially small
    np.testing.assert_allclose(got.mode().numpy(), want.numpy(), rtol=0, atol=1e-5)
    # and decode(bounded=False) is that map
    unbounded, _, _ = ndp_head.decode(raw.tanh().to(**f32), y0.to(**f32), dy0.to(**f32), False)
    np.testing.assert_allclose(unbounded.numpy(), want.numpy(), rtol=0, atol=1e-5)


def test_the_dmp_basis_of_a_state_dependent_frame_has_state_offsets():
    head, _ = _head("push-v3", k=10, chunk_basis="dmp")  # measured hand, its velocity
    assert float(head.offset_dy0[:, :3].abs().max()) > 0.1  # the hand DoF coast on
    assert float(head.offset_dy0[:, 3].abs().max()) == 0.0  # the gripper: its goal only
    assert float(head.basis[3, :, 1:].abs().max()) == 0.0  # ... so no weight moves it
    head, _ = _head("throw", k=10, chunk_basis="dmp")  # commanded joints at rest
    assert float(head.offset_dy0.abs().max()) == 0.0


def test_affine_parts_refuse_a_head_that_is_not_affine():
    cfg = _resolved("point-mass", algo="ndp", k=10, forcing="goal")
    head = build_head(cfg.policy, resolve_task("point-mass").spec)
    with pytest.raises(ValueError, match=r"not affine per DoF in \(g, w\) with forcing='goal'"):
        head.affine_parts()


def test_a_pca_head_without_its_file_acts_only_once_a_state_is_loaded(tmp_path):
    spec = resolve_task("point-mass").spec
    basis = np.linalg.qr(np.random.default_rng(0).normal(size=(10, 7)))[0]
    path = _write_basis(tmp_path / "b.npz", np.stack([basis, basis]), task="point-mass")
    cfg = _resolved("point-mass", k=10, chunk_basis="pca", chunk_basis_file=str(path))
    head = build_head(cfg.policy, spec)
    np.testing.assert_allclose(head.basis[0].numpy(), basis, atol=1e-7)
    state = head.state_dict()
    path.unlink()
    blank = build_head(cfg.policy, spec)  # the file is gone: a NaN basis
    with pytest.raises(ValueError, match=r"chunk_basis: the 'pca' head holds no basis"):
        blank.distribution(torch.zeros(1, 14))
    blank.load_state_dict(state)
    np.testing.assert_array_equal(
        blank.distribution(torch.ones(1, 14))[0].mode().numpy(),
        head.distribution(torch.ones(1, 14))[0].mode().numpy(),
    )


# ------------------------------------------------------------------ the basis file


def _write_basis(path, basis, **prov):
    a, k, p = basis.shape
    base = {"format": "ndp-chunk-basis", "version": 1, "task": "point-mass", "k": k}
    base.update(action_dim=a, columns=p, **prov)
    path.write_bytes(basis_file_bytes(basis, base, explained=np.ones(a)))
    return path


def test_a_basis_file_that_does_not_fit_the_run_is_refused(tmp_path):
    basis = np.stack([dct_basis(10, 7)] * 2)
    path = _write_basis(tmp_path / "b.npz", basis)
    data = read_basis_file(path)
    assert data.provenance["task"] == "point-mass" and data.basis.shape == (2, 10, 7)
    check_basis_file(data, path, task="point-mass", k=10, action_dim=2, columns=7)
    for kw, what in (
        ({"task": "push-v3"}, r"task 'point-mass', this run needs 'push-v3'"),
        ({"k": 12}, r"k \(sub-steps per decision\) 10, this run needs 12"),
        ({"action_dim": 4}, r"DoF count \(action dimensions\) 2, this run needs 4"),
        ({"columns": 6}, r"columns \(1 \+ n_basis\) 7, this run needs 6"),
    ):
        want = {"task": "point-mass", "k": 10, "action_dim": 2, "columns": 7, **kw}
        with pytest.raises(ValueError, match=r"^chunk_basis_file: .* was fitted for " + what):
            check_basis_file(data, path, **want)
    # through the config: k = 12 and another task are refused before any env is built
    with pytest.raises(ValueError, match=r"fitted for k \(sub-steps per decision\) 10"):
        _resolved("point-mass", k=12, chunk_basis="pca", chunk_basis_file=str(path))
    with pytest.raises(ValueError, match=r"fitted for task 'point-mass', this run needs 'point"):
        _resolved("point-mass-3d", k=10, chunk_basis="pca", chunk_basis_file=str(path))
    with pytest.raises(FileNotFoundError, match=r"chunk_basis_file: no such file"):
        _resolved("point-mass", k=10, chunk_basis="pca", chunk_basis_file=str(tmp_path / "x"))
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match=r"^chunk_basis_file: .* is not a readable .npz"):
        read_basis_file(bad)
    lying = _write_basis(tmp_path / "lying.npz", basis, k=11)  # provenance != its basis
    with pytest.raises(ValueError, match=r"its provenance says \[11\] for \['k'\]"):
        read_basis_file(lying)
    other = tmp_path / "other.npz"
    other.write_bytes(basis_file_bytes(basis, {"format": "something-else"}))
    with pytest.raises(ValueError, match=r"expected provenance of format 'ndp-chunk-basis'"):
        read_basis_file(other)
    assert json.loads(str(np.load(path)["provenance"]))["version"] == 1
