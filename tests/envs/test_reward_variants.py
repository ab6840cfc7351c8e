"""Reward variants (``--reward dense / sparse / smooth``, ndp.envs.rewards): the sparse reward on
a scripted Meta-World success, the smooth penalty against a hand computation, the option from
config.json to every env of a run (training, periodic evaluation, resume, ``load_policy``) and
the refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import ndp
from ndp.envs import ChunkedEnv, make_env
from ndp.envs.rewards import (
    DEFAULT_SMOOTH_LAMBDA,
    REWARDS,
    RewardVariant,
    reward_of,
    smooth_penalties,
    sparse_rewards,
)
from ndp.rl.config import TrainConfig, resolve_config

# ------------------------------------------------------------------------------ sparse


def _reach_action(obs: np.ndarray) -> np.ndarray:
    """A proportional controller moving reach-v3's hand (obs 0:3) to its goal (obs 36:39)."""
    a = np.zeros(4)
    a[:3] = np.clip(10.0 * (obs[36:39] - obs[0:3]), -1.0, 1.0)
    return a


def test_sparse_reward_on_a_scripted_reach_success():
    """reach-v3 driven to its goal: reward 0 before the first success, exactly 1 at it,
    terminated there, return 1; a dense twin fed the same actions confirms the step and the
    env's own reward rides along in info."""
    sparse = make_env("reach-v3", reward="sparse")
    dense = make_env("reach-v3")
    obs, _ = sparse.reset(seed=4)
    obs_d, _ = dense.reset(seed=4)
    np.testing.assert_array_equal(obs, obs_d)
    rewards, first = [], None
    for t in range(150):
        a = _reach_action(obs)
        obs, r, term, trunc, info = sparse.step(a)
        _, r_d, term_d, _, info_d = dense.step(a)
        rewards.append(r)
        assert info["success"] == info_d["success"]  # success is the task's own
        assert info["env_reward"] == r_d and not term_d  # Meta-World never terminates itself
        if info_d["success"]:
            first = t
            break
        assert r == 0.0 and not term and not trunc
    assert first is not None and first > 5  # the hand had to travel: a real episode
    assert rewards[-1] == 1.0 and term
    assert sum(rewards) == 1.0
    with pytest.raises(RuntimeError, match="episode is over"):
        sparse.step(np.zeros(4))
    sparse.reset(seed=5)  # a new episode runs again
    assert sparse.step(np.zeros(4))[1] == 0.0
    np.testing.assert_array_equal(sparse_rewards(np.arange(6) >= 3)[0], [0, 0, 0, 1, 0, 0])
    assert sparse_rewards(np.zeros(4, dtype=bool)) == (pytest.approx(np.zeros(4)), None)


def test_sparse_reward_through_the_chunked_env():
    """k = 5 without the stale rule: the decision stops at the success sub-step, whose reward
    (trained and live) is 1; success_any is the task's."""
    env = ndp.make_env("reach-v3", k=5, stale_world=False, reward="sparse")
    obs, info = env.reset(seed=4)
    total, live, steps = 0.0, 0.0, 0
    for _ in range(30):
        actions = np.stack([_reach_action(obs)] * 5)  # open loop within the decision
        obs, r, term, trunc, info = env.step(actions)
        n = int(info["n_substeps"])
        total += r
        live += float(info["sub_rewards_live"][:n].sum())
        steps += n
        if term or trunc:
            break
    assert term and not trunc and info["success_any"]
    n = int(info["n_substeps"])
    assert info["sub_success"][n - 1] == 1.0 and info["sub_rewards"][n - 1] == 1.0
    assert total == live == 1.0 and steps > 5


# ------------------------------------------------------------------------------ smooth


def test_smooth_penalty_equals_a_hand_computation():
    """Point mass (2-D actions in [-1, 1]): a known sequence, the last action out of bounds
    (clipped before the penalty), a reset in between (no penalty at an episode's first step)."""
    lam = 0.3
    smooth = make_env("point-mass", reward="smooth", smooth_lambda=lam)
    dense = make_env("point-mass")
    acts = [[0.5, 0.0], [-0.5, 0.25], [-0.5, 0.25], [2.0, 0.0]]
    # hand: 0; (-1)^2 + 0.25^2 = 1.0625; 0; clip(2) = 1: 1.5^2 + 0.25^2 = 2.3125
    want = [0.0, lam * 1.0625, 0.0, lam * 2.3125]
    for episode in range(2):
        smooth.reset(seed=episode)
        dense.reset(seed=episode)
        for a, p in zip(acts, want, strict=True):
            _, r, _, _, info = smooth.step(np.array(a))
            _, r_d, _, _, _ = dense.step(np.array(a))
            assert info["smooth_penalty"] == pytest.approx(p, abs=1e-12)
            assert r == pytest.approx(r_d - p, abs=1e-12)
    np.testing.assert_allclose(smooth_penalties(np.clip(acts, -1, 1), lam), want, atol=1e-12)
    assert smooth_penalties(np.zeros((0, 2)), lam).shape == (0,)


def test_smooth_penalty_reaches_every_sub_step_of_a_chunked_decision():
    """ChunkedEnv k = 3 (no stale rule): each sub-step's reward is the dense twin's minus the
    price of the change from the previous executed sub-action, across decisions; PPO's k = 1
    keeps the stale rule's default (it has no effect there)."""
    lam = 0.5
    env = ChunkedEnv(make_env("point-mass", reward="smooth", smooth_lambda=lam), 3, False)
    twin = ChunkedEnv(make_env("point-mass"), 3, False)
    env.reset(seed=1)
    twin.reset(seed=1)
    first = [[0.2, 0.2], [0.2, -0.2], [0.0, 0.0]]
    second = [[1.0, 1.0], [1.0, 1.0], [0.0, 1.0]]
    decisions = np.array([first, second])
    flat = decisions.reshape(-1, 2)
    want = smooth_penalties(flat, lam).reshape(2, 3)
    assert want[1, 0] == pytest.approx(lam * 2.0)  # the change across the decision boundary
    for d in range(2):
        _, r, _, _, info = env.step(decisions[d])
        _, r_d, _, _, info_d = twin.step(decisions[d])
        np.testing.assert_allclose(info["sub_rewards_live"], info_d["sub_rewards_live"] - want[d])
        np.testing.assert_allclose(info["sub_rewards"], info["sub_rewards_live"])
        assert r == pytest.approx(r_d - want[d].sum())
    assert reward_of(ChunkedEnv(make_env("point-mass", reward="smooth"), 1)) == "smooth"


def test_torque_rows_and_observation_filters_take_the_variants():
    """The VICES rows (their own action box) and the release's 9-D observation wrap the same
    way; the stale rule still reads env.unwrapped."""
    env = make_env("push-v3-osc", reward="smooth")
    assert reward_of(env) == "smooth" and env.get_wrapper_attr("smooth_lambda") == 0.25
    env.reset(seed=0)
    a = env.action_space.sample()
    assert np.isfinite(env.step(a)[1])
    nine = make_env("push-v3", reward="sparse", observation="release9")
    assert reward_of(nine) == "sparse" and nine.observation_space.shape == (9,)


# ------------------------------------------------------------------------------ runs


def _tiny(tmp_path, name: str, **kw) -> TrainConfig:
    cfg = TrainConfig(
        task="point-mass", steps=800, num_envs=2, vector="sync", seed=0, eval_every=800,
        eval_episodes=4, run_dir=str(tmp_path / name), progress=False, tensorboard=False, **kw,
    )  # fmt: skip
    d = cfg.to_dict()
    fast = {"minibatches": 4, "epochs": 2}
    return TrainConfig.from_dict({**d, "steps_per_update": 400, "ppo": {**d["ppo"], **fast}})


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == pytest.approx(b, abs=1e-9)


def test_reward_option_round_trips_and_reaches_every_env_of_a_run(tmp_path):
    """A tiny NDP run with the sparse reward (k = 5, --no-stale-world): config.json records it,
    every training env has it, and under it an episode's return is its success-any, so the
    training charts, the periodic deterministic evaluation, a resumed run's rows and
    ``ndp rl eval`` (``load_policy(...).make_env()``) all show return == success rate; a dense
    run's evaluation return is not."""
    from ndp.rl.evaluate import evaluate, load_policy
    from ndp.rl.run import open_run, resume
    from ndp.runs import read_metrics

    run = tmp_path / "sparse"
    cfg = _tiny(tmp_path, "sparse", algo="ndp", reward="sparse", stale_world=False)
    with open_run(cfg) as opened:
        for env in opened.learner.envs.envs:
            assert reward_of(env) == "sparse"
        opened.train()
    saved = json.loads((run / "config.json").read_text())
    recorded = (saved["reward"], saved["smooth_lambda"], saved["stale_world"])
    assert recorded == ("sparse", None, False)
    assert TrainConfig.from_dict(saved).env_options()["reward"] == "sparse"
    resume(run, steps=1600)  # the resumed run reads its reward from config.json
    rows = read_metrics(run)
    assert [r["global_step"] for r in rows] == [400.0, 800.0, 1200.0, 1600.0]
    for r in rows:
        assert _same(r["charts/episode_return"], r["charts/success_any"])
        assert _same(r["charts/episode_return_live"], r["charts/success_any"])
    evaluated = [r for r in rows if not math.isnan(r["eval/return"])]
    assert len(evaluated) == 2
    for r in evaluated:
        assert r["eval/return"] == pytest.approx(r["eval/success_any"], abs=1e-9)
    env = load_policy(run).make_env()
    assert reward_of(env) == "sparse" and not env.stale_world
    env.close()
    got = evaluate(run, episodes=3, deterministic=False)
    assert got["episode_return"] == pytest.approx(got["success_any"], abs=1e-9)
    dense = tmp_path / "dense"
    with open_run(_tiny(tmp_path, "dense", algo="ndp", stale_world=False)) as opened:
        opened.train()
    assert evaluate(dense, episodes=2)["episode_return"] < -1.0  # minus the distance per step


def test_smooth_lambda_default_is_recorded_and_the_other_learners_get_the_reward(tmp_path):
    """--reward smooth without a price records 0.25 in config.json (a later default cannot
    change an old run); PPO at k = 1 needs no --no-stale-world; SAC, chunked SAC, NDP-SAC,
    Dyn-E, PPO-multi and PPO-repeat build their training envs and their policy's evaluation
    env with the run's reward."""
    from ndp.rl.dyne.config import DyneConfig
    from ndp.rl.policy import Policy, load_policy
    from ndp.rl.run import open_run
    from ndp.rl.sac.config import SACConfig

    cfg = _tiny(tmp_path, "ppo", algo="ppo", reward="smooth")
    with open_run(cfg) as opened:
        opened.train()
    saved = json.loads((tmp_path / "ppo" / "config.json").read_text())
    assert saved["reward"] == "smooth" and saved["smooth_lambda"] == DEFAULT_SMOOTH_LAMBDA
    env = load_policy(tmp_path / "ppo").make_env()
    assert env.env.smooth_lambda == DEFAULT_SMOOTH_LAMBDA and reward_of(env) == "smooth"
    for algo in ("ppo-multi", "ppo-repeat", "sac", "sac-chunk", "ndp-sac", "dyne"):
        cfg = TrainConfig(
            task="point-mass", algo=algo, steps=20_000, num_envs=1, vector="sync",
            run_dir=str(tmp_path / algo), progress=False, tensorboard=False, reward="smooth",
            smooth_lambda=0.7, stale_world=False, sac=SACConfig(buffer_size=5000),
            dyne=DyneConfig(replay_size=1000),
        )  # fmt: skip
        with open_run(cfg) as opened:
            learner = opened.learner
            (train_env,) = learner.envs.envs
            assert reward_of(train_env) == "smooth", algo
            ev = learner.evaluator  # its env is the policy's, as ndp rl eval's
            eval_env = Policy(ev.cfg, ev.spec, learner.model, None).make_env()
            assert reward_of(eval_env) == "smooth" and eval_env.env.smooth_lambda == 0.7, algo
            eval_env.close()


# ------------------------------------------------------------------------------ refusals


@pytest.mark.parametrize("algo", ["ndp", "ppo-multi", "sac-chunk", "dyne"])
@pytest.mark.parametrize("reward", ["sparse", "smooth"])
def test_stale_world_with_a_non_dense_reward_is_refused(algo, reward):
    msg = (
        rf"reward: '{reward}' is ill-defined with the stale-world rule at k=5 .* "
        rf"\(--reward {reward} --no-stale-world\) or use k = 1$"
    )
    with pytest.raises(ValueError, match=msg):
        resolve_config(TrainConfig(task="reach-v3", algo=algo, reward=reward))
    resolve_config(TrainConfig(task="reach-v3", algo=algo, reward=reward, stale_world=False))
    resolve_config(TrainConfig(task="reach-v3", algo="ppo", reward=reward))  # k = 1: no rule


def test_the_chunked_env_refuses_the_stale_rule_with_a_non_dense_reward():
    with pytest.raises(ValueError, match=r"reward: 'sparse' is ill-defined .* k=5"):
        ndp.make_env("point-mass", k=5, reward="sparse")
    with pytest.raises(ValueError, match=r"--reward smooth --no-stale-world"):
        ChunkedEnv(make_env("point-mass", reward="smooth"), 2)
    ChunkedEnv(make_env("point-mass", reward="smooth"), 1)  # k = 1: the rule never applies
    ChunkedEnv(make_env("point-mass"), 5)  # dense: the default, unchanged


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"reward": "shaped"}, r"reward: expected one of dense, sparse, smooth, got 'shaped'"),
        ({"reward": "smooth", "smooth_lambda": -0.1}, r"smooth_lambda: expected .* >= 0, got -0.1"),
        ({"reward": "smooth", "smooth_lambda": math.inf}, r"smooth_lambda: expected a finite"),
        ({"reward": "smooth", "smooth_lambda": math.nan}, r"smooth_lambda: expected a finite"),
        ({"smooth_lambda": 0.5}, r"smooth_lambda: only .*smooth.* reward='dense'"),
        ({"reward": "sparse", "smooth_lambda": 0.5}, r"smooth_lambda: only .*reward='sparse'"),
    ],
)
def test_bad_reward_options_are_refused_by_the_config_and_the_env(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TrainConfig(task="point-mass", **kwargs)
    with pytest.raises(ValueError, match=match):
        make_env("point-mass", **kwargs)


def test_the_config_knows_the_envs_rewards_and_old_configs_run_dense():
    from ndp.rl import config

    assert config.REWARDS == REWARDS
    new_keys = ("reward", "smooth_lambda")
    old = {k: v for k, v in TrainConfig().to_dict().items() if k not in new_keys}
    back = TrainConfig.from_dict(old)
    assert (back.reward, back.smooth_lambda) == ("dense", None)
    assert "reward" not in back.env_options()
    assert not isinstance(make_env("point-mass"), RewardVariant)  # dense: no wrapper at all
