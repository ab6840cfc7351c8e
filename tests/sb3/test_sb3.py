"""ndp.sb3: the NDP policy under Stable-Baselines3's PPO on the chunked env."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import ndp

pytest.importorskip("stable_baselines3")
from stable_baselines3 import PPO

import ndp.sb3
from ndp.dmp import dmp_rollout_reference
from ndp.envs import get_task_spec


@pytest.fixture
def one_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def test_with_robot_state_puts_the_dmp_start_in_the_observation():
    env = ndp.sb3.make_env("point-mass", k=5)  # preset: the commanded state
    assert env.observation_space.state_keys == ("cmd_y0", "cmd_dy0")
    assert env.observation_space.task == "point-mass"
    obs, info = env.reset(seed=3)
    assert set(obs) == {"obs", "y0", "dy0"} and env.observation_space.contains(obs)
    np.testing.assert_array_equal(obs["y0"], info["cmd_y0"])
    obs, _, _, _, info = env.step(np.full((5, 2), 0.5))
    np.testing.assert_array_equal(obs["y0"], info["cmd_y0"])
    np.testing.assert_array_equal(obs["dy0"], info["cmd_dy0"])
    assert not np.allclose(obs["y0"], 0.0)
    push = ndp.sb3.make_env("push-v3", k=5)  # Meta-World's preset: the measured hand
    obs, info = push.reset(seed=0)
    assert push.observation_space.state_keys == ("dmp_y0", "dmp_dy0")
    np.testing.assert_array_equal(obs["y0"], info["dmp_y0"])
    push.close()
    with pytest.raises(ValueError, match=r"chunked env .* \[k, A\]"):
        ndp.sb3.with_robot_state(ndp.make_env("point-mass", k=1).env, "point-mass")
    with pytest.raises(ValueError, match="dmp_state"):
        ndp.sb3.make_env("point-mass", dmp_state="odometry")


POINT_MASS = get_task_spec("point-mass")


def _goal_only_actions(policy, obs: dict) -> np.ndarray:
    """The k sub-actions of a DMP without forcing term (weights 0), integrated by the reference
    loop from the observation's y0 and dy0 (physical velocity -> DMP time: times the decision's
    duration), with the goal the policy's network gives."""
    head = policy.ndp_head
    t = {k: torch.as_tensor(v, dtype=torch.float32)[None] for k, v in obs.items()}
    with torch.no_grad():
        latent = policy.mlp_extractor.forward_actor(t["obs"])
        raw_goal = policy.action_net(latent)[:, : head.dmp_dofs]
        goal = t["y0"] + head.goal_scale * torch.tanh(raw_goal)  # delta DoF (point mass)
        weights = torch.zeros(1, head.dmp_dofs, head.n_basis)
        dy0 = t["dy0"] * (5 * POINT_MASS.control_dt)
        pos = dmp_rollout_reference(goal, weights, t["y0"], dy0, head.dmp.config).pos[0]
    scale = np.asarray(POINT_MASS.action_scale)
    return np.clip(np.diff(pos.numpy(), axis=0) / scale, -1.0, 1.0)


def test_sb3_ppo_trains_the_ndp_policy_and_acts_through_the_dmp(one_thread, tmp_path):
    env = ndp.sb3.make_env("point-mass", k=5)
    # the DMP starts with the state's velocity (the toy task's preset starts at rest): delta
    # actions of a DMP at rest do not depend on where it starts, its velocity they do
    kw = {"ndp": {"dmp_velocity": "state"}}
    model = PPO(
        ndp.sb3.NDPPolicy,
        env,
        n_steps=128,
        batch_size=64,
        n_epochs=3,
        seed=0,
        device="cpu",
        policy_kwargs=kw,
    )
    policy = model.policy
    assert policy.ndp_head.k == 5 and policy.action_net.out_features == 2 * (1 + 6)
    before = {k: v.clone() for k, v in policy.state_dict().items()}
    model.learn(512)  # decisions: 2560 env steps, 4 updates
    logged = model.logger.name_to_value
    assert logged["train/n_updates"] == 12
    for key in ("train/loss", "train/policy_gradient_loss", "train/value_loss", "train/approx_kl"):
        assert np.isfinite(logged[key]), key
    changed = [k for k, v in policy.state_dict().items() if not torch.equal(v, before[k])]
    assert "action_net.weight" in changed and "ndp_head.log_std" in changed
    assert policy.log_std is policy.ndp_head.log_std  # SB3's train/std reads the head's
    with pytest.raises(AttributeError, match="log_std: NDPPolicy's log std is the NDP head's"):
        policy.log_std = torch.zeros(2)

    obs, _ = env.reset(seed=5)
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == (5, 2) and np.all(np.abs(actions) <= 1.0)
    # the robot state reaches the DMP: the same observation at another velocity acts otherwise
    moved = dict(obs, y0=obs["y0"] + 0.3, dy0=obs["dy0"] + 0.4)
    assert not np.allclose(model.predict(moved, deterministic=True)[0], actions, atol=1e-4)

    # with the forcing weights' outputs zeroed, the actions are the goal-only DMP's
    d, n = policy.ndp_head.dmp_dofs, policy.ndp_head.n_basis
    with torch.no_grad():
        policy.action_net.weight[d : d + d * n] = 0.0
        policy.action_net.bias[d : d + d * n] = 0.0
    for o in (obs, moved):
        np.testing.assert_allclose(
            model.predict(o, deterministic=True)[0], _goal_only_actions(policy, o), atol=1e-5
        )

    # saved and loaded: the same actions
    model.save(tmp_path / "ndp-sb3.zip")
    loaded = PPO.load(tmp_path / "ndp-sb3.zip", device="cpu")
    np.testing.assert_allclose(
        loaded.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0]
    )


def test_ndp_policy_refuses_what_it_cannot_run():
    with pytest.raises(ValueError, match="with_robot_state"):
        PPO(ndp.sb3.NDPPolicy, ndp.make_env("point-mass", k=5), device="cpu")
    env = ndp.sb3.make_env("point-mass", k=5)
    with pytest.raises(ValueError, match="param_noise"):
        PPO(ndp.sb3.NDPPolicy, env, policy_kwargs={"ndp": {"param_noise": True}}, device="cpu")
    with pytest.raises(ValueError, match="dmp_state"):
        PPO(
            ndp.sb3.NDPPolicy,
            env,
            policy_kwargs={"ndp": {"dmp_state": "measured"}},
            device="cpu",
        )


def test_vecnormalize_statistics_saved_and_loaded_with_the_model(one_thread, tmp_path):
    """docs/sb3.md's recipe: model.save + VecNormalize.save, then VecNormalize.load +
    PPO.load(env=...): the reloaded model acts as the trained one on the same raw observation;
    reloaded without the statistics it acts otherwise (why the docs save them)."""
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    k = 5
    venv = DummyVecEnv([lambda: ndp.sb3.make_env("point-mass", k=k) for _ in range(2)])
    venv = VecNormalize(venv, gamma=0.99**k, norm_obs_keys=["obs"])
    model = PPO(ndp.sb3.NDPPolicy, venv, gamma=0.99**k, n_steps=64, batch_size=64, n_epochs=1,
                seed=0, device="cpu")  # fmt: skip
    model.learn(256)
    model.save(tmp_path / "m.zip")
    venv.save(str(tmp_path / "vn.pkl"))
    raw = ndp.sb3.make_env("point-mass", k=k).reset(seed=4)[0]
    raw_batch = {key: v[None] for key, v in raw.items()}
    want = model.predict(venv.normalize_obs(raw_batch), deterministic=True)[0]

    fresh = DummyVecEnv([lambda: ndp.sb3.make_env("point-mass", k=k)])
    loaded_vn = VecNormalize.load(str(tmp_path / "vn.pkl"), fresh)
    loaded_vn.training, loaded_vn.norm_reward = False, False
    loaded = PPO.load(tmp_path / "m.zip", env=loaded_vn, device="cpu")
    got = loaded.predict(loaded_vn.normalize_obs(raw_batch), deterministic=True)[0]
    np.testing.assert_allclose(got, want, atol=1e-6)
    # without the statistics: raw observations, other actions
    bare = PPO.load(tmp_path / "m.zip", device="cpu")
    assert not np.allclose(bare.predict(raw_batch, deterministic=True)[0], want, atol=1e-3)


def test_ndp_policy_predict_checks_its_inputs_as_every_runtime_does():
    """A NaN observation is refused naming ``obs`` and the index (not the DMP's internal
    ``goal``); a NaN robot state names its key; a good observation still predicts."""
    env = ndp.sb3.make_env("point-mass", k=5)
    model = PPO(ndp.sb3.NDPPolicy, env, n_steps=8, batch_size=8, device="cpu")
    obs, _ = env.reset(seed=0)
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == env.action_space.shape
    bad = {**obs, "obs": obs["obs"].copy()}
    bad["obs"][1] = np.nan
    with pytest.raises(ValueError, match=r"^obs: expected finite values, got nan at \[0, 1\]$"):
        model.predict(bad)
    bad = {**obs, "y0": np.full_like(obs["y0"], np.inf)}
    with pytest.raises(ValueError, match=r"^observation: 'y0' expected finite values"):
        model.predict(bad)
    with pytest.raises(ValueError, match=r"^observation: expected the dict"):
        model.predict(obs["obs"])
    env.close()


def test_an_ndppolicy_model_becomes_a_package_policy_that_exports(one_thread, tmp_path):
    """ndp.sb3.to_policy: the SB3 model's deterministic actions (VecNormalize on obs) equal the
    converted policy's on raw observations; it exports to safetensors (with its card) and
    ONNX, and both load back and act the same; bad inputs are one line."""
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from ndp.act_inputs import RobotState

    venv = DummyVecEnv([lambda: ndp.sb3.make_env("point-mass", k=5) for _ in range(2)])
    venv = VecNormalize(venv, gamma=0.99**5, norm_obs_keys=["obs"])
    model = PPO(ndp.sb3.NDPPolicy, venv, n_steps=32, batch_size=32, n_epochs=2, seed=0,
                device="cpu")  # fmt: skip
    model.learn(total_timesteps=128)
    venv.training = False
    pol = ndp.sb3.to_policy(model, venv)
    assert pol.cfg.algo == "ndp" and pol.cfg.k == 5 and pol.obs_norm.enabled
    env = ndp.sb3.make_env("point-mass", k=5)
    exported = pol.export(tmp_path / "exp")
    onnx_dir = pol.export(tmp_path / "onnx", format="onnx")
    again, graph = ndp.load_policy(exported), ndp.load_policy(onnx_dir)
    assert "Stable-Baselines3" in (exported / "README.md").read_text()
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        sb3_action, _ = model.predict(venv.normalize_obs(obs), deterministic=True)
        state = RobotState(obs["y0"], obs["dy0"])
        ours = pol.act(obs["obs"], state)
        np.testing.assert_allclose(ours, sb3_action, atol=1e-5)
        np.testing.assert_allclose(again.act(obs["obs"], state), ours, atol=1e-6)
        np.testing.assert_allclose(graph.act(obs["obs"], state), ours, atol=1e-5)
    env.close()
    with pytest.raises(ValueError, match=r"^model: expected an SB3 model with ndp.sb3.NDPPolicy"):
        ndp.sb3.to_policy(PPO("MlpPolicy", "Pendulum-v1", device="cpu"))
    bad = VecNormalize(
        DummyVecEnv([lambda: ndp.sb3.make_env("point-mass", k=5)]), norm_obs_keys=["obs", "y0"]
    )
    with pytest.raises(ValueError, match=r"^vec_normalize: expected norm_obs_keys=\['obs'\]"):
        ndp.sb3.to_policy(model, bad)
    venv.close()
