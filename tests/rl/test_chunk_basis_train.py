"""PPO-multi with a chunk basis (``--chunk-basis``) through the trainer, checkpoints,
``load_policy``, ONNX export, ``ndp rl fit-basis`` and a sweep's arm, on the toy task."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

import ndp
from ndp.cli import main as ndp_main
from ndp.policies import PolicyConfig
from ndp.policies.chunk_basis import read_basis_file
from ndp.policies.heads import ChunkBasisHead
from ndp.rl.config import PPOConfig, TrainConfig
from ndp.rl.run import train
from ndp.runs import load_checkpoint, read_metrics
from policy_fixtures import fixture_policy

K = 10  # point-mass: n_basis 6, so 7 columns need k >= 7
TINY = PPOConfig(minibatches=2, epochs=2, lr=1e-3)  # with steps_per_update=400


def _train(run: Path, steps: int = 800, **policy) -> dict:
    cfg = TrainConfig(
        task="point-mass",
        algo="ppo-multi",
        steps=steps,
        num_envs=2,
        run_dir=str(run),
        progress=False,
        tensorboard=False,
        vector="sync",
        steps_per_update=400,
        ppo=TINY,
        policy=PolicyConfig.from_dict({"k": K, **policy}),
    )
    return train(cfg)


def _obs(policy, n: int = 6, seed: int = 0) -> tuple[np.ndarray, dict]:
    """Observations and infos of the policy's first decisions in its env."""
    env = policy.make_env()
    obs, info = env.reset(seed=seed)
    out = []
    for _ in range(n):
        out.append((obs, {k: np.asarray(info[k]) for k in policy.state_keys}))
        obs, _, term, trunc, info = env.step(policy.act(obs, info))
        if term or trunc:
            obs, info = env.reset(seed=seed + 1)
    env.close()
    return np.stack([o for o, _ in out]), {
        k: np.stack([i[k] for _, i in out]) for k in policy.state_keys
    }


def _means(policy, obs: np.ndarray, info: dict) -> torch.Tensor:
    ky, kdy = policy.state_keys
    with torch.no_grad():
        dist, _ = policy.model.distribution(
            torch.from_numpy(policy.obs_norm(obs)),
            torch.as_tensor(info[ky], dtype=torch.float32),
            torch.as_tensor(info[kdy], dtype=torch.float32),
        )
    return dist.mode()


@pytest.mark.parametrize("basis", ["dct", "bspline", "dmp"])
def test_a_few_ppo_updates_train_with_each_basis_and_the_chunk_stays_in_its_span(basis, tmp_path):
    run = tmp_path / basis
    metrics = _train(run, chunk_basis=basis)
    rows = read_metrics(run / "metrics.csv")
    assert len(rows) == 2 and metrics["global_step"] == 800
    for key in ("losses/policy", "losses/value", "losses/approx_kl"):
        assert all(np.isfinite(r[key]) for r in rows), key
    assert metrics["losses/approx_kl"] > 0  # the policy moved
    cfg = json.loads((run / "config.json").read_text())["policy"]
    assert (cfg["chunk_basis"], cfg["k"], cfg["ndp"]["n_basis"]) == (basis, K, 6)
    ckpt = load_checkpoint(run, kind="rl")
    assert ckpt["model"]["head.basis"].shape == (2, K, 7)  # saved in the checkpoint
    policy = ndp.load_policy(run)
    head = policy.model.head
    assert isinstance(head, ChunkBasisHead) and head.kind == basis
    torch.testing.assert_close(head.basis, ckpt["model"]["head.basis"], rtol=0, atol=0)
    obs, info = _obs(policy)
    mean = _means(policy, obs, info).double()  # [B, k, A]
    # every DoF's chunk lies in the span of its basis (offsets are zero on the toy task)
    for a in range(2):
        b = head.basis[a].double()  # [k, P]
        coef = torch.linalg.lstsq(b, mean[:, :, a].T).solution
        torch.testing.assert_close(b @ coef, mean[:, :, a].T, rtol=0, atol=1e-5)
    assert float(mean.abs().max()) > 1e-3
    act = policy.act(obs, info)
    assert act.shape == (len(obs), K, 2) and np.all(np.abs(act) <= 1.0)


@pytest.fixture(scope="module")
def multi_run(tmp_path_factory) -> Path:
    """A tiny trained PPO-multi run at k = 10 (one update)."""
    run = tmp_path_factory.mktemp("fit") / "multi"
    _train(run, steps=400)
    return run


def test_fit_basis_writes_the_pca_basis_with_its_provenance_and_training_reads_it(
    multi_run, tmp_path, capsys
):
    out = tmp_path / "basis.npz"
    argv = ["rl", "fit-basis", str(multi_run), "--decisions", "25", "--out", str(out)]
    assert ndp_main(argv) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["columns"] == 7 and summary["decisions"] == 25 and summary["k"] == K
    assert all(0.0 < e <= 1.0 for e in summary["explained"])
    data = read_basis_file(out)
    prov = data.provenance
    assert (prov["task"], prov["k"], prov["action_dim"], prov["n_basis"]) == ("point-mass", K, 2, 6)
    assert prov["decisions"] == 25 and prov["mode"] == "deterministic" and prov["date"]
    assert prov["runs"][0]["path"].endswith("multi") and prov["runs"][0]["seed"] == 0
    assert "commit" in prov and prov["centred"] is False
    for a in range(2):
        np.testing.assert_allclose(data.basis[a].T @ data.basis[a], np.eye(7), atol=1e-10)
    # the basis holds the recorded chunks better than any other 7 directions: at least
    # as well as the first 7 DCT vectors do
    from ndp.policies.chunk_basis import dct_basis
    from ndp.rl.fit_basis import collect_chunks

    chunks = collect_chunks(ndp.load_policy(multi_run), 25)
    for a in range(2):
        x = chunks[:, :, a]
        kept = np.linalg.norm(x @ data.basis[a]) ** 2
        assert kept >= np.linalg.norm(x @ dct_basis(K, 7)) ** 2 - 1e-9
    assert ndp_main(argv) == 2  # an existing file is kept without --overwrite
    assert "exists" in capsys.readouterr().err

    # training reads it; the checkpoint holds it, so the policy loads without the file
    run = tmp_path / "pca"
    metrics = _train(run, chunk_basis="pca", chunk_basis_file=str(out))
    assert np.isfinite(metrics["losses/policy"])
    policy = ndp.load_policy(run)
    np.testing.assert_allclose(policy.model.head.basis.numpy(), data.basis, atol=1e-7)
    # a resume (which resolves the config again: the file must still be there) keeps the basis
    from ndp.rl.run import resume

    assert resume(run, steps=1200)["global_step"] == 1200
    policy = ndp.load_policy(run)
    np.testing.assert_allclose(policy.model.head.basis.numpy(), data.basis, atol=1e-7)
    obs, info = _obs(policy)
    before = policy.act(obs, info)
    out.unlink()
    again = ndp.load_policy(run)
    np.testing.assert_array_equal(again.act(obs, info), before)
    # exported (safetensors) and loaded again, still without the file
    exported = again.export(tmp_path / "export")
    np.testing.assert_array_equal(ndp.load_policy(exported).act(obs, info), before)
    pytest.importorskip("onnxruntime")
    from ndp.rl.onnx_export import OnnxPolicy

    onnx_out = again.export(tmp_path / "onnx", format="onnx")
    np.testing.assert_allclose(OnnxPolicy(onnx_out).act(obs, info), before, rtol=0, atol=1e-5)


def test_fit_basis_refuses_runs_it_cannot_pool(multi_run, tmp_path):
    from ndp.rl.fit_basis import fit_basis

    with pytest.raises(ValueError, match=r"^run_dirs: .*push-v3-ndp is a ndp run; expected ppo"):
        fit_basis([fixture_policy("push-v3-ndp")], tmp_path / "b.npz")
    other = tmp_path / "k5"
    _train(other, steps=100, k=5)
    with pytest.raises(ValueError, match=r"has \(task, k, DoF count\) \('point-mass', 5, 2\)"):
        fit_basis([multi_run, other], tmp_path / "b.npz", decisions=5)
    with pytest.raises(ValueError, match=r"more than the k = 5 sub-steps"):
        fit_basis([other], tmp_path / "b.npz", decisions=5)  # 7 columns at k = 5
    with pytest.raises(ValueError, match=r"^decisions: expected an integer >= 1, got 0"):
        fit_basis([multi_run], tmp_path / "b.npz", decisions=0)
    assert not (tmp_path / "b.npz").exists()


def test_a_sweep_arm_passes_the_option(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = ["sweep", "--tasks", "push-v3", "--methods", "ppo-multi", "--seeds", "0", "--steps",
            "1000", "--dry-run", "-o", "k=10", "--", "--chunk-basis", "dct"]  # fmt: skip
    assert ndp_main(argv) == 0
    out = capsys.readouterr().out
    assert "push-v3 ppo-multi s0" in out and "--k 10 --chunk-basis dct" in out
    # at the default k = 5 the arm is refused before anything starts
    assert ndp_main([*argv[:-5], "--", "--chunk-basis", "dct"]) != 0
    assert "7 columns per DoF, more than the k = 5" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # a dry run writes nothing
