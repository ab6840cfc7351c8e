"""The VICES impedance controller and the torque-actuated tasks (ndp.envs.impedance / torque)."""

from __future__ import annotations

import copy
import warnings

import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from ndp.envs import TORQUE_TASKS, ChunkedEnv, get_task_spec, make_env, torque_variant
from ndp.envs.impedance import (
    ImpedanceController,
    clip_gains,
    joint_impedance_torque,
    orientation_error,
    osc_torque,
    osc_torque_dense,
)


def _hold(name, offset, kp, reach_s=2.0, hold_s=3.0, force=None, torque=None):
    """Fixed target (measured + offset), no policy: run the controller alone.

    Returns (error after reach_s, max error over the next hold_s, orientation error, deflection
    vector at the end, max |torque| / limit, all torques finite)."""
    env = make_env(name, seed=0)
    env.reset(seed=0)
    arm, d, m = env.arm, env.data, env.model
    n = arm.ctrl.n_axes
    period = round(0.1 / m.opt.timestep)
    arm.set_goal(d, np.asarray(offset, float), np.full(n, kp), np.ones(n), period)
    goal = arm.goal.copy()
    if force is not None:
        d.xfrc_applied[arm.ee_id if arm.ee_kind == "body" else m.body("jaco/hand/hand").id, :3] = (
            force
        )
    if torque is not None:
        d.qfrc_applied[arm.dofs] = torque
    ratio, finite = 0.0, True
    for _ in range(int(reach_s / m.opt.timestep)):
        _, ok = arm.step(d, 1)
        finite &= ok
        ratio = max(ratio, float(np.max(np.abs(d.ctrl[arm.act]) / arm.limit)))
    reach = float(np.abs(arm.position(d) - goal).max())
    hold = 0.0
    for _ in range(int(hold_s / m.opt.timestep)):
        _, ok = arm.step(d, 1)
        finite &= ok and bool(np.all(np.isfinite(d.actuator_force)))
        ratio = max(ratio, float(np.max(np.abs(d.actuator_force[arm.act]) / arm.limit)))
        hold = max(hold, float(np.abs(arm.position(d) - goal).max()))
    ori = 0.0
    if arm.ctrl.space == "ee":
        ori = float(np.linalg.norm(orientation_error(arm.rot_goal, arm.rotation(d))))
    return reach, hold, ori, arm.position(d) - goal, ratio, finite


def test_osc_reaches_and_holds_target_against_gravity():
    # Sawyer: 5 cm on each axis, kp 150 (mid range): within 1 mm after 2 s, held within 2 mm
    # for 3 s more, orientation within 0.03 rad; torques finite and within the limits
    reach, hold, ori, _, ratio, finite = _hold("push-v3-osc", [0.05, -0.05, 0.05], 150.0)
    assert reach < 1e-3 and hold < 2e-3 and ori < 0.03, (reach, hold, ori)
    assert finite and ratio <= 1.0 + 1e-9


def test_joint_impedance_reaches_and_holds_target():
    # Jaco: 0.2-0.3 rad on every joint; the model's joint friction (frictionloss ~1.4 / 0.7 N m)
    # leaves a static error frictionloss / (M kp) of ~2.5 mrad at kp 150: tolerance 5 mrad
    offset = [0.2, -0.2, 0.2, 0.3, -0.3, 0.3]
    reach, hold, _, _, ratio, finite = _hold("pick-joint", offset, 150.0)
    assert reach < 5e-3 and hold < 5e-3, (reach, hold)
    assert finite and ratio <= 1.0 + 1e-9


def test_jaco_osc_reaches_and_holds_target():
    reach, hold, ori, _, ratio, finite = _hold("pick-osc", [0.05, 0.05, 0.05], 150.0)
    assert reach < 3e-3 and hold < 3e-3 and ori < 0.03, (reach, hold, ori)
    assert finite and ratio <= 1.0 + 1e-9


def test_higher_kp_is_stiffer():
    # steady deflection under a constant push: theory 1 / kp (ratio 6 between kp 50 and 300)
    soft = np.linalg.norm(_hold("push-v3-osc", [0, 0, 0], 50.0, force=[1.0, 0, 0])[3])
    stiff = np.linalg.norm(_hold("push-v3-osc", [0, 0, 0], 300.0, force=[1.0, 0, 0])[3])
    assert stiff < soft / 4, (soft, stiff)
    push = np.array([8.0, 0, 0, 0, 0, 0])
    soft_j = np.abs(_hold("pick-joint", [0] * 6, 50.0, torque=push)[3]).max()
    stiff_j = np.abs(_hold("pick-joint", [0] * 6, 300.0, torque=push)[3]).max()
    assert stiff_j < soft_j / 3, (soft_j, stiff_j)


def test_step1_step2_is_mj_step():
    # the controller's split step equals MuJoCo's own step for both integrators in use
    for name in ("push-v3-osc", "throw-joint"):
        env = make_env(name, seed=0)
        env.reset(seed=0)
        m, d = env.model, env.data
        d2 = copy.copy(d)  # MjData's copy is a deep copy of the state
        d.ctrl[env.arm.act] = 1.0
        d2.ctrl[:] = d.ctrl
        mujoco.mj_step(m, d)
        mujoco.mj_step1(m, d2)
        mujoco.mj_step2(m, d2)
        np.testing.assert_allclose(d.qpos, d2.qpos, atol=1e-12)
        np.testing.assert_allclose(d.qvel, d2.qvel, atol=1e-12)


def test_pure_functions_shapes_and_values():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(7, 7))
    mass = a @ a.T + 7 * np.eye(7)
    jac = rng.normal(size=(6, 7))
    bias = rng.normal(size=7)
    zero = np.zeros(6)
    # no error, no velocity, no posture: only the compensation
    tau = osc_torque_dense(jac, mass, bias, zero, zero, np.ones(6), np.ones(6), np.zeros(7))
    np.testing.assert_allclose(tau, bias, atol=1e-12)
    # the task force reaches the end effector: J M^-1 (tau - bias) = Lambda^-1 F = kp * err
    err = rng.normal(size=6)
    kp = np.full(6, 100.0)
    tau = osc_torque_dense(jac, mass, bias, err, zero, kp, np.ones(6), np.zeros(7))
    np.testing.assert_allclose(jac @ np.linalg.solve(mass, tau - bias), kp * err, rtol=1e-9)
    # the posture term does not accelerate the end effector (dynamically consistent null space)
    jm = jac @ np.linalg.inv(mass)
    post = rng.normal(size=7)
    tau = osc_torque(jac, jm, np.zeros(7), zero, zero, kp, kp, post)
    np.testing.assert_allclose(jac @ np.linalg.solve(mass, tau), np.zeros(6), atol=1e-9)
    t = joint_impedance_torque(mass, bias, np.ones(7), np.zeros(7), np.full(7, 2.0), np.ones(7))
    np.testing.assert_allclose(t, mass @ np.full(7, 2.0) + bias)


def test_gains_outside_bounds_are_clipped_and_counted():
    kp, zeta, n = clip_gains(np.array([5.0, 100.0, 1e4]), np.array([-1.0, 1.0, np.nan]))
    np.testing.assert_array_equal(kp, [10.0, 100.0, 300.0])
    np.testing.assert_array_equal(zeta, [0.0, 1.0, 0.0])
    assert n == 4
    env = make_env("push-v3-osc", seed=0)
    env.reset(seed=0)
    assert env.arm.set_goal(env.data, np.zeros(3), [1e6, 0, 50], [3, 1, 1], 5) == 3
    assert np.all(env.arm.kp <= 300) and np.all(env.arm.zeta <= 2)
    # raw kp actions outside [-1, 1] are clipped by the env and counted
    a = np.zeros(env.action_space.shape)
    a[3:6] = [5.0, -5.0, 0.5]
    *_, info = env.step(a)
    assert info["ctrl_gains_clipped"] == 2


def test_action_mapping():
    ctrl = ImpedanceController("ee", (0.05,) * 3, (1.0,) * 7, learn_damping=True)
    assert ctrl.action_dim == 10
    delta, kp, zeta, grip = ctrl.decode(np.array([1, -1, 0, -1, 0, 1, -1, 0, 1, 0.5]))
    np.testing.assert_allclose(delta, [0.05, -0.05, 0.0])
    np.testing.assert_allclose(kp, [10.0, 155.0, 300.0])
    np.testing.assert_allclose(zeta, [0.0, 1.0, 2.0])
    assert grip == 0.5
    with pytest.raises(ValueError, match="space"):
        ImpedanceController("cartesian", (0.05,) * 3, (1.0,) * 7)
    with pytest.raises(ValueError, match="period"):
        ImpedanceController("ee", (0.05,) * 3, (1.0,) * 7, period=0)


@pytest.mark.parametrize("name", ["push-v3-osc", "throw-joint", "throw-osc-zeta", "pick-joint-k5"])
def test_check_env_and_same_seed_same_episode(name):
    env = make_env(name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    messages = [str(w.message) for w in caught if "infinity" not in str(w.message)]
    messages = [m for m in messages if "maximum and minimum values are equal" not in m]
    assert messages == [], messages

    def rollout():
        obs, _ = env.reset(seed=3)
        rng = np.random.default_rng(1)
        out = [obs]
        for _ in range(6):
            out.append(env.step(rng.uniform(-1, 1, env.action_space.shape))[0])
        return np.array(out)

    np.testing.assert_array_equal(rollout(), rollout())


@pytest.mark.parametrize("name", ["push-v3", "throw", "pick"])
def test_same_reset_and_same_rewards_as_the_position_task(name):
    """Same seed: same first observation; same robot + world state: same reward and success
    (the mocap / position env's recorded states replayed into the torque env)."""
    pos_env = make_env(name, seed=0)
    tq_env = make_env(torque_variant(get_task_spec(name)).name, seed=0)
    obs_p, _ = pos_env.reset(seed=5)
    obs_t, _ = tq_env.reset(seed=5)
    np.testing.assert_array_equal(obs_p, obs_t)
    rng = np.random.default_rng(0)
    for _ in range(25):
        a = rng.uniform(-1, 1, pos_env.action_space.shape)
        prev = pos_env.mw._prev_obs.copy() if name.endswith("-v3") else None
        _, r, _, _, info = pos_env.step(a)
        d_t = tq_env.data
        d_t.qpos[:] = pos_env.data.qpos
        d_t.qvel[:] = pos_env.data.qvel
        mujoco.mj_forward(tq_env.model, d_t)
        if name.endswith("-v3"):
            mw = tq_env.mw
            mw._prev_obs = prev
            for site in mw._target_site_config:
                mw._set_pos_site(*site)
            obs = np.clip(
                mw._get_obs(), mw.sawyer_observation_space.low, mw.sawyer_observation_space.high
            )
            np.testing.assert_allclose(obs, pos_env._obs, atol=1e-12)
            r_t, info_t = mw.evaluate_state(obs, np.float32(a))
            assert r_t == pytest.approx(r, abs=1e-9) and info_t["success"] == info["success"]
        else:
            r_t, s_t = tq_env._reward_success(tq_env._cube_pos().copy())
            assert r_t == pytest.approx(r, abs=1e-12) and s_t == info["success"]


def test_nonfinite_torque_ends_the_episode_with_a_flag():
    env = make_env("throw-joint", seed=0)
    env.reset(seed=0)
    env.arm.torque = lambda data: np.full(6, np.nan)  # a broken controller
    obs, r, term, trunc, info = env.step(np.zeros(env.action_space.shape))
    assert trunc and not term and r == 0.0 and info["sim_unstable"] and info["ctrl_nonfinite"]
    assert np.all(np.isfinite(obs))
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(env.action_space.shape))
    del env.arm.torque
    env.reset(seed=1)
    assert np.isfinite(env.step(np.zeros(env.action_space.shape))[1])


def test_low_frequency_rows_hold_the_decision_for_the_period():
    env = ChunkedEnv(make_env("push-v3-osc-k5", seed=0), k=5)
    env.reset(seed=0)
    base = env.unwrapped
    a = np.zeros((5, base.action_space.shape[0]))
    a[0, :3] = 1.0  # only the first sub-step's action is a decision
    a[1:, :3] = -1.0
    x0 = base.arm.position(base.data)
    env.step(a)
    np.testing.assert_allclose(base.arm.goal, np.clip(x0 + 0.05, base.arm.low, base.arm.high))
    a[:, :3] = 0.0
    a[1:, 0] = 1.0
    x1 = base.arm.position(base.data)
    env.step(a)  # sub-steps 1..4 are ignored: the new target is from sub-step 0 only
    np.testing.assert_allclose(base.arm.goal, x1)
    # one period = 5 env steps x 5 simulator steps; the ramp is its first 20 %
    assert base.arm.step_in_period == 25 and base.arm.ramp_steps == 5


def test_table_rows():
    assert len(TORQUE_TASKS) == 50 * 4 + 2 * 8
    s = get_task_spec("push-v3-osc")
    assert s.actuation == "torque" and s.base_task == "push-v3" and s.action_dim == 7
    assert s.horizon == get_task_spec("push-v3").horizon and s.obs_dim == 39
    assert get_task_spec("throw-joint").action_dim == 13
    assert get_task_spec("throw-osc-zeta").action_dim == 10
    assert torque_variant(get_task_spec("throw-joint-zeta"), space="osc").name == "throw-osc-zeta"
    with pytest.raises(ValueError, match="torque-actuated"):
        torque_variant(get_task_spec("point-mass"))
    with pytest.raises(ValueError, match="controller"):
        s.inverse_controller(None)
