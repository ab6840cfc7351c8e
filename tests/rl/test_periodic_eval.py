"""Periodic deterministic evaluation (ndp.rl.periodic_eval) and the release's execution."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ndp.envs import ChunkedEnv, make_env
from ndp.rl.config import TrainConfig
from ndp.rl.logger import TIME_METRICS
from ndp.rl.periodic_eval import EVAL_METRICS, eval_due
from ndp.rl.run import train
from ndp.runs import read_metrics


def _run(tmp_path, name: str, algo: str = "ndp", **kw) -> list[dict[str, float]]:
    cfg = TrainConfig(
        task="point-mass", algo=algo, steps=2400, num_envs=2, vector="sync", seed=3,
        run_dir=str(tmp_path / name), progress=False, tensorboard=False,
        **kw,
    )  # fmt: skip
    cfg = dataclasses.replace(cfg, steps_per_update=400)
    train(cfg)
    return read_metrics(tmp_path / name)


@pytest.mark.parametrize("algo", ["ndp", "ppo"])
def test_evaluation_does_not_change_the_training_stream(tmp_path, algo):
    """Same seed, evaluation on and off: every training column is identical; the evaluated run
    has eval/* where due (every 800 env steps and after the last update), NaN elsewhere."""
    off = _run(tmp_path, "off", algo, eval_every=0)
    on = _run(tmp_path, "on", algo, eval_every=800, eval_episodes=2)
    assert len(on) == len(off) == 6
    skip = set(TIME_METRICS) | set(EVAL_METRICS)
    for a, b in zip(off, on, strict=True):
        for key in a:
            if key in skip:
                continue
            assert (math.isnan(a[key]) and math.isnan(b[key])) or a[key] == b[key], key
        assert all(math.isnan(a[k]) for k in EVAL_METRICS)
    evaluated = [r["global_step"] for r in on if not math.isnan(r["eval/success_any"])]
    assert evaluated == [800.0, 1600.0, 2400.0]  # 400 env steps per update
    for r in on:
        if not math.isnan(r["eval/success_any"]):
            assert r["eval/episodes"] == 2 and 0.0 <= r["eval/success_any"] <= 1.0


def test_evaluation_is_the_deterministic_policy_on_the_evaluation_seeds(tmp_path):
    """The logged evaluation equals ndp rl eval's (mode, seeds EVAL_SEED..) of the final
    policy."""
    from ndp.rl.evaluate import evaluate

    rows = _run(tmp_path, "r", "ndp", eval_every=2400, eval_episodes=3)
    got = evaluate(tmp_path / "r", episodes=3, deterministic=True)
    assert rows[-1]["eval/success_any"] == pytest.approx(got["success_any"])
    assert rows[-1]["eval/return"] == pytest.approx(got["episode_return"], rel=1e-5)


def test_eval_due_rule():
    assert not eval_due(0, 0, 10_000, True)  # off
    assert eval_due(1000, 900, 1100, False) and not eval_due(1000, 1100, 1900, False)
    assert eval_due(1000, 1100, 1500, True)  # the last update always


def test_bad_evaluation_options_are_refused():
    with pytest.raises(ValueError, match="eval_every: expected an integer >= 0"):
        TrainConfig(eval_every=-1)
    with pytest.raises(ValueError, match="eval_episodes: expected an integer >= 0"):
        TrainConfig(eval_episodes=1.5)  # type: ignore[arg-type]


# ------------------------------------------------------------------ first-held execution


def test_first_held_runs_the_first_sub_action_k_times():
    """execution='first-held' is the all-executed env given the first sub-action k times."""
    k = 5
    rng = np.random.default_rng(0)
    held = ChunkedEnv(make_env("point-mass"), k, execution="first-held")
    ref = ChunkedEnv(make_env("point-mass"), k)
    o1, _ = held.reset(seed=4)
    o2, _ = ref.reset(seed=4)
    np.testing.assert_array_equal(o1, o2)
    moved_differently = False
    for _ in range(6):
        a = rng.uniform(-1, 1, size=(k, 2))
        o1, r1, _, _, i1 = held.step(a)
        o2, r2, _, _, i2 = ref.step(np.repeat(a[:1], k, axis=0))
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(i1["sub_rewards"], i2["sub_rewards"])
        assert r1 == r2
        other = ChunkedEnv(make_env("point-mass"), k)
        other.reset(seed=4)
        moved_differently |= not np.array_equal(other.step(a)[0], o1)
    assert moved_differently
    with pytest.raises(ValueError, match="execution: expected one of all, first-held"):
        ChunkedEnv(make_env("point-mass"), k, execution="first")


def test_first_held_reaches_training_and_evaluation_envs(tmp_path):
    from ndp.rl.evaluate import load_policy

    _run(tmp_path, "fh", "ppo-multi", execution="first-held", eval_every=0)
    env = load_policy(tmp_path / "fh").make_env()
    assert env.execution == "first-held"
    env.close()


def test_ppo_repeat_holds_one_action_per_decision(tmp_path):
    """ppo-repeat: one action per decision (hold head), k = 5 env steps, one log-prob per
    decision."""
    import torch

    from ndp.rl.evaluate import load_policy

    rows = _run(tmp_path, "rep", "ppo-repeat", eval_every=0)
    assert rows[-1]["global_step"] == 2400
    pol = load_policy(tmp_path / "rep")
    assert pol.cfg.k == 5 and pol.cfg.policy.head == "hold"
    env = pol.make_env()
    obs, info = env.reset(seed=0)
    act = pol.act(obs, info, deterministic=False)
    assert act.shape == (5, 2) and np.all(act == act[:1])
    dist, _ = pol.model.distribution(torch.zeros(1, pol.model.obs_dim))
    assert dist.per_decision
    env.close()
