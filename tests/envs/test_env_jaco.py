"""Jaco Throw and Pick: scripted motions succeed, rewards and success are reported, rendering."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ndp.envs import ChunkedEnv, make_env, write_mp4
from ndp.envs import jaco as J


def scripted_throw(env: J.JacoEnv, seed: int, speed: float = 3.2, release: int = 17):
    """Swing the grip site along a 40-degree line at ``speed`` m/s, open the hand at ``release``.

    Joint-target deltas come from the arm Jacobian's pseudo-inverse (resolved-rate control).
    Returns (success at any step, rewards).
    """
    m, d = env.model, env.data
    env.reset(seed=seed)
    jacp = np.zeros((3, m.nv))
    grip = m.site("jaco/hand/gripsite").id
    arm_v = [m.joint(j).dofadr[0] for j in J.ARM_JOINTS]
    success, rewards = False, []
    for t in range(60):
        if t < release:
            mujoco.mj_jacSite(m, d, jacp, None, grip)
            v = speed * np.array([0.0, np.cos(0.7), np.sin(0.7)]) * min(1.0, (t + 1) / 5)
            dq = np.linalg.pinv(jacp[:, arm_v]) @ v * J.CONTROL_DT
            a = np.r_[dq / J.ARM_DELTA, 1.0]
        else:
            a = np.r_[np.zeros(6), -1.0]
        _, r, _, _, info = env.step(np.clip(a, -1, 1))
        rewards.append(r)
        success |= info["success"]
    return success, rewards


def pick_plan(env: J.JacoEnv, cube: np.ndarray) -> list[tuple[np.ndarray, float, int]]:
    """Waypoints (arm joint targets, finger command, steps): above, down, close, lift."""
    above = J.jaco_ik(env.model, cube + np.array([0, 0, 0.15]), q0=J.PICK_HOME)
    grasp = J.jaco_ik(env.model, cube + np.array([0, 0, 0.03]), q0=above)
    lift = J.jaco_ik(env.model, cube + np.array([0, 0, 0.25]), q0=grasp)
    return [(above, -1.0, 30), (grasp, -1.0, 30), (grasp, 1.0, 25), (lift, 1.0, 40)]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_scripted_throw_lands_in_basket(seed):
    env = make_env("throw")
    success, rewards = scripted_throw(env, seed)
    assert success
    assert rewards[-1] > -J.BASKET_INNER_HALF * np.sqrt(2)  # minus the horizontal distance
    assert rewards[0] < -0.8  # starts about 0.9 m away


@pytest.mark.parametrize("seed", [0, 3])
def test_scripted_pick_through_chunked_wrapper(seed):
    env = ChunkedEnv(make_env("pick"), k=5, stale_world=True)
    obs, info = env.reset(seed=seed)
    base = env.unwrapped
    assert info["robot_pos"].shape == (7,)
    assert not base._reward_success(obs[18:21])[1]
    total = 0.0
    success_any = False
    for q, fingers, steps in pick_plan(base, obs[18:21].copy()):
        for _ in range(steps // 5):
            chunk = []
            target = base.joint_targets[:6]
            for _ in range(5):  # plan the chunk on the targets the env will hold
                a = np.clip((q - target) / J.ARM_DELTA, -1, 1) * 0.5
                target = target + a * J.ARM_DELTA
                chunk.append(np.r_[a, fingers])
            obs, r, _, _, info = env.step(np.stack(chunk))
            total += r
            success_any = info["success_any"]
    assert success_any and info["success"]
    assert obs[20] > base._cube_rest_z + J.PICK_LIFT  # cube lifted
    assert total > 0.0


def test_pick_reward_needs_the_cube_held():
    env = make_env("pick", seed=0)
    env.reset()
    cube_z = env.data.qpos[env._cube_q + 2]
    r = env.stale_reward(np.r_[0.0, 0.5, cube_z + 0.2, 1.0, 0, 0, 0, 0, 0, 0])
    assert r == 0.0  # lifted cube far from the open hand: not held, no reward


def test_throw_stale_reward_uses_the_snapshot():
    env = make_env("throw", seed=0)
    env.reset()
    snap = env.world_snapshot()
    snap[:2] = env._goal[:2] + np.array([0.3, 0.4])
    assert env.stale_reward(snap) == pytest.approx(-0.5)


def test_reset_state_holds_the_cube_and_dmp_state_is_physical():
    env = make_env("throw", seed=0)
    obs, info = env.reset()
    assert obs[20] > 0.25  # cube held in the hand, not on the floor
    np.testing.assert_allclose(info["robot_pos"][:6], obs[:6])
    assert info["robot_pos"][6] == pytest.approx(obs[6:9].mean())
    assert abs(env._goal[1] - obs[19] - J.THROW_DISTANCE) <= 0.051


def test_render_upright_frames_and_mp4(tmp_path):
    env = make_env("throw", render_mode="rgb_array", width=96, height=64)
    env.reset(seed=0)
    frames = []
    for _ in range(5):
        env.step(np.zeros(7))
        frames.append(env.render())
    f = frames[-1]
    assert f.shape == (64, 96, 3) and f.dtype == np.uint8
    # Upright: dark sky on top, lit floor at the bottom.
    assert f[:8].mean() < f[-8:].mean()
    path = write_mp4(frames, tmp_path / "throw.mp4", fps=10)
    assert path.stat().st_size > 0
    with pytest.raises(ValueError, match="frames"):
        write_mp4([], tmp_path / "x.mp4")
    env.close()
    mw = make_env("reach-v3", render_mode="rgb_array", width=64, height=64)
    mw.reset(seed=0)
    frame = mw.render()
    assert frame.shape == (64, 64, 3) and frame.dtype == np.uint8
    mw.close()


def test_jaco_command_state_is_the_joint_targets():
    env = ChunkedEnv(make_env("throw"), k=5, stale_world=True)
    _, info = env.reset(seed=0)
    a = np.zeros((5, 7))
    a[:, 0] = 1.0
    _, _, _, _, info2 = env.step(a)
    from ndp.envs import jaco

    np.testing.assert_allclose(
        info2["cmd_y0"][0] - info["cmd_y0"][0], 5 * jaco.ARM_DELTA, atol=1e-9
    )
    np.testing.assert_allclose(info2["cmd_dy0"][0], jaco.ARM_DELTA / jaco.CONTROL_DT, atol=1e-9)
    assert info2["cmd_y0"][0] > info2["dmp_y0"][0]  # the joint lags its target
    env.close()
