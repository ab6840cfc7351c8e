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
    with pytest.raises(ValueError, match=r"reward_version: expected one of v1, v2, got 'v3'"):
        make_env("push-v3", reward_version="v3")
    with pytest.raises(ValueError, match=r"reward_version: 'v1' exists for Meta-World tasks"):
        make_env("throw", reward_version="v1")
    for name in V1_REWARD_BROKEN:
        with pytest.raises(ValueError, match=rf"reward_version: {name}'s v1 reward"):
            make_env(name, reward_version="v1")
    for bad in (-1, 1.5, True, "3"):
        with pytest.raises(ValueError, match="fixed_goal: expected None, an integer >= 0 or "):
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


# one small update sees few observations: a reset outside their range is clipped and said once
@pytest.mark.filterwarnings("ignore:obs.*outside the trained range:RuntimeWarning")
def test_release9_observation_is_hand_object_goal_and_trains(tmp_path):
    """observation='release9': the 9 values the release's policies saw, taken from the full
    observation; the stale rule and rewards are untouched; a run trains on it and its policy
    acts in its own env."""
    from ndp.envs.factory import RELEASE9
    from ndp.rl.config import PPOConfig, TrainConfig
    from ndp.rl.evaluate import load_policy
    from ndp.rl.run import train

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
    # the observation's plumbing, not the vector env's (tests/envs/test_env_vector.py): in-process
    # envs, no periodic evaluation, one small update
    train(TrainConfig(task="push-v3", algo="ndp", observation="release9", steps=200,
                      num_envs=2, vector="sync", run_dir=str(run), eval_every=0,
                      steps_per_update=260, ppo=PPOConfig(minibatches=2),
                      progress=False, tensorboard=False))  # fmt: skip
    pol = load_policy(run)
    env = pol.make_env()
    obs, info = env.reset(seed=0)
    assert obs.shape == (9,) and pol.act(obs, info).shape == (5, 4)
    env.close()


# ------------------------------------------------------------------ the release's one goal


def _positions(task: str, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(object or faucet xyz, goal xyz) of a Meta-World observation."""
    return np.asarray(obs[4:7]), np.asarray(obs[36:39])


@pytest.mark.parametrize(
    ("task", "obj_xy", "goal_xy"),
    [
        ("push-v3", (0.0, 0.6), (0.1, 0.8)),
        ("soccer-v3", (0.0, 0.6), (0.0, 0.9)),
        ("faucet-open-v3", None, (0.175, 0.8)),  # v3's goal: faucet (0, 0.8) + its handle
    ],
)
def test_release_goal_is_the_releases_hard_coded_configuration(task, obj_xy, goal_xy):
    """fixed_goal='release' puts object and goal where the release hard-coded them, at every
    reset and for every episode seed (ndp-method.md section 7)."""
    env = make_env(task, fixed_goal="release")
    first = None
    for seed in (0, 1, 7):
        obs, _ = env.reset(seed=seed)
        obj, goal = _positions(task, obs)
        np.testing.assert_allclose(goal[:2], goal_xy, atol=1e-6)
        if obj_xy is not None:
            np.testing.assert_allclose(obj[:2], obj_xy, atol=1e-3)
        first = obs if first is None else first
        np.testing.assert_array_equal(obs, first)
    env.close()
    # the default still draws fresh configurations (the env's own draw is not frozen for good)
    free = make_env(task)
    a, _ = free.reset(seed=0)
    b, _ = free.reset(seed=1)
    assert not np.array_equal(a[36:39], b[36:39])
    free.close()


@pytest.mark.parametrize("task", ["throw", "pick"])
def test_release_goal_on_jaco_is_the_nominal_place(task):
    """Throw's basket / Pick's cube at the nominal place (jitter 0) for every episode seed."""
    env = make_env(task, fixed_goal="release")
    goals = [env.reset(seed=s)[0][-3:] for s in (0, 1, 2)]
    for g in goals[1:]:
        np.testing.assert_array_equal(g, goals[0])
    free = make_env(task)
    jittered = [free.reset(seed=s)[0][-3:] for s in (0, 1)]
    assert not np.array_equal(jittered[0], jittered[1])
    if task == "pick":
        np.testing.assert_allclose(goals[0][:2], (0.0, 0.5), atol=1e-6)
    env.close()
    free.close()


def test_release_goal_refused_where_the_release_had_none():
    for task in ("reach-v3", "point-mass"):
        with pytest.raises(ValueError, match=r"fixed_goal: 'release' .* exists for push-v3"):
            make_env(task, fixed_goal="release")


def test_release_goal_rule_per_task_and_method():
    """The release's rule, pinned: PPO (and its variants) random on push and soccer only; NDP and
    PPO-multi fixed everywhere; faucet-open, Throw, Pick fixed for every method."""
    from ndp.envs.release import RELEASE_GOAL_TASKS, release_goals

    want = {
        ("push-v3", "ndp"): "release",
        ("push-v3", "ppo-multi"): "release",
        ("push-v3", "ppo"): "random",
        ("push-v3", "ppo-repeat"): "random",
        ("soccer-v3", "ndp"): "release",
        ("soccer-v3", "ppo-multi"): "release",
        ("soccer-v3", "ppo"): "random",
        ("faucet-open-v3", "ndp"): "release",
        ("faucet-open-v3", "ppo-multi"): "release",
        ("faucet-open-v3", "ppo"): "release",
        ("throw", "ndp"): "release",
        ("throw", "ppo"): "release",
        ("pick", "ppo"): "release",
        ("pick", "ndp"): "release",
    }
    for (task, method), goals in want.items():
        assert release_goals(task, method) == goals, (task, method)
    assert set(RELEASE_GOAL_TASKS) == {"push-v3", "soccer-v3", "faucet-open-v3", "throw", "pick"}
    with pytest.raises(ValueError, match="task: the release's goal rule covers"):
        release_goals("reach-v3", "ndp")


def test_as_release_goals_resolve_per_method():
    """--goals as-release is resolved before the run: the config that runs (and is saved) says
    'release' or 'random'."""
    from ndp.rl.config import TrainConfig, resolve_config

    for algo, want in (("ndp", "release"), ("ppo", "random"), ("ppo-multi", "release")):
        cfg = resolve_config(TrainConfig(task="push-v3", algo=algo, goals="as-release"))
        assert cfg.goals == want
        assert cfg.env_options().get("fixed_goal") == ("release" if want == "release" else None)
    assert (
        resolve_config(TrainConfig(task="faucet-open-v3", algo="ppo", goals="as-release")).goals
        == "release"
    )
    with pytest.raises(ValueError, match="goals: 'as-release' needs a task the release ran"):
        resolve_config(TrainConfig(task="reach-v3", goals="as-release"))
    with pytest.raises(ValueError, match="fixed_goal: 'release'"):
        resolve_config(TrainConfig(task="reach-v3", goals="release"))
    # the old name of the per-seed goal is still read
    assert TrainConfig(goals="fixed").goals == "per-seed"
