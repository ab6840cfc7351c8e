"""The release's task conditions as options: v1 rewards, fixed goals (docs/envs.md)."""

from __future__ import annotations

import numpy as np
import pytest

import ndp
from ndp.envs import fixed_goal_seed, make_env
from ndp.envs.metaworld_env import V1_REWARD_BROKEN


def _goal(env, seed: int) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    return np.asarray(obs, dtype=np.float64).copy()


@pytest.mark.parametrize("task", ["push-v3", "throw", "pick", "point-mass"])
def test_fixed_goal_is_the_same_at_every_reset_and_differs_across_seeds(task):
    a = make_env(task, fixed_goal=fixed_goal_seed(0))
    b = make_env(task, fixed_goal=fixed_goal_seed(1))
    free = make_env(task)
    first = _goal(a, 0)
    for s in (1, 2, 3):  # other episode seeds, other episodes: the same configuration
        np.testing.assert_array_equal(_goal(a, s), first)
    assert not np.array_equal(_goal(b, 0), first)  # another run seed, another goal
    assert not np.array_equal(_goal(free, 0), _goal(free, 1))  # the default: fresh goals
    for e in (a, b, free):
        e.close()


def test_fixed_goal_seed_is_deterministic_and_distinct_per_run_seed():
    assert fixed_goal_seed(3) == fixed_goal_seed(3)
    assert len({fixed_goal_seed(s) for s in range(50)}) == 50


def test_v1_reward_is_metaworlds_v1_and_success_stays_v2():
    """The v1 env's reward is metaworld's v1 compute_reward; its success equals the v2 env's
    along the same trajectory (success means the same under both rewards)."""
    from metaworld.env_dict import ALL_V3_ENVIRONMENTS
    from metaworld.policies import ENV_POLICY_MAP

    v1, v2 = make_env("push-v3", reward_version="v1"), make_env("push-v3")
    ref = v1.unwrapped.mw
    assert ref.reward_function_version == "v2"  # metaworld's own step keeps the v2 evaluation
    o1, _ = v1.reset(seed=5)
    o2, _ = v2.reset(seed=5)
    policy = ENV_POLICY_MAP["push-v3"]()
    differ, succeeded = 0, False
    cls = ALL_V3_ENVIRONMENTS["push-v3"]
    assert cls is not None
    for _ in range(120):
        a = np.clip(policy.get_action(o1), -1, 1)
        o1, r1, _, _, i1 = v1.step(a)
        o2, r2, _, _, i2 = v2.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert i1["success"] == i2["success"]
        succeeded |= bool(i1["success"])
        ref.reward_function_version = "v1"
        want = float(ref.compute_reward(a.astype(np.float64), o1)[0])
        ref.reward_function_version = "v2"
        assert r1 == want
        differ += int(r1 != r2)
    assert succeeded and differ > 100


def test_reward_version_and_fixed_goal_refused_with_a_clear_message():
    with pytest.raises(ValueError, match=r"reward_version: expected 'v1' or 'v2', got 'v3'"):
        make_env("push-v3", reward_version="v3")
    with pytest.raises(ValueError, match=r"reward_version: 'v1' exists for Meta-World tasks"):
        make_env("throw", reward_version="v1")
    for name in V1_REWARD_BROKEN:
        with pytest.raises(ValueError, match=rf"reward_version: {name}'s v1 reward"):
            make_env(name, reward_version="v1")
    for bad in (-1, 1.5, True, "3"):
        with pytest.raises(ValueError, match="fixed_goal: expected None or an integer >= 0"):
            make_env("point-mass", fixed_goal=bad)
    assert make_env("point-mass", fixed_goal=np.int64(4)).unwrapped.fixed_goal == 4


def test_v1_reward_refused_where_metaworld_cannot_run_it():
    """assembly-v3's v1 branch reads an attribute metaworld never sets: refusing it is right."""
    env = make_env("assembly-v3")
    env.reset(seed=0)
    mw = env.unwrapped.mw
    mw.reward_function_version = "v1"
    with pytest.raises(AttributeError):
        mw.compute_reward(np.zeros(4), env.unwrapped._obs)
    env.close()


def test_public_make_env_takes_the_options():
    env = ndp.make_env("push-v3", k=5, reward_version="v1", fixed_goal=7)
    base = env.unwrapped
    assert base.reward_version == "v1" and base.fixed_goal == 7
    env.close()


def test_release9_observation_is_hand_object_goal_and_trains(tmp_path):
    """observation='release9': the 9 values the release's policies saw, taken from the full
    observation; the stale rule and rewards are untouched; a run trains on it and its policy
    acts in its own env."""
    from ndp.envs.factory import RELEASE9
    from ndp.rl.config import TrainConfig
    from ndp.rl.evaluate import load_policy
    from ndp.rl.trainer import train

    full = ndp.make_env("push-v3", k=5)
    small = ndp.make_env("push-v3", k=5, observation="release9")
    assert small.observation_space.shape == (9,)
    o_full, _ = full.reset(seed=1)
    o_small, _ = small.reset(seed=1)
    np.testing.assert_array_equal(o_small, o_full[list(RELEASE9)])
    act = np.zeros((5, 4))
    o_full, r_full, *_, i_full = full.step(act)
    o_small, r_small, *_, i_small = small.step(act)
    np.testing.assert_array_equal(o_small, o_full[list(RELEASE9)])
    assert r_small == r_full
    np.testing.assert_array_equal(i_small["sub_rewards"], i_full["sub_rewards"])
    with pytest.raises(ValueError, match="observation: 'release9' exists for Meta-World"):
        make_env("throw", observation="release9")
    run = tmp_path / "r9"
    train(TrainConfig(task="push-v3", algo="ndp", observation="release9", steps=200,
                      num_envs=2, vector="workers", env_workers=2, run_dir=str(run),
                      progress=False, tensorboard=False))  # fmt: skip
    pol = load_policy(run)
    env = pol.make_env()
    obs, info = env.reset(seed=0)
    assert obs.shape == (9,) and pol.act(obs, info).shape == (5, 4)
    env.close()
