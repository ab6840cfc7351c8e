"""ChunkedEnv bookkeeping with a counting fake env (no simulator)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from ndp.envs import ChunkedEnv


class CountingEnv(gym.Env):
    """Fake env: the robot is the step counter t, the world a counter w that grows by 10 a step.

    reward(t) = t + w (live); stale_reward(snapshot) = t + snapshot. Success when t is in
    ``success_at``; terminates at ``terminate_at``; truncates at ``horizon``.
    """

    def __init__(self, terminate_at: int = 10**9, horizon: int = 10**9, success_at=()) -> None:
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(2,), dtype=np.float64)
        self.terminate_at, self.horizon, self.success_at = terminate_at, horizon, set(success_at)
        self.t = 0
        self.w = 0
        self.actions: list[np.ndarray] = []
        self.snapshots_taken = 0

    def robot_state(self):
        return np.array([float(self.t), -float(self.t)]), np.array([1.0, -1.0])

    def world_snapshot(self):
        self.snapshots_taken += 1
        return self.w

    def stale_reward(self, snapshot, action):
        return float(self.t + snapshot)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t, self.w = 0, 0
        return np.zeros(2), {}

    def step(self, action):
        self.actions.append(np.array(action))
        self.t += 1
        self.w += 10
        obs = np.array([self.t, self.w], dtype=np.float64)
        info: dict[str, Any] = {"success": self.t in self.success_at}
        term, trunc = self.t >= self.terminate_at, self.t >= self.horizon
        return obs, float(self.t + self.w), term, trunc, info


def test_stale_and_live_rewards_are_booked_per_substep():
    env = ChunkedEnv(CountingEnv(), k=3, stale_world=True)
    _, info = env.reset()
    assert info["robot_pos"].shape == (2,) and info["success_any"] is False
    _, reward, term, trunc, info = env.step(np.zeros((3, 2)))
    # sub-step 0: live 1 + 10; snapshot w = 10; then t = 2, 3 with the stale world 10.
    np.testing.assert_allclose(info["sub_rewards"], [11.0, 12.0, 13.0])
    np.testing.assert_allclose(info["sub_rewards_live"], [11.0, 22.0, 33.0])
    np.testing.assert_allclose(info["sub_mask"], [1.0, 1.0, 1.0])
    assert reward == pytest.approx(36.0) and not term and not trunc
    assert info["robot_pos"].shape == (4, 2)
    np.testing.assert_allclose(info["robot_pos"][:, 0], [0, 1, 2, 3])
    np.testing.assert_allclose(info["dmp_y0"], [3.0, -3.0])
    np.testing.assert_allclose(info["dmp_dy0"], [1.0, -1.0])
    # The next decision snapshots the world again (w = 40 after its first sub-step).
    _, reward, _, _, info = env.step(np.zeros((3, 2)))
    np.testing.assert_allclose(info["sub_rewards"], [44.0, 45.0, 46.0])


def test_stale_rule_off_and_k1_are_plain_execution():
    env = ChunkedEnv(CountingEnv(), k=3, stale_world=False)
    env.reset()
    _, reward, _, _, info = env.step(np.zeros((3, 2)))
    np.testing.assert_allclose(info["sub_rewards"], [11.0, 22.0, 33.0])
    assert reward == pytest.approx(66.0)
    plain, one = CountingEnv(), ChunkedEnv(CountingEnv(), k=1, stale_world=True)
    plain.reset()
    one.reset()
    for _ in range(4):
        _, r_plain, *_ = plain.step(np.zeros(2))
        _, r_one, _, _, info = one.step(np.zeros((1, 2)))
        assert r_one == r_plain and info["sub_rewards"].shape == (1,)


def test_actions_run_in_order_and_are_clipped():
    fake = CountingEnv()
    env = ChunkedEnv(fake, k=4)
    env.reset()
    acts = np.array([[0.1, 0.2], [0.3, 0.4], [5.0, -7.0], [-0.5, 0.5]])
    env.step(acts)
    got = np.stack(fake.actions)
    np.testing.assert_allclose(got, np.clip(acts, -1, 1), rtol=1e-6)
    assert env.action_space.shape == (4, 2)


def test_early_termination_pads_and_masks():
    env = ChunkedEnv(CountingEnv(terminate_at=2), k=4)
    env.reset()
    _, reward, term, trunc, info = env.step(np.zeros((4, 2)))
    assert term and not trunc and info["n_substeps"] == 2
    np.testing.assert_allclose(info["sub_mask"], [1, 1, 0, 0])
    np.testing.assert_allclose(info["sub_rewards"], [11, 12, 0, 0])
    assert reward == pytest.approx(23.0)
    np.testing.assert_allclose(info["robot_pos"][:, 0], [0, 1, 2, 2, 2])
    np.testing.assert_allclose(info["dmp_y0"], [2.0, -2.0])


def test_truncation_stops_early_and_counts_substeps():
    env = ChunkedEnv(CountingEnv(horizon=7), k=3)
    env.reset()
    env.step(np.zeros((3, 2)))
    env.step(np.zeros((3, 2)))
    _, _, term, trunc, info = env.step(np.zeros((3, 2)))
    assert trunc and not term and info["n_substeps"] == 1
    np.testing.assert_allclose(info["sub_mask"], [1, 0, 0])


def test_success_any_within_decision_episode_and_reset():
    env = ChunkedEnv(CountingEnv(success_at={2}), k=3)
    env.reset()
    _, _, _, _, info = env.step(np.zeros((3, 2)))
    assert info["success_decision"] and info["success_any"] and not info["success"]
    np.testing.assert_allclose(info["sub_success"], [0, 1, 0])
    _, _, _, _, info = env.step(np.zeros((3, 2)))
    assert info["success_any"] and not info["success_decision"]
    _, info = env.reset()
    assert info["success_any"] is False
    _, _, _, _, info = env.step(np.zeros((3, 2)))
    assert info["success_any"]  # t = 2 again after the reset


def test_bad_input_is_rejected():
    env = ChunkedEnv(CountingEnv(), k=2)
    env.reset()
    with pytest.raises(ValueError, match="actions"):
        env.step(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([[0.0, np.nan], [0.0, 0.0]]))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([[0.0, np.inf], [0.0, 0.0]]))
    for k in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="k"):
            ChunkedEnv(CountingEnv(), k=k)


def test_vector_env_stacks_the_info_arrays():
    venv = gym.vector.SyncVectorEnv([lambda: ChunkedEnv(CountingEnv(), k=3) for _ in range(2)])
    venv.reset(seed=0)
    _, rew, _, _, info = venv.step(np.zeros((2, 3, 2)))
    assert rew.shape == (2,)
    assert info["sub_rewards"].shape == (2, 3)
    assert info["robot_pos"].shape == (2, 4, 2)
    venv.close()
