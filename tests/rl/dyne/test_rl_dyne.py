"""Dyn-E (--algo dyne): the embedding, TD3 in its latent, checkpoints, the CLI, bad input."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import torch

from ndp.cli import main as ndp_main
from ndp.rl import envs as rl_envs
from ndp.rl.config import TrainConfig, resolve_config
from ndp.rl.dyne.config import DyneConfig
from ndp.rl.methods import METHODS, POLICY_CHECKPOINT_KEYS
from ndp.runs import load_checkpoint, read_metrics

# small but complete: 4 exploration iterations of 500 env steps, then TD3
FAST = DyneConfig(explore_steps=2000, embed_updates=600, decoder_updates=600, updates_per_step=0.5)


def _cfg(tmp_path, name="r", task="point-mass", steps=6000, dyne=FAST, **kw):
    kw.setdefault("steps_per_update", 500)
    return TrainConfig(
        task=task,
        algo="dyne",
        steps=steps,
        vector="sync",
        run_dir=str(tmp_path / name),
        progress=False,
        tensorboard=False,
        dyne=dyne,
        **kw,
    )


def _open(cfg, resume=False):
    """The Dyn-E run of ``cfg``, opened by the run driver (``.learner`` is the DyneLearner)."""
    from ndp.rl.run import open_run

    return open_run(resolve_config(cfg), resume=resume, resolved=True)


def test_dyne_is_registered_with_the_td3_actor():
    m = METHODS["dyne"]
    assert m.head == "dyne" and m.learner is not None
    cfg = resolve_config(TrainConfig(task="point-mass", algo="dyne"))
    assert cfg.policy.head == "dyne" and cfg.policy.k == 5
    assert cfg.policy.hidden == (400, 300) and cfg.policy.activation == "relu"
    assert cfg.policy.ndp.n_basis is None
    assert TrainConfig.from_dict(cfg.to_dict()) == cfg
    # a config written before Dyn-E (no "dyne" key) still loads, with the defaults
    d = cfg.to_dict()
    d.pop("dyne")
    assert TrainConfig.from_dict(d).dyne == DyneConfig()


def test_dyne_runs_on_the_shared_off_policy_loop():
    from ndp.rl.dyne.learner import DyneLearner
    from ndp.rl.offpolicy.loop import OffPolicyLearner

    assert issubclass(DyneLearner, OffPolicyLearner)
    # no collection loop of its own: env stepping, replay insertion and evaluation are the loop's
    for name in ("iterate", "_decide", "_start"):
        assert getattr(DyneLearner, name) is getattr(OffPolicyLearner, name), name


def test_embedding_prediction_loss_falls_and_decoder_reconstructs(tmp_path):
    # measured (seeds 0, 1): prediction loss 0.36 over the first 10% of the steps -> 0.13,
    # cycle and predicted-effect errors 0.001, displacement error 0.08-0.11 of its spread
    cfg = _cfg(tmp_path, dyne=dataclasses.replace(FAST, embed_updates=1000, decoder_updates=1000))
    opened = _open(cfg)
    lr = opened.learner
    seen = {}
    fit = lr._fit_embedding

    def spy():  # the exploration data as the fit at the end of the exploration phase sees it
        seen["data"] = [np.concatenate(x) for x in zip(*lr._explore_data, strict=True)]
        seen["stats"] = fit()
        return seen["stats"]

    lr._fit_embedding = spy
    try:
        for _ in range(lr.n_explore):
            row = lr.iterate()  # the loop's iterations; the last one fits the embedding
    finally:
        opened.close()
    data, stats = seen["data"], seen["stats"]
    assert row["dyne/embed_loss"] == stats["embed_loss"] and lr.embedded
    s0, act, delta = (torch.as_tensor(x, dtype=torch.float32) for x in data)
    assert act.shape[1:] == (5, 2) and s0.shape[1] == delta.shape[1] == 4
    assert stats["sequences"] >= 350  # 2000 env steps = 400 chunks, the full ones
    # the whitened prediction error falls well below its start (and below predicting 0: 1.0)
    assert stats["embed_loss"] < 0.6 * stats["embed_loss_first"], stats
    assert stats["embed_loss"] < 0.5, stats
    emb, head = lr.embedding, lr.head
    with torch.no_grad():
        z = emb.whiten_latent(emb.encode(act)[0])
        rec = head.decode(z)  # decoded sequences [N, k, A]
        z_rec = emb.whiten_latent(emb.encode(rec)[0])
        pred, pred_rec = emb.predict(s0, emb.encode(act)[0]), emb.predict(s0, emb.encode(rec)[0])
    assert float(rec.abs().max()) <= 1.0  # tanh-bounded to the action range
    # the encoder maps a decoded sequence back onto its latent ...
    assert float(((z_rec - z) ** 2).mean()) < 0.02
    # ... so that it has the same predicted effect on the state ...
    assert float(((pred_rec - pred) ** 2).mean()) < 0.02
    # ... and the same physical effect: the point mass moves by 0.05 * sum of the actions
    disp, disp_rec = act.sum(1), rec.sum(1)
    err = float(((disp_rec - disp) ** 2).sum(1).mean())
    spread = float(((disp - disp.mean(0)) ** 2).sum(1).mean())
    assert err < 0.25 * spread, (err, spread)
    assert 1.0 < stats["max_latent"] < 10.0


@pytest.mark.slow  # a learning check (~10 s alone, a minute beside other work): make test-slow
def test_td3_in_the_latent_improves_on_point_mass_fast(tmp_path):
    """Small budget (6000 env steps, 2000 of them exploration; ~10 s): TD3 beats the random
    exploration phase clearly."""
    cfg = _cfg(tmp_path)
    opened = _open(cfg)
    try:
        last = opened.train()
    finally:
        opened.close()
    rows = read_metrics(tmp_path / "r")
    assert len(rows) == 12 and rows[-1]["global_step"] == 6000
    explore = [r for r in rows if r["update"] <= 4]
    assert math.isfinite(explore[-1]["dyne/embed_loss"])
    assert all(r["dyne/gradient_steps"] == 0 for r in explore)
    ret0 = np.mean([r["charts/episode_return"] for r in explore])
    ret1 = np.mean([r["charts/episode_return"] for r in rows[-2:]])
    assert ret1 > 0.5 * ret0, (ret0, ret1)  # returns are negative distances: at least halved
    # 0.5 gradient steps per env step once the buffer holds a batch (100 decisions)
    assert last["dyne/gradient_steps"] == pytest.approx(0.5 * (4000 - 500), abs=30)


@pytest.mark.slow
def test_td3_in_the_latent_solves_point_mass(tmp_path):
    """Default Dyn-E settings, 20k env steps (5k exploration): measured success 1.0 from about
    10k env steps on; 2-3 min."""
    cfg = _cfg(tmp_path, steps=20_000, dyne=DyneConfig(), steps_per_update=1000)
    opened = _open(cfg)
    try:
        opened.train()
    finally:
        opened.close()
    rows = read_metrics(tmp_path / "r")
    assert np.mean([r["charts/success_any"] for r in rows[-3:]]) >= 0.9
    from ndp.rl.evaluate import evaluate

    assert evaluate(tmp_path / "r", episodes=10)["success_any"] >= 0.9


def _state(lr):
    sd = lr.state_dict()
    sd.pop("rng", None)  # the session adds the global RNG state on save
    return sd


def _same(a, b, path="") -> None:
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for key in a:
            _same(a[key], b[key], f"{path}.{key}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{path}[{i}]")
    elif isinstance(a, torch.Tensor):
        assert torch.equal(a, b), path
    elif isinstance(a, np.ndarray):
        assert np.array_equal(a, b), path
    else:
        assert a == b, path


def test_checkpoint_round_trip_includes_the_replay_buffer(tmp_path):
    small = dataclasses.replace(FAST, embed_updates=100, decoder_updates=100, updates_per_step=0.1)
    cfg = _cfg(tmp_path, dyne=small)
    opened = _open(cfg)
    lr = opened.learner
    try:
        opened.train(6)  # 4 exploration iterations (checkpoint), then 2 of TD3
        opened.save()
        before = _state(lr)
        draws = (lr.rng.random(), torch.rand(1))
    finally:
        opened.close()
    ckpt = load_checkpoint(tmp_path / "r", kind="rl")
    assert set(POLICY_CHECKPOINT_KEYS) <= set(ckpt)
    replay = ckpt["dyne"]["replay"]
    assert replay["size"] == 2 * 500 // 5 and replay["data"]["obs"].shape == (200, 6)
    opened_again = _open(cfg, resume=True)
    again = opened_again.learner
    try:
        _same(_state(again), before)
        assert (again.rng.random(), torch.rand(1)) == draws  # the RNGs continue too
        opened_again.train()  # the budget to the end
    finally:
        opened_again.close()
    rows = read_metrics(tmp_path / "r")
    assert [r["update"] for r in rows] == list(range(1, 13))
    assert load_checkpoint(tmp_path / "r", kind="rl")["dyne"]["replay"]["size"] == 800


def test_cli_trains_resumes_evaluates_renders_and_exports(tmp_path, capsys):
    run = tmp_path / "run"
    base = ["rl", "train", "--task", "point-mass", "--algo", "dyne", "--run-dir", str(run),
            "--steps-per-update", "200", "--explore-steps", "400", "--embed-updates", "50",
            "--decoder-updates", "50", "--updates-per-step", "0.2", "--vector", "sync",
            "--no-progress", "--no-tensorboard"]  # fmt: skip
    assert ndp_main([*base, "--steps", "1000"]) == 0
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["algo"] == "dyne" and cfg["dyne"]["explore_steps"] == 400
    assert cfg["policy"]["hidden"] == [400, 300]
    capsys.readouterr()
    resume = ["rl", "train", "--resume", str(run), "--steps", "1400", "--no-progress"]
    assert ndp_main(resume) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["global_step"] == 1400
    assert len(read_metrics(run)) == 7
    assert ndp_main(["rl", "eval", str(run), "--episodes", "2"]) == 0
    outs = [json.loads(line) for line in capsys.readouterr().out.strip().splitlines()]
    assert [o["deterministic"] for o in outs] == [True, False] and outs[0]["episodes"] == 2
    assert ndp_main(["rl", "render", str(run), "--out", str(tmp_path / "v.mp4")]) == 0
    assert (tmp_path / "v.mp4").stat().st_size > 0
    assert ndp_main(["rl", "export", str(run), str(tmp_path / "exp")]) == 0
    import ndp

    pol, exp = ndp.load_policy(run), ndp.load_policy(tmp_path / "exp")
    env = pol.make_env()
    obs, info = env.reset(seed=3)
    a, b = pol.act(obs, info), exp.act(obs, info)
    assert a.shape == (5, 2) and np.array_equal(a, b)
    assert float(pol.model.head.max_latent) > 1.0  # the trained latent range, not the default


def _no_env(*a, **k):
    raise AssertionError("an environment was built")


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"dyne": {"explore_steps": 0}}, "explore_steps"),
        ({"dyne": {"batch_size": 10, "replay_size": 5}}, "batch_size"),
        ({"dyne": {"tau": 0.0}}, "tau"),
        ({"dyne": {"kl_weight": -1.0}}, "kl_weight"),
        ({"dyne": {"updates_per_step": 0.0}}, "updates_per_step"),
        ({"steps": 2000}, "leaves no TD3 iteration"),
    ],
)
def test_bad_input_fails_before_any_env(monkeypatch, tmp_path, kwargs, match):
    monkeypatch.setattr(rl_envs, "make_vector_env", _no_env)
    with pytest.raises(ValueError, match=match):
        if "dyne" in kwargs:
            kwargs = {"dyne": DyneConfig(**{"explore_steps": 2000, **kwargs["dyne"]})}
        _open(_cfg(tmp_path, **kwargs))
    assert not (tmp_path / "r" / "checkpoint.pt").exists()


def test_nan_stops_training_and_keeps_the_last_good_checkpoint(tmp_path):
    from ndp.rl.onpolicy.trainer import TrainingDivergedError

    cfg = _cfg(tmp_path, dyne=dataclasses.replace(FAST, embed_updates=50, decoder_updates=50))
    opened = _open(cfg)
    lr = opened.learner
    try:
        opened.train(5)  # exploration (checkpoint at update 4) + one TD3 iteration
        good = load_checkpoint(tmp_path / "r", kind="rl")
        assert good["update"] == 4
        with torch.no_grad():
            next(lr.critic.parameters()).fill_(float("nan"))
        with pytest.raises(TrainingDivergedError, match="last good checkpoint is kept"):
            opened.train()
    finally:
        opened.close()
    kept = load_checkpoint(tmp_path / "r", kind="rl")
    assert kept["update"] == 4
    _same(kept["model"], good["model"])


@pytest.mark.parametrize("task", ["push-v3", "throw"])
def test_smoke_real_tasks(tmp_path, task, record_actions):
    dyne = DyneConfig(explore_steps=100, embed_updates=20, decoder_updates=20,
                      updates_per_step=0.2, batch_size=16)  # fmt: skip
    cfg = _cfg(tmp_path, task=task, steps=300, dyne=dyne, num_envs=2, horizon=25,
               steps_per_update=100)  # fmt: skip
    opened = _open(cfg)
    lr = opened.learner
    try:
        seen = record_actions(lr.envs)
        metrics = opened.train()
    finally:
        opened.close()
    acts = np.concatenate(seen)
    assert acts.shape[1:] == (5, lr.spec.action_dim)
    assert acts.min() >= -1.0 and acts.max() <= 1.0
    assert metrics["charts/episodes"] >= 2 and metrics["charts/episode_length"] == 25
    for key in ("losses/value", "losses/policy", "dyne/q", "charts/episode_return"):
        assert math.isfinite(metrics[key]), key
    assert len(read_metrics(tmp_path / "r")) == 3
    from ndp.rl.evaluate import evaluate

    out = evaluate(tmp_path / "r", episodes=1)
    assert 0.0 <= out["success_any"] <= 1.0


def _cli_args(run, steps):
    return ["rl", "train", "--task", "point-mass", "--algo", "dyne", "--run-dir", str(run),
            "--steps", str(steps), "--steps-per-update", "200", "--explore-steps", "400",
            "--embed-updates", "50", "--decoder-updates", "50", "--updates-per-step", "0.2",
            "--checkpoint-every", "2", "--vector", "sync", "--no-progress",
            "--no-tensorboard"]  # fmt: skip


def test_two_runs_with_one_seed_are_identical(tmp_path):
    from ndp.rl.logger import TIME_METRICS

    for name in ("a", "b"):
        assert ndp_main(_cli_args(tmp_path / name, 1200)) == 0
    rows_a, rows_b = read_metrics(tmp_path / "a"), read_metrics(tmp_path / "b")
    drop = {*TIME_METRICS}
    assert [{k: v for k, v in r.items() if k not in drop} for r in rows_a] == [
        {k: v for k, v in r.items() if k not in drop} for r in rows_b
    ]
    _same(load_checkpoint(tmp_path / "a")["model"], load_checkpoint(tmp_path / "b")["model"])


def test_sigkill_then_resume(tmp_path, kill_after_rows):
    import signal
    import sys

    run, n = tmp_path / "run", 20
    proc = kill_after_rows([sys.executable, "-m", "ndp.cli", *_cli_args(run, 200 * n)], run)
    assert proc.returncode == -signal.SIGKILL
    assert len(read_metrics(run)) < n
    assert ndp_main(["rl", "train", "--resume", str(run), "--no-progress"]) == 0
    rows = read_metrics(run)
    assert [r["update"] for r in rows] == list(range(1, n + 1))
    ckpt = load_checkpoint(run, kind="rl")
    assert ckpt["update"] == n and ckpt["global_step"] == 200 * n
    # every TD3 iteration's 40 decisions are in the buffer exactly once
    assert ckpt["dyne"]["replay"]["size"] == 40 * (n - 2)


def test_exploration_preset_is_at_most_a_sixth_of_the_budget():
    from ndp.rl.config import TrainConfig
    from ndp.rl.dyne import resolve_dyne_config

    short = resolve_dyne_config(TrainConfig(task="push-v3", algo="dyne", steps=20_000))
    assert short.dyne.explore_steps == 3333  # the 50k preset would leave no TD3 iteration
    full = resolve_dyne_config(TrainConfig(task="push-v3", algo="dyne", steps=300_000))
    assert full.dyne.explore_steps == 50_000


def test_a_td3_phase_shorter_than_one_batch_is_refused():
    import dataclasses

    from ndp.rl.config import TrainConfig
    from ndp.rl.dyne import check_budget
    from ndp.rl.dyne.config import DyneConfig

    cfg = TrainConfig(
        task="point-mass",
        algo="dyne",
        steps=4000,
        num_envs=2,
        steps_per_update=200,
        dyne=DyneConfig(explore_steps=200),
    )
    check_budget(cfg)  # 19 TD3 iterations of 40 decisions: 760 >= 100
    small = dataclasses.replace(cfg, steps=600)  # 2 TD3 iterations: 80 decisions
    with pytest.raises(ValueError, match=r"steps: Dyn-E's TD3 phase collects 80 decision\(s\)"):
        check_budget(small)
