"""The SB3 reference of TD3 is built with our TD3's settings (one row of the table)."""

from __future__ import annotations

import numpy as np


def test_sb3_td3_has_our_td3_settings():
    from stable_baselines3.common.vec_env import DummyVecEnv

    from ndp.rl.envs import resolve_task
    from ndp.rl.td3.config import TD3Config
    from ndp.sb3.runs import OFF_POLICY_REFERENCES, PER_STEP_METHODS, SB3_METHODS

    assert "sb3-td3" in SB3_METHODS and "sb3-td3" in PER_STEP_METHODS
    h = resolve_task("point-mass")
    venv = DummyVecEnv([lambda: h.make(horizon=20) for _ in range(2)])
    model = OFF_POLICY_REFERENCES["sb3-td3"](venv, 0, 2)
    c = TD3Config()
    assert model.learning_rate == c.lr and model.batch_size == c.batch_size
    assert model.buffer_size == c.buffer_size and model.learning_starts == c.random_steps
    assert model.tau == c.tau and model.policy_delay == c.policy_delay
    assert model.target_policy_noise == c.target_noise
    assert model.target_noise_clip == c.target_noise_clip
    assert model.gradient_steps == 2  # one per env step of the 2 envs
    assert np.allclose(model.action_noise._sigma, c.expl_noise)
    sizes = [m.out_features for m in model.actor.mu if hasattr(m, "out_features")]
    assert sizes[:2] == [400, 300]
    venv.close()
