"""Trainer on the toy task: learning, determinism, NaN stop, termination handling, CLI smoke."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env

from ndp.cli import main as ndp_main
from ndp.envs.point_mass import PointMassEnv
from ndp.policies import NDPHeadConfig, PolicyConfig
from ndp.rl.config import PPOConfig, TrainConfig
from ndp.rl.evaluate import evaluate
from ndp.rl.logger import TIME_METRICS
from ndp.rl.onpolicy.trainer import TrainingDivergedError
from ndp.rl.run import open_run, train
from ndp.runs import load_checkpoint, read_metrics

FAST = PPOConfig(minibatches=4, lr=1e-3)  # with steps_per_update=512 (_cfg)


def _cfg(tmp_path, name="run", **kw):
    base = {
        "task": "point-mass",
        "algo": "ndp",
        "steps": 2048,
        "num_envs": 4,
        "run_dir": str(tmp_path / name),
        "progress": False,
        "tensorboard": False,
        "steps_per_update": 512,
        "ppo": FAST,
        "vector": "sync",
    }
    return TrainConfig(**{**base, **kw})


def test_point_mass_passes_gymnasium_check_env():
    check_env(PointMassEnv(), skip_render_check=True)


def test_point_mass_seeded_spec_and_bounded_inverse_controller():
    from ndp.envs import TaskSpec
    from ndp.envs.point_mass import make_point_mass_env
    from ndp.envs.spec import toy_spec as point_mass_spec

    spec = point_mass_spec()
    assert isinstance(spec, TaskSpec) and spec.dmp_dofs == spec.action_dim == 2
    a, b = make_point_mass_env(seed=3), make_point_mass_env(seed=3)
    oa, ia = a.reset()
    ob, _ = b.reset()
    np.testing.assert_array_equal(oa, ob)
    np.testing.assert_array_equal(ia["robot_pos"], oa[:2])
    for _ in range(5):
        oa, ra, *_ = a.step(np.array([0.7, -2.0]))
        ob, rb, *_ = b.step(np.array([0.7, -2.0]))
    np.testing.assert_array_equal(oa, ob)
    assert ra == rb
    traj = torch.zeros(1, 6, 2)
    traj[0, :, 0] = torch.linspace(0, 1, 6)  # 0.2 m per sub-step: far beyond one action
    acts = spec.inverse_controller(traj)
    assert acts.shape == (1, 5, 2) and float(acts.max()) == 1.0


def test_ndp_learns_point_mass_within_seconds(tmp_path):
    metrics = train(_cfg(tmp_path, steps=20_000))
    rows = read_metrics(tmp_path / "run" / "metrics.csv")
    assert len(rows) == math.ceil(20_000 / 520)
    late = np.mean([r["charts/success_any"] for r in rows[-4:]])
    early = np.mean([r["charts/success_any"] for r in rows[:2]])
    assert late >= 0.8, f"success {late:.2f} (early {early:.2f})"
    assert late > early + 0.3
    assert metrics["dmp/goal_norm"] > 0
    ev = evaluate(tmp_path / "run", episodes=10, deterministic=True)
    assert ev["success_any"] >= 0.8


def test_same_seed_identical_metrics_and_different_seed_differs(tmp_path):
    cfg = _cfg(tmp_path, "a", steps=1560)
    train(cfg)
    train(_cfg(tmp_path, "b", steps=1560))
    train(_cfg(tmp_path, "c", steps=1560, seed=1))

    def strip(rows):
        return [{k: v for k, v in r.items() if k not in TIME_METRICS} for r in rows]

    a = strip(read_metrics(tmp_path / "a" / "metrics.csv"))
    b = strip(read_metrics(tmp_path / "b" / "metrics.csv"))
    c = strip(read_metrics(tmp_path / "c" / "metrics.csv"))
    assert len(a) == 3
    assert a == b  # bit-identical (NaN-free rows compare equal)
    assert a != c
    wa = load_checkpoint(tmp_path / "a" / "checkpoint.pt")["model"]
    wb = load_checkpoint(tmp_path / "b" / "checkpoint.pt")["model"]
    assert all(torch.equal(wa[k], wb[k]) for k in wa)


def test_nan_parameter_stops_training_and_keeps_last_good_checkpoint(tmp_path):
    opened = open_run(_cfg(tmp_path, checkpoint_every=1))
    tr = opened.learner
    try:
        opened.train(1)
        ckpt = tmp_path / "run" / "checkpoint.pt"
        before = ckpt.read_bytes()
        with torch.no_grad():
            tr.model.actor.net[0].weight[0, 0] = float("nan")
        with pytest.raises(TrainingDivergedError, match="last good checkpoint is kept"):
            opened.train(1)
        assert ckpt.read_bytes() == before
        state = load_checkpoint(ckpt)
        assert state["update"] == 1
        assert all(torch.isfinite(v).all() for v in state["model"].values())
    finally:
        opened.close()


def test_nan_loss_stops_training(tmp_path, monkeypatch):
    opened = open_run(_cfg(tmp_path, algo="ppo-multi"))
    try:
        monkeypatch.setattr(
            "ndp.rl.onpolicy.trainer.value_loss", lambda *a, **k: torch.tensor(float("nan"))
        )
        with pytest.raises(TrainingDivergedError, match="non-finite loss"):
            opened.train(1)
        assert not (tmp_path / "run" / "checkpoint.pt").exists()
    finally:
        opened.close()


def test_terminated_episodes_and_all_methods_run(tmp_path, monkeypatch):
    # Episodes that end mid-decision (terminate on success) exercise masks and termination.
    import ndp.rl.onpolicy.trainer as rl_trainer
    from ndp.rl import envs as rl_envs

    orig = rl_envs.resolve_task

    def toy_terminating(name, **options):
        h = orig(name, **options)
        return rl_envs.TaskHandle(h.spec, lambda **kw: h.make(terminate_on_success=True, **kw))

    monkeypatch.setattr(rl_trainer, "resolve_task", toy_terminating)
    for algo in ("ndp", "ppo", "ppo-multi"):
        opened = open_run(_cfg(tmp_path, algo, algo=algo, steps=1040))
        tr = opened.learner
        try:
            batch = tr.collect()
            m = batch["mask"].numpy()
            assert m.shape[1] == tr.k
            # executed sub-steps are a prefix; advantages vanish where nothing ran
            assert np.all(np.diff(m, axis=1) <= 0)
            assert np.all(batch["adv"].numpy()[m == 0] == 0)
            stats = tr.learn(batch)
            assert all(math.isfinite(stats[k]) for k in ("policy", "value", "approx_kl"))
        finally:
            opened.close()


def test_param_noise_trains(tmp_path):
    m = train(_cfg(tmp_path, steps=1040, policy=PolicyConfig(ndp=NDPHeadConfig(param_noise=True))))
    assert math.isfinite(m["losses/policy"]) and m["update"] == 2


def test_param_noise_uses_one_decision_level_advantage(tmp_path, monkeypatch):
    """Parameter-space exploration: one clipped term per decision whose advantage is the
    decision's own GAE advantage A[:, 0] (normalised over decisions), not a mean over k."""
    import ndp.rl.onpolicy.trainer as trainer_mod
    from ndp.rl.onpolicy.losses import normalize_advantages

    seen = []
    real = trainer_mod.policy_loss

    def spy(new_logp, old_logp, adv, mask, clip):
        seen.append((new_logp.shape, adv.detach().clone(), mask.clone()))
        return real(new_logp, old_logp, adv, mask, clip)

    monkeypatch.setattr(trainer_mod, "policy_loss", spy)
    ppo = PPOConfig(minibatches=1, epochs=1, lr=1e-3)
    opened = open_run(
        _cfg(tmp_path, ppo=ppo, policy=PolicyConfig(ndp=NDPHeadConfig(param_noise=True)))
    )
    tr = opened.learner
    try:
        batch = tr.collect()
        torch.manual_seed(0)
        tr.learn(batch)
    finally:
        opened.close()
    ((shape, adv, mask),) = seen
    assert shape[1] == 1 and adv.shape[1] == 1 and mask.shape[1] == 1
    expected = normalize_advantages(batch["adv"][:, :1], batch["mask"][:, :1])
    # one mini-batch, one epoch: the same decisions in permuted order
    torch.testing.assert_close(
        torch.sort(adv.flatten()).values, torch.sort(expected.flatten()).values
    )


def _ppo_methods() -> list[tuple[str, str]]:
    """(method, task) of every registered method the PPO trainer trains (VICES on the torque
    variant of push-v3, the others on the toy task)."""
    from ndp.rl.methods import METHODS

    out = []
    for name, m in METHODS.items():
        if m.learner is not None:  # trained by another learner (Dyn-E: TD3)
            continue
        out.append((name, "push-v3" if m.task_variant is not None else "point-mass"))
    return out


@pytest.mark.parametrize("algo,task", _ppo_methods())
def test_every_head_gets_the_advantage_its_distribution_asks_for(tmp_path, monkeypatch, algo, task):
    """The trainer reads "one log-prob per decision" from the distribution (per_decision), never
    from a head attribute: a per-decision distribution gets the decision's advantage A[:, :1],
    a per-sub-action one the k sub-step advantages. vices-low-freq (HoldHead, a ParamGaussian
    without param_noise) was trained with the k sub-step advantages before this rule."""
    import ndp.rl.onpolicy.trainer as trainer_mod

    seen = []
    real_pl, real_gl = trainer_mod.policy_loss, trainer_mod.gaussian_policy_loss

    def spy_pl(new_logp, old_logp, adv, mask, clip):
        seen.append((new_logp.shape[1], adv.shape[1]))
        return real_pl(new_logp, old_logp, adv, mask, clip)

    def spy_gl(mean, log_std, z, old_logp, adv, mask, clip):
        seen.append((old_logp.shape[1], adv.shape[1]))
        return real_gl(mean, log_std, z, old_logp, adv, mask, clip)

    monkeypatch.setattr(trainer_mod, "policy_loss", spy_pl)
    monkeypatch.setattr(trainer_mod, "gaussian_policy_loss", spy_gl)
    ppo = PPOConfig(minibatches=1, epochs=1)
    opened = open_run(_cfg(tmp_path, algo=algo, task=task, ppo=ppo, num_envs=2, steps=256,
                           steps_per_update=256))  # fmt: skip
    tr = opened.learner
    try:
        batch = tr.collect()
        obs = torch.zeros(1, tr.obs_dim)
        y0 = torch.zeros(1, tr.spec.dmp_dofs)
        dist, _ = tr.model.distribution(obs, y0, y0)
        tr.learn(batch)
    finally:
        opened.close()
    assert batch["per_decision"] == dist.per_decision
    ((logp_cols, adv_cols),) = seen
    if dist.per_decision:
        assert logp_cols == 1 and adv_cols == 1
    else:
        assert logp_cols == adv_cols == tr.k
    if algo == "vices-low-freq":
        assert dist.per_decision and tr.k > 1  # the case the old rule got wrong


def test_minibatch_advantage_normalisation(tmp_path, monkeypatch):
    import ndp.rl.onpolicy.trainer as trainer_mod

    seen = []
    real = trainer_mod.gaussian_policy_loss  # PPO's Gaussian takes the fused surrogate

    def spy(mean, log_std, z, old_logp, adv, mask, clip):
        seen.append((adv.detach(), mask))
        return real(mean, log_std, z, old_logp, adv, mask, clip)

    monkeypatch.setattr(trainer_mod, "gaussian_policy_loss", spy)
    ppo = PPOConfig(minibatches=4, epochs=1, adv_norm_scope="minibatch")
    opened = open_run(_cfg(tmp_path, algo="ppo", ppo=ppo))
    tr = opened.learner
    try:
        tr.learn(tr.collect())
    finally:
        opened.close()
    assert len(seen) == 4
    for adv, mask in seen:  # each mini-batch on its own has mean 0 and std 1
        a = adv[mask > 0]
        assert abs(float(a.mean())) < 1e-5 and abs(float(a.std()) - 1.0) < 1e-3


def test_cli_train_eval_render(tmp_path, capsys):
    run = tmp_path / "cli"
    rc = ndp_main(
        [
            "rl",
            "train",
            "--task",
            "point-mass",
            "--algo",
            "ppo-multi",
            "--steps",
            "520",
            "--steps-per-update",
            "512",
            "--minibatches",
            "4",
            "--run-dir",
            str(run),
            "--no-progress",
            "--no-tensorboard",
        ]
    )
    assert rc == 0
    assert (run / "config.json").is_file() and (run / "checkpoint.pt").is_file()
    assert ndp_main(["rl", "eval", str(run), "--episodes", "2"]) == 0
    out = capsys.readouterr().out
    assert '"deterministic": true' in out and '"deterministic": false' in out
    assert ndp_main(["rl", "render", str(run), "--out", str(tmp_path / "v.mp4")]) == 0
    assert (tmp_path / "v.mp4").stat().st_size > 0
    assert ndp_main(["rl", "train", "--task", "nope-v3"]) == 2
    assert ndp_main(["rl", "train", "--algo", "dqn"]) == 2
    assert ndp_main(["rl", "eval", str(tmp_path / "missing")]) == 2
    # a second fresh run into the same directory is refused (use --resume)
    assert ndp_main(["rl", "train", "--task", "point-mass", "--run-dir", str(run)]) == 2


@pytest.mark.parametrize("task,algo", [("reach-v3", "ndp"), ("point-mass", "ppo")])
def test_worker_vector_env_gives_the_sync_rollout(tmp_path, task, algo):
    """Same seed, same initial policy: env workers (2 workers x 2 envs, shared memory) give
    the same rollout as the one-process sync env, episode ends and autoresets included."""
    ppo = PPOConfig(minibatches=4)
    batches = []
    for vector in ("sync", "workers"):
        cfg = _cfg(
            tmp_path,
            vector,
            task=task,
            algo=algo,
            horizon=30,
            steps_per_update=600 if algo == "ndp" else 400,
            ppo=ppo,
            vector=vector,
            env_workers=2 if vector == "workers" else None,
        )
        opened = open_run(cfg)
        tr = opened.learner
        try:
            if vector == "workers":
                assert type(tr.envs).__name__ == "WorkerVectorEnv"
                assert tr.envs.num_workers == 2
            batches.append(tr.collect())
        finally:
            opened.close()
    a, b = batches
    assert len(a["episodes"]) > 0 and a["episodes"] == b["episodes"]
    for key in ("obs", "y0", "dy0", "z", "logp", "adv", "returns", "mask"):
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=0, msg=key)


def test_async_vector_env_matches_sync(tmp_path):
    train(_cfg(tmp_path, "sync", steps=1040, num_envs=2))
    train(_cfg(tmp_path, "async", steps=1040, num_envs=2, vector="async"))
    a = read_metrics(tmp_path / "sync" / "metrics.csv")
    b = read_metrics(tmp_path / "async" / "metrics.csv")
    key = "charts/episode_return"
    assert [r[key] for r in a] == [r[key] for r in b]


def test_device_option_is_checked_before_anything_runs():
    from ndp.rl.config import TrainConfig

    with pytest.raises(ValueError, match="device: expected a torch device"):
        TrainConfig(device="gpu0")


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_update_on_cuda_rollout_on_cpu(tmp_path):
    from ndp.rl.config import TrainConfig
    from ndp.rl.run import open_run

    cfg = TrainConfig(task="point-mass", algo="ndp", steps=1040, device="cuda", vector="sync",
                      run_dir=str(tmp_path / "r"), progress=False, tensorboard=False)  # fmt: skip
    opened = open_run(cfg)
    tr = opened.learner
    try:
        m = opened.train()
        assert math.isfinite(m["losses/policy"])
        assert next(tr.model.parameters()).device.type == "cuda"
        assert next(tr.rollout_model.parameters()).device.type == "cpu"
        learner, actor = tr.model.state_dict(), tr.rollout_model.state_dict()
        for name, a in learner.items():
            assert torch.equal(a.cpu(), actor[name])  # the rollout acts with the updated policy
    finally:
        opened.close()


@pytest.mark.parametrize("algo", ["ndp", "ppo-multi"])
def test_decide_refuses_non_finite_inputs_and_actions(tmp_path, algo):
    """A NaN observation stops the rollout: as a non-finite DMP input (NDP's head checks its
    inputs first) or as non-finite actions; an Inf robot state as a non-finite goal."""
    opened = open_run(_cfg(tmp_path, algo=algo))
    try:
        tr = opened.learner
        y0, dy0 = tr.decision_start()
        obs = torch.zeros(tr.num_envs, tr.obs_dim)
        d = tr.decide(obs, y0, dy0)
        assert bool(((d.act >= tr.low) & (d.act <= tr.high)).all())
        obs[1, 0] = float("nan")
        what = "non-finite DMP input" if algo == "ndp" else "non-finite actions"
        with pytest.raises(TrainingDivergedError, match=what):
            tr.decide(obs, y0, dy0)
        if algo == "ndp":
            y0 = y0.clone()
            y0[0, 0] = float("inf")
            with pytest.raises(TrainingDivergedError, match=r"the rollout \(goal: expected finite"):
                tr.decide(torch.zeros_like(obs), y0, dy0)
    finally:
        opened.close()
