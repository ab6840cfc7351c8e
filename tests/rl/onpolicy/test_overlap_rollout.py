"""``vector='overlap'``: two env groups in alternation give the serial rollout (PPO, PPO-multi,
NDP on the toy task, episodes ending inside the rollout), refuse what they cannot run, and
resume from a checkpoint."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from ndp.envs.vector import OverlapVectorEnv, WorkerVectorEnv
from ndp.policies import NDPHeadConfig, PolicyConfig
from ndp.rl.config import PPOConfig, TrainConfig
from ndp.rl.run import open_run
from ndp.runs import load_checkpoint, read_metrics

FAST = PPOConfig(minibatches=4, lr=1e-3)


def _cfg(tmp_path, name, **kw):
    base = {
        "task": "point-mass",
        "algo": "ndp",
        "steps": 2048,
        "num_envs": 4,
        "run_dir": str(tmp_path / name),
        "progress": False,
        "tensorboard": False,
        "steps_per_update": 400,
        "horizon": 30,  # several episodes end (truncated) inside each rollout
        "ppo": FAST,
        "eval_every": 0,
    }
    return TrainConfig(**{**base, **kw})


ROLLOUT_KEYS = ("obs", "y0", "dy0", "z", "logp", "values", "adv", "returns", "mask")


def _collect(cfg, updates=2):
    """``updates`` rollouts (with a PPO update between them) and the final state."""
    opened = open_run(cfg)
    tr = opened.learner
    try:
        torch.manual_seed(0)
        batches = []
        for _ in range(updates):
            batches.append(tr.collect())
            tr.learn(batches[-1])
        return batches, tr.obs_norm.state_dict(), tr.ret_norm.state_dict(), tr.envs
    finally:
        opened.close()


@pytest.mark.parametrize("algo", ["ndp", "ppo-multi", "ppo", "ndp-param-noise"])
def test_overlap_rollout_is_the_sync_rollout_without_obs_norm(tmp_path, algo):
    """Bit for bit: every rollout tensor, the episodes' rows, over two rollouts and an update."""
    kw = {"algo": algo, "norm_obs": False}
    if algo == "ndp-param-noise":  # one draw per decision (ParamGaussian)
        kw = {"norm_obs": False, "policy": PolicyConfig(ndp=NDPHeadConfig(param_noise=True))}
    sync, *_, envs_s = _collect(_cfg(tmp_path, "s", vector="sync", **kw))
    over, *_, envs_o = _collect(_cfg(tmp_path, "o", vector="overlap", **kw))
    assert isinstance(envs_o, OverlapVectorEnv) and not isinstance(envs_s, OverlapVectorEnv)
    for bs, bo in zip(sync, over, strict=True):
        assert bs["episodes"] and bs["episodes"] == bo["episodes"]  # episodes ended, same rows
        assert bs["executed"] == bo["executed"]
        for key in ROLLOUT_KEYS:
            torch.testing.assert_close(bo[key], bs[key], rtol=0, atol=0, msg=key)
        assert bs["goal_norm"] == bo["goal_norm"] or (
            np.isnan(bs["goal_norm"]) and np.isnan(bo["goal_norm"])
        )


def test_overlap_with_obs_norm_differs_only_through_the_normaliser(tmp_path):
    """With the observation normaliser: the same observations merged (in halves), the same
    episodes at the first rollout's start; the decisions of group B at t = 0 see every
    observation of t = 0, as the serial ones do."""
    sync, norm_s, _, _ = _collect(_cfg(tmp_path, "s", vector="sync"), updates=1)
    over, norm_o, ret_o, _ = _collect(_cfg(tmp_path, "o", vector="overlap"), updates=1)
    assert norm_o["count"] == norm_s["count"]
    # the first decision's raw observations are the same (same seeds): its normalised rows of
    # group B (statistics of all E observations, merged in two halves) agree to rounding
    E = 4
    torch.testing.assert_close(over[0]["obs"][2:E], sync[0]["obs"][2:E], rtol=1e-5, atol=1e-5)
    assert np.isfinite(norm_o["mean"]).all() and np.isfinite(ret_o["var"]).all()
    assert over[0]["executed"] == sync[0]["executed"]


def test_overlap_env_steps_as_the_worker_env(tmp_path):
    from ndp.rl.config import resolve_config
    from ndp.rl.envs import resolve_task, run_envs

    cfg = resolve_config(_cfg(tmp_path, "e", vector="overlap", horizon=3))
    task = resolve_task(cfg.task)
    over, _ = run_envs(cfg, task)
    work, _ = run_envs(resolve_config(_cfg(tmp_path, "w", vector="workers", horizon=3)), task)
    assert isinstance(over, OverlapVectorEnv) and isinstance(work, WorkerVectorEnv)
    try:
        rng = np.random.default_rng(0)
        (oo, io), (ow, iw) = over.reset(seed=[1, 2, 3, 4]), work.reset(seed=[1, 2, 3, 4])
        np.testing.assert_array_equal(oo, ow)
        assert io.keys() == iw.keys()
        for _ in range(4):  # episodes of 3 decisions end at the third
            act = rng.uniform(-1, 1, size=(4, cfg.k, 2))
            so, sw = over.step(act), work.step(act)
            for a, b in zip(so[:4], sw[:4], strict=True):
                np.testing.assert_array_equal(a, b)
            assert so[4].keys() == sw[4].keys()
            for key, val in sw[4].items():
                if key == "final_info":
                    done = sw[2] | sw[3]
                    for fk, fv in val.items():
                        np.testing.assert_array_equal(so[4][key][fk][done], fv[done])
                elif key == "final_obs":
                    for i in np.flatnonzero(sw[2] | sw[3]):
                        np.testing.assert_array_equal(so[4][key][i], val[i])
                else:
                    np.testing.assert_array_equal(so[4][key], val)
    finally:
        over.close()
        work.close()


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"num_envs": 3}, "vector: 'overlap' .* even num_envs >= 2, got num_envs=3"),
        ({"num_envs": 1}, "vector: 'overlap' .* got num_envs=1"),
        ({"algo": "ppo", "policy": {"noise": "ar1"}}, "vector: 'overlap' .*noise='ar1'"),
    ],
)
def test_overlap_refusals_name_the_field(tmp_path, kw, match):
    if "policy" in kw:
        kw = {**kw, "policy": PolicyConfig(**kw["policy"])}
    with pytest.raises(ValueError, match=match) as err:
        _cfg(tmp_path, "x", vector="overlap", **kw)
    assert "\n" not in str(err.value)


def test_overlap_run_resumes_from_its_checkpoint(tmp_path):
    """Interrupted after one update and resumed, an overlapped run ends where the sync run
    (no observation normaliser) ends: the same model."""
    kw = {"steps": 800, "norm_obs": False}
    cfg = _cfg(tmp_path, "o", vector="overlap", **kw)
    opened = open_run(cfg)
    try:
        opened.train(1)
        opened.save()
    finally:
        opened.close()
    again = open_run(cfg, resume=True)
    try:
        again.train()
    finally:
        again.close()
    ref = open_run(_cfg(tmp_path, "s", vector="sync", **kw))
    try:
        ref.train(1)
        ref.save()
    finally:
        ref.close()
    ref = open_run(_cfg(tmp_path, "s", vector="sync", **kw), resume=True)
    try:
        ref.train()
    finally:
        ref.close()
    assert [r["update"] for r in read_metrics(tmp_path / "o")] == [1, 2]
    mo = load_checkpoint(tmp_path / "o", kind="rl")["model"]
    ms = load_checkpoint(tmp_path / "s", kind="rl")["model"]
    for key in ms:
        torch.testing.assert_close(mo[key], ms[key], rtol=0, atol=0, msg=key)


def test_overlap_divergence_while_a_group_steps_stops_and_closes(tmp_path):
    """A decision that fails while the other group's step is in flight raises the divergence,
    and the run closes (the in-flight step's reply is drained, the workers stop)."""
    from ndp.rl.onpolicy.trainer import TrainingDivergedError

    opened = open_run(_cfg(tmp_path, "o", vector="overlap"))
    tr = opened.learner
    calls = {"n": 0}
    real = tr.decide

    def failing(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 4:  # group B's decision 1, while group A steps its decision 1
            raise tr._diverged("non-finite actions (test)")
        return real(*args, **kwargs)

    tr.decide = failing
    try:
        with pytest.raises(TrainingDivergedError, match="non-finite actions"):
            tr.collect()
    finally:
        opened.close()
    envs = tr.envs
    assert isinstance(envs, OverlapVectorEnv)
    assert all(not p.is_alive() for g in envs.groups for p in g._procs)
