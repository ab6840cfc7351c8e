"""The SAC family (ndp.rl.sac): the losses on hand-checked numbers, the squashed density, the
k-step target of the chunked critic, NDP-SAC's gradient reaching the DMP parameters, save and
resume with the replay buffer, and the three methods end to end through the command line."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from ndp.cli import main as ndp_main
from ndp.policies.squashed import SquashedGaussian, tanh_log_det
from ndp.rl.replay import RingReplay
from ndp.rl.sac.config import SACConfig
from ndp.rl.sac.losses import (
    actor_loss,
    alpha_loss,
    bootstrap_discount,
    chunk_return,
    critic_loss,
    critic_target,
    soft_update,
)
from ndp.rl.sac.replay import DecisionReplay
from ndp.runs import load_checkpoint, read_metrics


def test_chunk_return_and_bootstrap_weight_by_hand():
    r = torch.tensor([[1.0, 2.0, 3.0], [1.0, 1.0, 1.0]])
    mask = torch.tensor([[1.0, 1.0, 0.0], [1.0, 1.0, 1.0]])  # row 0: the episode ended after 2
    ret, n = chunk_return(r, mask, 0.9)
    assert ret.tolist() == pytest.approx([1 + 0.9 * 2, 1 + 0.9 + 0.81])
    assert n.tolist() == [2.0, 3.0]
    w = bootstrap_discount(n, torch.tensor([1.0, 0.0]), 0.9)  # row 0 terminated
    assert w.tolist() == pytest.approx([0.0, 0.729])
    ret1, n1 = chunk_return(r[:, :1], mask[:, :1], 0.9)  # k = 1: SAC's one-step target
    assert ret1.tolist() == [1.0, 1.0] and n1.tolist() == [1.0, 1.0]


def test_losses_on_a_tiny_batch_by_hand():
    y = critic_target(
        ret=torch.tensor([1.0, 2.0]),
        discount=torch.tensor([0.5, 0.0]),
        q1_next=torch.tensor([4.0, 9.0]),
        q2_next=torch.tensor([3.0, 1.0]),
        logp_next=torch.tensor([-1.0, 5.0]),
        alpha=0.2,
    )
    assert y.tolist() == pytest.approx([1.0 + 0.5 * (3.0 + 0.2), 2.0])
    q1, q2 = torch.tensor([3.0, 2.0]), torch.tensor([2.0, 4.0])
    assert float(critic_loss(q1, q2, y)) == pytest.approx(
        0.5 * (((3.0 - 2.6) ** 2 + 0) / 2 + ((2.0 - 2.6) ** 2 + 4.0) / 2)
    )
    la = actor_loss(torch.tensor([-1.0, 1.0]), q1, q2, 0.5)
    assert float(la) == pytest.approx(((-0.5 - 2.0) + (0.5 - 2.0)) / 2)
    log_alpha = torch.tensor(0.3, requires_grad=True)
    lt = alpha_loss(log_alpha, torch.tensor([-1.0, -3.0]), target_entropy=-2.0)
    assert float(lt.detach()) == pytest.approx(-0.3 * ((-1.0 - 2.0) + (-3.0 - 2.0)) / 2)  # 1.2
    lt.backward()
    # d/dlog_alpha = -mean(logp + H) = 4 > 0: descent lowers alpha while the entropy (-logp,
    # 2 on average) is above the target (-H = ... -2)
    assert float(log_alpha.grad) == pytest.approx(4.0)


def test_soft_update_moves_tau_of_the_way():
    a, b = torch.nn.Linear(2, 1), torch.nn.Linear(2, 1)
    before = a.weight.detach().clone()
    soft_update(a, b, 0.25)
    assert torch.allclose(a.weight, 0.75 * before + 0.25 * b.weight)


def test_the_squashed_density_is_that_of_tanh_of_a_gaussian():
    torch.manual_seed(0)
    mean, log_std = torch.randn(5, 3), torch.randn(5, 3).clamp(-2, 1)
    dist = SquashedGaussian(mean, log_std, lambda u: torch.tanh(u).unsqueeze(1))
    u = dist.sample()
    ref = torch.distributions.TransformedDistribution(
        torch.distributions.Normal(mean, log_std.exp()),
        [torch.distributions.TanhTransform(cache_size=1)],
    )
    expected = ref.log_prob(torch.tanh(u)).sum(-1, keepdim=True)
    assert torch.allclose(dist.log_prob(u), expected, atol=1e-4)
    assert torch.allclose(tanh_log_det(torch.tensor([30.0])), torch.tensor([-58.6137]), atol=1e-3)
    assert dist.per_decision and dist.log_prob(u).shape == (5, 1)


def test_replay_round_trip_and_ring():
    dims = {"obs": 2, "next_obs": 2, "u": 3, "critic_in": 3, "y0": 1, "dy0": 1, "next_y0": 1,
            "next_dy0": 1}  # fmt: skip
    buf = DecisionReplay(4, dims)
    for i in range(3):
        buf.add(obs=np.full((2, 2), i), y0=np.zeros((2, 1)), dy0=np.zeros((2, 1)),
                u=np.zeros((2, 3)), critic_in=np.zeros((2, 3)), ret=np.full(2, i),
                discount=np.ones(2), next_obs=np.zeros((2, 2)), next_y0=np.zeros((2, 1)),
                next_dy0=np.zeros((2, 1)))  # fmt: skip
    assert buf.size == 4 and buf.ptr == 2
    assert buf.data["ret"][:, 0].tolist() == [2, 2, 1, 1]  # the oldest two overwritten
    again = DecisionReplay(4, dims)
    again.load_state_dict(buf.state_dict())
    rng_a, rng_b = np.random.default_rng(1), np.random.default_rng(1)
    a, b = buf.sample(6, rng_a), again.sample(6, rng_b)
    assert all(torch.equal(a[k], b[k]) for k in a)
    wider = r"replay: column u has shape \(3,\) in the checkpoint, \(5,\) now"
    with pytest.raises(ValueError, match=wider):
        DecisionReplay(4, {**dims, "u": 5}).load_state_dict(buf.state_dict())


def test_ring_replay_scalar_columns_and_capacity_check():
    buf = RingReplay(3, {"obs": (2,), "rew": (4,), "term": ()})
    buf.add(obs=np.arange(4.0).reshape(2, 2), rew=np.ones((2, 4)), term=np.array([0.0, 1.0]))
    b = buf.sample(5, np.random.default_rng(0))
    assert b["obs"].shape == (5, 2) and b["rew"].shape == (5, 4) and b["term"].shape == (5,)
    rows = {tuple(r) for r in b["obs"].tolist()}
    assert rows <= {(0.0, 1.0), (2.0, 3.0)}  # only filled rows are drawn
    # every drawn row keeps its columns together (one gather of whole rows)
    for o, t in zip(b["obs"].tolist(), b["term"].tolist(), strict=True):
        assert t == (1.0 if o == [2.0, 3.0] else 0.0)
    with pytest.raises(ValueError, match="buffer holds 3 decisions, expected 4"):
        RingReplay(4, buf.shapes).load_state_dict(buf.state_dict())
    empty = RingReplay(3, buf.shapes)
    empty.load_state_dict(RingReplay(3, buf.shapes).state_dict())  # an empty buffer round-trips
    assert empty.size == 0


def test_config_refuses_bad_values_naming_the_field():
    with pytest.raises(ValueError, match="critic_input: expected one of params, actions"):
        SACConfig(critic_input="state")
    with pytest.raises(ValueError, match="tau: expected a number in"):
        SACConfig(tau=0.0)
    with pytest.raises(ValueError, match="batch_size: expected an integer >= 1"):
        SACConfig(batch_size=0)
    with pytest.raises(ValueError, match="critic_layer_norm: expected true or false, got 'yes'"):
        SACConfig(critic_layer_norm="yes")  # type: ignore[arg-type]


def test_first_learning_decision_by_hand():
    from ndp.rl.offpolicy.loop import first_learning_decision

    # 4 envs, k = 1: 5,000 random steps take 1,250 rounds (the last is round 1,249); a batch of
    # 256 is in after 64 rounds, so the random steps decide
    assert first_learning_decision(5000, 256, 10**6, 1, 4) == 1249
    # k = 5: 250 rounds of random steps; the batch still needs 64 rounds
    assert first_learning_decision(5000, 256, 10**6, 5, 4) == 249
    assert first_learning_decision(0, 256, 10**6, 5, 4) == 63  # the batch decides
    assert first_learning_decision(0, 1, 10, 1, 4) == 0  # the first round already learns
    assert first_learning_decision(0, 256, 255, 1, 4) is None  # the replay never holds a batch


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--steps", "400"],
            "steps: --algo sac takes its first gradient step after 5,000 env steps",
        ),
        (
            ["--steps", "20000", "--sac-batch-size", "100000", "--sac-random-steps", "0"],
            "steps: --algo sac takes its first gradient step after 100,000 env steps",
        ),
        (
            ["--steps", "20000", "--sac-buffer-size", "100"],
            "sac.buffer_size: expected at least batch_size x k = 256 env steps",
        ),
        (
            ["--steps", "20000", "--sac-random-steps", "0", "--sac-updates-per-step", "1e-6"],
            "sac.updates_per_step: expected at least one gradient step",
        ),
    ],
)
def test_a_sac_run_that_could_never_learn_is_refused_before_its_folder(
    tmp_path, capsys, argv, message
):
    """A budget that ends in the random steps, a batch larger than the run's decisions, a
    replay smaller than a batch or a negligible update rate: a one-line error naming the
    argument, and no run folder."""
    run = tmp_path / "never"
    rc = ndp_main(["rl", "train", "--task", "point-mass", "--algo", "sac", "--run-dir", str(run),
                   "--no-progress", "--no-tensorboard", "--vector", "sync", *argv])  # fmt: skip
    assert rc != 0
    err = capsys.readouterr().err
    assert message in err and not run.exists()


def _open(tmp_path, algo, task="point-mass", **kw):
    from ndp.rl.config import TrainConfig
    from ndp.rl.run import open_run

    sac = SACConfig(**{"random_steps": 100, "batch_size": 32, **kw.pop("sac", {})})
    cfg = TrainConfig(task=task, algo=algo, steps=kw.pop("steps", 400), seed=0,
                      run_dir=str(tmp_path / algo), progress=False, tensorboard=False,
                      vector="sync", num_envs=2, steps_per_update=100, sac=sac,
                      eval_every=0, **kw)  # fmt: skip
    return open_run(cfg)


@pytest.mark.parametrize("critic_input", ["params", "actions"])
def test_ndp_sac_actor_gradient_reaches_the_dmp_parameters(tmp_path, critic_input):
    opened = _open(tmp_path, "ndp-sac", sac={"critic_input": critic_input})
    try:
        lr = opened.learner
        assert lr.is_ndp and lr.scores_params == (critic_input == "params")
        obs = torch.randn(8, lr.obs_dim)
        y0, dy0 = torch.zeros(8, 2), torch.zeros(8, 2)
        dist = lr._dist(obs, y0, dy0)
        u = dist.rsample()
        u.retain_grad()
        q1, q2 = lr.critic(obs, lr.critic_input(u, dist))
        actor_loss(dist.log_prob(u)[:, 0], q1, q2, 0.1).backward()
        assert u.grad is not None and float(u.grad.abs().sum()) > 0  # d loss / d DMP params
        last = lr.model.actor.net[-1].weight.grad  # the layer giving goal and weights
        assert last is not None and float(last[: lr.P].abs().sum()) > 0
    finally:
        opened.close()


def test_a_layer_norm_critic_is_built_saved_and_resumed(tmp_path):
    opened = _open(tmp_path, "ndp-sac", sac={"critic_layer_norm": True}, checkpoint_every=1)
    try:
        lr = opened.learner
        for net in (lr.critic, lr.critic_target):
            norms = [m for m in net.modules() if isinstance(m, torch.nn.LayerNorm)]
            assert len(norms) == 4  # two hidden layers in each of the two critics
        opened.train(1)
    finally:
        opened.close()
    saved = load_checkpoint(tmp_path / "ndp-sac", kind="rl")["sac"]["critic"]
    assert "q1.net.1.weight" in saved and saved["q1.net.1.weight"].shape == (256,)
    from ndp.rl.run import resume

    resume(tmp_path / "ndp-sac")  # the config brings the option back: the weights fit
    assert load_checkpoint(tmp_path / "ndp-sac", kind="rl")["global_step"] == 400


def test_chunked_sac_scores_the_whole_chunk(tmp_path):
    opened = _open(tmp_path, "sac-chunk")
    try:
        lr = opened.learner
        assert lr.k == 5 and lr.P == 5 * 2  # k actions of A = 2
        dist = lr._dist(torch.zeros(3, lr.obs_dim), torch.zeros(3, 2), torch.zeros(3, 2))
        c = lr.critic_input(dist.sample(), dist)
        assert c.shape == (3, 10) and float(c.abs().max()) <= 1.0
    finally:
        opened.close()


def test_a_resumed_sac_run_keeps_its_replay_and_continues(tmp_path):
    opened = _open(tmp_path, "sac", checkpoint_every=1)
    try:
        opened.train(2)
        saved = load_checkpoint(tmp_path / "sac", kind="rl")
        size = opened.learner.replay.size
        steps = opened.learner.grad_steps
    finally:
        opened.close()
    assert saved["sac"]["replay"]["size"] == size == 200  # 200 env steps at k = 1
    assert steps > 0
    from ndp.rl.run import resume

    resume(tmp_path / "sac")
    end = load_checkpoint(tmp_path / "sac", kind="rl")
    assert end["sac"]["replay"]["size"] == 400 and end["global_step"] == 400
    rows = read_metrics(tmp_path / "sac")
    assert [r["update"] for r in rows] == [1, 2, 3, 4]
    assert math.isfinite(rows[-1]["sac/alpha"]) and rows[-1]["sac/gradient_steps"] > steps


def test_the_three_methods_are_listed_and_ndp_sac_trains_resumes_and_exports(tmp_path, capsys):
    assert ndp_main(["rl", "methods"]) == 0
    out = capsys.readouterr().out
    listed = {line.split(":")[0] for line in out.splitlines()}
    assert {"sac", "sac-chunk", "ndp-sac"} <= listed
    run = tmp_path / "nsac"
    common = ["--task", "push-v3", "--algo", "ndp-sac", "--num-envs", "2", "--horizon", "20",
              "--steps-per-update", "50", "--sac-random-steps", "50", "--sac-batch-size", "16",
              "--eval-every", "0", "--no-progress", "--no-tensorboard",
              "--vector", "sync"]  # fmt: skip
    assert ndp_main(["rl", "train", *common, "--steps", "100", "--run-dir", str(run)]) == 0
    assert ndp_main(["rl", "train", "--resume", str(run), "--steps", "150"]) == 0
    assert load_checkpoint(run, kind="rl")["global_step"] == 150
    assert ndp_main(["rl", "export", str(run), str(tmp_path / "exp"), "--format", "onnx"]) == 0
    import ndp

    onnx = ndp.load_policy(tmp_path / "exp")  # an OnnxPolicy: onnxruntime, no torch model
    torch_pol = ndp.load_policy(run)
    from ndp.act_inputs import RobotState

    obs = np.linspace(-0.5, 0.5, 39)
    state = RobotState(np.array([0.0, 0.6, 0.2, -1.0]), np.zeros(4))
    a1 = onnx.act(obs, state)
    a2 = torch_pol.act(obs, state, deterministic=True)
    assert a1.shape == (5, 4) and np.allclose(a1, a2, atol=1e-4)
    # SAC trains on raw observations: the loaded policy neither normalises nor clips them (an
    # input 50 away from the origin reaches the network as it is, as in training)
    assert not torch_pol.obs_norm.enabled
    far = np.full(39, 50.0, dtype=np.float32)
    assert np.array_equal(torch_pol.obs_norm(far), far)
    a3 = onnx.act(far, state)
    assert np.allclose(a3, torch_pol.act(far, state, deterministic=True), atol=1e-4)


@pytest.mark.slow
def test_sac_learns_the_point_mass(tmp_path):
    """3,000 env steps, 2,500 gradient steps of batch 256 (about a minute on one free core):
    the deterministic policy reaches the target (measured 1.0 at seed 0)."""
    from ndp.rl.evaluate import evaluate

    opened = _open(tmp_path, "sac", steps=3000, sac={"random_steps": 500, "batch_size": 256})
    try:
        opened.train()
    finally:
        opened.close()
    assert evaluate(tmp_path / "sac", episodes=5)["success_any"] >= 0.8


def test_a_runaway_critic_is_said_once_and_its_peak_return_is_kept(tmp_path):
    """The rule (ndp.rl.sac.health): an estimate above 10x the largest mean episode return
    (at least 1) is a runaway. A real learner says it once on stderr as a RuntimeWarning, and
    the return it compares with is saved in the checkpoint, so a resumed run keeps it."""
    from ndp.rl.sac.health import q_runaway

    assert q_runaway(1001.0, 100.0) and not q_runaway(999.0, 100.0)
    assert q_runaway(11.0, 0.2) and not q_runaway(9.0, 0.2)  # returns near 0 count as 1
    assert q_runaway(11.0, -1.0) and not q_runaway(math.nan, 5.0)
    opened = _open(tmp_path, "sac", checkpoint_every=1)
    try:
        lr = opened.learner
        assert lr.return_peak is None
        with pytest.warns(RuntimeWarning, match="critic is running away") as said:
            lr._watch_critic({"charts/episode_return": -30.0, "sac/q": 100.0})  # 30: fine
            lr._watch_critic({"charts/episode_return": math.nan, "sac/q": 301.0})  # > 300
            lr._watch_critic({"charts/episode_return": 5.0, "sac/q": 1e6})  # said already
        assert len(said) == 1 and "301" in str(said[0].message)
        assert lr.return_peak == 30.0
        assert lr.state_dict()["sac"]["return_peak"] == 30.0
        opened.train(1)
        saved = load_checkpoint(tmp_path / "sac", kind="rl")
    finally:
        opened.close()
    assert saved["sac"]["return_peak"] >= 30.0


def test_the_replay_probe_reads_a_real_checkpoint(tmp_path):
    """benchmarks/sac_replay_probe.py on a tiny real run: its windows cover the replay's rows
    in order, its fractions are fractions, and it counts every stored bootstrap weight."""
    mod = _bench("sac_replay_probe")
    opened = _open(tmp_path, "sac", checkpoint_every=1)
    try:
        opened.train(2)
    finally:
        opened.close()
    out = mod.probe(tmp_path / "sac", windows=(0, 100, None))
    assert out["global_step"] == 200 and out["parameters"] == 2
    assert [w["decisions"] for w in out["windows"]] == [100, 100]
    assert all(
        0.0 <= w["edge_0.99"] <= w["edge_0.99_worst_parameter"] <= 1.0 for w in out["windows"]
    )
    assert sum(out["bootstrap_weights"].values()) == 200
    ppo = _open(tmp_path / "p", "ppo", checkpoint_every=1)
    try:
        ppo.train(1)
    finally:
        ppo.close()
    with pytest.raises(SystemExit, match=r"run_dir: .* is not a SAC-family run"):
        mod.probe(tmp_path / "p" / "ppo")  # a PPO run's checkpoint has no replay
    with pytest.raises(SystemExit, match=r"run_dir: checkpoint: no such file"):
        mod.probe(tmp_path / "nothing-here")


def _bench(name):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).parents[3] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize(("algo", "sac"), [("ndp-sac", {"critic_layer_norm": True}),
                                           ("sac-chunk", {})])  # fmt: skip
def test_the_critic_probe_reads_the_run_critic_as_trained(tmp_path, algo, sac):
    """benchmarks/sac_critic_probe.py on a tiny real run: its Q of the stored decisions is the
    trained critic's on the same rows, its TD error is its target minus that Q, its cosines
    are cosines; a non-SAC run is refused in one line."""
    mod = _bench("sac_critic_probe")
    opened = _open(tmp_path, algo, sac=sac, checkpoint_every=1)
    try:
        opened.train(2)
        critic = opened.learner.critic
    finally:
        opened.close()
    out = mod.probe(tmp_path / algo, rows=32, seed=3)
    data = load_checkpoint(tmp_path / algo, kind="rl")["sac"]["replay"]["data"]
    pick = np.random.default_rng(3).choice(len(data["u"]), 32, replace=False)
    with torch.no_grad():
        q = torch.minimum(*critic(torch.as_tensor(data["obs"][pick]),
                                  torch.as_tensor(data["critic_in"][pick])))  # fmt: skip
    assert out["rows"] == 32 and out["critic_layer_norm"] == bool(sac)
    assert out["q_replay"] == pytest.approx(float(q.mean()), rel=1e-5)
    assert out["td_mean"] == pytest.approx(out["target"] - out["q_replay"], abs=1e-4)
    assert -1.0 <= out["feature_cos"] <= 1.0 and out["feature_norm"] > 0
    with pytest.raises(SystemExit, match=r"run_dir: checkpoint: no such file"):
        mod.probe(tmp_path / "nothing-here")


def test_torch_threads_reach_the_update_of_a_sync_run(tmp_path, monkeypatch):
    """``--torch-threads 2`` with ``--vector sync``: the env factories (one torch thread, for
    worker processes) run in the trainer's process and no longer reset it to 1."""
    seen = []
    from ndp.rl.sac.learner import SACLearner

    step = SACLearner.gradient_step

    def spy(self, b):
        seen.append(torch.get_num_threads())
        return step(self, b)

    monkeypatch.setattr(SACLearner, "gradient_step", spy)
    before = torch.get_num_threads()
    try:
        opened = _open(tmp_path, "sac", steps=200, torch_threads=2, sac={"batch_size": 8})
        try:
            opened.train(1)
        finally:
            opened.close()
    finally:
        torch.set_num_threads(before)
    assert seen and set(seen) == {2}
