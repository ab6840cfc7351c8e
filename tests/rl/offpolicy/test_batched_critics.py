"""The batched twin critics (ndp.rl.offpolicy.critics.BatchedTwinQ): TwinQ's state_dict both
ways (a checkpoint written by TwinQ loads), and the same SAC critic loss, actor loss and
gradients of every parameter as the plain TwinQ to 1e-6 on a fixed batch."""

from __future__ import annotations

import copy

import pytest
import torch

from ndp.rl.offpolicy.critics import BatchedTwinQ, TwinQ
from ndp.rl.sac.losses import actor_loss, critic_loss, critic_target

OBS, C, B = 7, 3, 64


def _pair(layer_norm: bool, activation: str = "relu") -> tuple[TwinQ, BatchedTwinQ]:
    torch.manual_seed(0)
    plain = TwinQ(OBS, C, (32, 16), activation, layer_norm)
    torch.manual_seed(0)
    batched = BatchedTwinQ(OBS, C, (32, 16), activation, layer_norm)
    return plain, batched


def _batched_grads(net: BatchedTwinQ) -> dict[str, torch.Tensor]:
    """The batched parameters' gradients under TwinQ's names and shapes."""
    out = {}
    for i in range(2):
        for own, twin, transposed in net._twin_names():
            g = getattr(net, own).grad
            assert g is not None
            out[f"q{i + 1}.{twin}"] = g[i].t() if transposed else g[i, 0]
    return out


@pytest.mark.parametrize("layer_norm", [False, True])
def test_the_state_dict_is_twinqs_both_ways(tmp_path, layer_norm):
    plain, batched = _pair(layer_norm)  # the same seed: the same initial weights
    sp, sb = plain.state_dict(), batched.state_dict()
    assert list(sp) == list(sb)
    assert all(sp[k].shape == sb[k].shape and torch.equal(sp[k], sb[k]) for k in sp)
    # a checkpoint written by the old module loads into the new one, and back
    torch.manual_seed(5)
    old = TwinQ(OBS, C, (32, 16), "relu", layer_norm)
    torch.save({"critic": old.state_dict()}, tmp_path / "old.pt")
    saved = torch.load(tmp_path / "old.pt", weights_only=True)["critic"]
    batched.load_state_dict(saved)
    obs, c = torch.randn(B, OBS), torch.randn(B, C)
    for a, b in zip(old(obs, c), batched(obs, c), strict=True):
        assert torch.allclose(a, b, atol=1e-6)
    plain.load_state_dict(batched.state_dict())
    assert all(torch.equal(v, saved[k]) for k, v in plain.state_dict().items())
    assert all(
        torch.equal(v, saved[k]) for k, v in BatchedTwinQ.from_twin(old).state_dict().items()
    )


def test_a_wrong_state_dict_is_refused():
    plain, batched = _pair(False)
    sd = plain.state_dict()
    with pytest.raises(RuntimeError, match="Unexpected key"):
        batched.load_state_dict({**sd, "q3.net.0.weight": torch.zeros(1)})
    with pytest.raises(RuntimeError, match=r"Missing key.*q2\.net\.2\.bias"):
        batched.load_state_dict({k: v for k, v in sd.items() if k != "q2.net.2.bias"})
    with pytest.raises(RuntimeError, match=r"size mismatch for q1\.net\.0\.weight"):
        batched.load_state_dict({**sd, "q1.net.0.weight": torch.zeros(32, OBS)})
    ln = BatchedTwinQ(OBS, C, (32, 16), "relu", layer_norm=True)
    with pytest.raises(RuntimeError, match=r"Missing key.*q1\.net\.1\.weight"):
        ln.load_state_dict(sd)  # a plain critic's weights lack the LayerNorm's


@pytest.mark.parametrize(("layer_norm", "activation"),
                         [(False, "relu"), (True, "relu"), (False, "tanh")])  # fmt: skip
def test_same_losses_and_gradients_as_the_plain_critics(layer_norm, activation):
    plain, batched = _pair(layer_norm, activation)
    torch.manual_seed(1)
    actor = torch.nn.Linear(OBS, C)
    obs, nobs = torch.randn(B, OBS), torch.randn(B, OBS)
    c, c_next = torch.rand(B, C) * 2 - 1, torch.rand(B, C) * 2 - 1
    ret, disc, logp_n = torch.randn(B), torch.rand(B), torch.randn(B)
    results = []
    for net in (plain, batched):
        target = copy.deepcopy(net).requires_grad_(False)
        actor.zero_grad(set_to_none=True)
        q1_t, q2_t = target(nobs, c_next)
        y = critic_target(ret, disc, q1_t, q2_t, logp_n, 0.2)
        q1, q2 = net(obs, c)
        lc = critic_loss(q1, q2, y)
        lc.backward()
        g_critic = (
            {k: p.grad.clone() for k, p in net.named_parameters()}
            if isinstance(net, TwinQ)
            else {k: g.clone() for k, g in _batched_grads(net).items()}
        )
        net.requires_grad_(False)
        u = actor(obs)
        logp = -(u**2).sum(-1)  # any differentiable log-prob
        q1_pi, q2_pi = net(obs, torch.tanh(u))
        la = actor_loss(logp, q1_pi, q2_pi, 0.2)
        la.backward()
        net.requires_grad_(True)
        g_actor = {k: p.grad.clone() for k, p in actor.named_parameters()}
        results.append((float(lc.detach()), float(la.detach()), g_critic, g_actor))
    (lc0, la0, gc0, ga0), (lc1, la1, gc1, ga1) = results
    assert lc1 == pytest.approx(lc0, abs=1e-6) and la1 == pytest.approx(la0, abs=1e-6)
    assert list(gc0) == list(gc1) and list(gc0) == list(plain.state_dict())  # every parameter
    for k in gc0:
        assert torch.allclose(gc0[k], gc1[k], atol=1e-6, rtol=0), k
    for k in ga0:
        assert torch.allclose(ga0[k], ga1[k], atol=1e-6, rtol=0), k


def test_a_sac_gradient_step_on_batched_critics_is_the_plain_one(tmp_path):
    """SACLearner.gradient_step (critics, actor, temperature, soft update; fused Adam) from the
    same state on the same batch and seed: the same losses and parameters to 1e-6."""
    import numpy as np

    from ndp.rl.config import TrainConfig
    from ndp.rl.run import open_run
    from ndp.rl.sac.config import SACConfig

    cfg = TrainConfig(task="point-mass", algo="sac", steps=400, seed=0, run_dir=str(tmp_path / "s"),
                      progress=False, tensorboard=False, vector="sync", num_envs=2,
                      steps_per_update=100, eval_every=0,
                      sac=SACConfig(random_steps=100, batch_size=32))  # fmt: skip
    with open_run(cfg) as opened:
        lr = opened.learner
        rng = np.random.default_rng(0)
        cols = {n: rng.standard_normal((100, s.stop - s.start)).astype(np.float32)
                for n, s in lr.replay._slices.items()}  # fmt: skip
        cols["discount"] = rng.uniform(0.0, 0.99, size=(100, 1)).astype(np.float32)
        lr.replay.add(**cols)
        batch = lr.replay.sample(32, rng)
        start = {n: copy.deepcopy(getattr(lr, n)) for n in ("model", "critic", "critic_target")}
        log_alpha = lr.log_alpha.detach().clone()
        runs = []
        for batched in (False, True):
            if batched:  # the same start, the batched critics, fresh optimisers (as the first)
                lr.model = copy.deepcopy(start["model"])
                lr._open_critics(BatchedTwinQ.from_twin(start["critic"]))
                lr.critic_target = BatchedTwinQ.from_twin(start["critic_target"])
                lr.critic_target.requires_grad_(False)
                lr.log_alpha = log_alpha.clone().requires_grad_(True)
                s = lr.settings
                lr.actor_opt = torch.optim.Adam(lr.model.actor.parameters(), lr=s.lr, fused=True)
                lr.critic_opt = torch.optim.Adam(lr.critic.parameters(), lr=s.lr, fused=True)
                lr.alpha_opt = torch.optim.Adam([lr.log_alpha], lr=s.lr)
            torch.manual_seed(3)
            out = lr.gradient_step(batch)
            state = {
                **{f"model.{k}": v.clone() for k, v in lr.model.state_dict().items()},
                **{f"critic.{k}": v.clone() for k, v in lr.critic.state_dict().items()},
                **{f"target.{k}": v.clone() for k, v in lr.critic_target.state_dict().items()},
                "log_alpha": lr.log_alpha.detach().clone(),
            }
            runs.append((out, state))
    (out0, st0), (out1, st1) = runs
    assert isinstance(start["critic"], TwinQ)
    for k in out0:
        assert out1[k] == pytest.approx(out0[k], abs=1e-6), k
    assert list(st0) == list(st1)
    moved = [k for k in st0 if k.startswith("critic.")
             and not torch.equal(st0[k], start["critic"].state_dict()[k[7:]])]  # fmt: skip
    assert moved  # the step trained the critics
    for k in st0:
        assert torch.allclose(st0[k], st1[k], atol=1e-6, rtol=0), k
