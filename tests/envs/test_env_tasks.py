"""Every registered task: gymnasium's check_env, seeding, bad input, instability handling."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from ndp.envs import TASKS, ChunkedEnv, make_env, register_envs

# Meta-World's observation space (metaworld's own design) has infinite bounds on the object
# block, and for some tasks a goal coordinate whose low equals its high; gymnasium's checker warns
# about exactly that. These three warnings, and only these, are silenced, and only for the
# Meta-World tasks.
METAWORLD_OBS_WARNINGS = (
    "A Box observation space minimum value is -infinity",
    "A Box observation space maximum value is infinity",
    "A Box observation space maximum and minimum values are equal",
)


def _rollout(env: gym.Env, seed: int, n: int = 8) -> tuple[list[np.ndarray], list[float]]:
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(123)
    observations, rewards = [obs], []
    for _ in range(n):
        obs, r, _, _, _ = env.step(rng.uniform(-1, 1, env.action_space.shape))
        observations.append(obs)
        rewards.append(r)
    return observations, rewards


@pytest.mark.parametrize("name", list(TASKS))
def test_check_env_and_same_seed_same_episode(name):
    env = make_env(name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    messages = [str(w.message) for w in caught]
    if TASKS[name].family == "metaworld":
        messages = [m for m in messages if not any(k in m for k in METAWORLD_OBS_WARNINGS)]
    assert messages == [], messages
    obs_a, rew_a = _rollout(env, seed=7)
    obs_b, rew_b = _rollout(env, seed=7)
    for a, b in zip(obs_a, obs_b, strict=True):
        np.testing.assert_array_equal(a, b)
    assert rew_a == rew_b
    env.close()


def test_registered_with_gymnasium_and_seed_in_factory():
    ids = register_envs()
    from ndp.gym_ids import LEGACY_IDS

    old = sum(s.env_id in LEGACY_IDS for s in TASKS.values())  # deprecated aliases (4)
    assert len(ids) == 2 * len(TASKS) + old and "ndp/JacoThrow-v0" in ids
    assert "ndp/push-v3-k5" in ids and "ndp/throw" in ids
    env = gym.make("ndp/push-v3", seed=3)
    obs1, _ = env.reset()
    obs2, _ = make_env("push-v3").reset(seed=3)
    np.testing.assert_array_equal(obs1, obs2)
    env.close()


def test_metaworld_goals_are_random_per_reset_and_identical_across_instances():
    a, b = make_env("push-v3", seed=11), make_env("push-v3", seed=11)
    goals_a = [a.reset()[0][36:39] for _ in range(4)]
    goals_b = [b.reset()[0][36:39] for _ in range(4)]
    np.testing.assert_array_equal(np.stack(goals_a), np.stack(goals_b))
    assert len({tuple(g) for g in goals_a}) == 4  # a new goal every reset
    objs = [a.reset(seed=s)[0][4:7] for s in (1, 2)]
    assert not np.allclose(objs[0], objs[1])


def test_horizon_truncates_and_500_is_available():
    env = make_env("reach-v3", horizon=4)
    env.reset(seed=0)
    flags = [env.step(np.zeros(4))[3] for _ in range(4)]
    assert flags == [False, False, False, True]
    with pytest.raises(RuntimeError):
        env.step(np.zeros(4))
    assert make_env("reach-v3", horizon=500).mw.max_path_length == 500
    chunked = ChunkedEnv(make_env("reach-v3", horizon=150), k=5)
    chunked.reset(seed=0)
    n = 0
    while True:
        n += 1
        *_, trunc, _ = chunked.step(np.zeros((5, 4)))
        if trunc:
            break
    assert n == 30


@pytest.mark.parametrize("name", ["push-v3", "throw"])
def test_bad_actions(name):
    env = make_env(name, seed=0)
    env.reset()
    dim = TASKS[name].action_dim
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full(dim, np.nan))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full(dim, np.inf))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(dim + 1))
    # Out-of-range actions are clipped to [-1, 1]: same result as the clipped action.
    big = np.full(dim, 50.0)
    big[0] = -50.0
    twin = make_env(name, seed=0)
    twin.reset()
    o1, r1, *_ = env.step(big)
    o2, r2, *_ = twin.step(np.clip(big, -1, 1))
    np.testing.assert_array_equal(o1, o2)
    assert r1 == r2


def test_bad_factory_arguments():
    with pytest.raises(ValueError, match="close names: push-v3"):
        make_env("push-v2")
    with pytest.raises(ValueError, match="horizon"):
        make_env("push-v3", horizon=0)
    with pytest.raises(ValueError, match="render_mode"):
        make_env("throw", render_mode="human")


@pytest.mark.parametrize("name", ["push-v3", "pick"])
def test_simulator_instability_ends_episode_with_flag(name):
    env = ChunkedEnv(make_env(name, seed=0), k=5)
    env.reset()
    env.step(np.zeros((5, TASKS[name].action_dim)))
    base = env.unwrapped
    base.data.qvel[:] = 1e30  # provoke MuJoCo's bad-qacc / bad-qvel warning
    obs, reward, term, trunc, info = env.step(np.zeros((5, TASKS[name].action_dim)))
    assert info["sim_unstable"] and trunc and not term
    assert info["n_substeps"] == 1 and np.all(np.isfinite(obs))
    assert np.all(np.isfinite(info["robot_pos"])) and np.isfinite(reward)
    env.reset()  # a reset recovers
    _, _, _, _, info = env.step(np.zeros((5, TASKS[name].action_dim)))
    assert not info["sim_unstable"]


def test_async_vector_env_from_factory_closures():
    fns = [lambda i=i: ChunkedEnv(make_env("reach-v3", seed=100 + i), k=5) for i in range(2)]
    venv = gym.vector.AsyncVectorEnv(fns)
    obs, info = venv.reset()
    assert obs.shape == (2, 39) and info["dmp_y0"].shape == (2, 4)
    _, rew, _, _, info = venv.step(np.zeros((2, 5, 4)))
    assert rew.shape == (2,) and info["robot_pos"].shape == (2, 6, 4)
    venv.close()


def test_chunked_env_ids_and_unknown_family(monkeypatch):
    import dataclasses

    import ndp.envs.factory as factory
    from ndp.envs import TASKS

    env = gym.make("ndp/push-v3-k5")
    _, info = env.reset(seed=0)
    assert env.action_space.shape == (5, 4) and "cmd_y0" in info
    env.close()
    odd = dataclasses.replace(TASKS["point-mass"], family="rover")  # no env class for it
    monkeypatch.setattr(factory, "get_task_spec", lambda name: odd)
    with pytest.raises(ValueError, match="family: no env class for family 'rover'"):
        factory.make_env("point-mass")


def test_video_output_checked_before_work_and_written_atomically(tmp_path):
    from ndp.envs.render import write_mp4
    from ndp.io import check_output_path

    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OSError, match=r"a part of that path \(.*file\) is a file"):
        check_output_path(blocker / "sub" / "v.mp4")
    with pytest.raises(OSError, match="is a folder"):
        check_output_path(tmp_path)
    frames = [np.zeros((16, 16, 3), np.uint8)] * 3
    out = write_mp4(frames, tmp_path / "v.mp4", fps=5)
    assert out.stat().st_size > 0 and not list(tmp_path.glob(".v.*"))
    # odd sizes: the encoder (H.264 / yuv420p) cannot take them; refused before writing, and
    # nothing is left behind (it used to write a 0-byte mp4 and report success)
    for shape, side in (((16, 15, 3), "width"), ((3, 4, 3), "height"), ((1, 1, 3), "height")):
        with pytest.raises(ValueError, match=f"{side}: expected an even number of px"):
            write_mp4([np.zeros(shape, np.uint8)] * 2, tmp_path / "odd.mp4", fps=5)
    assert not (tmp_path / "odd.mp4").exists() and not list(tmp_path.glob(".odd.*"))
