"""Torque-actuated variants of the tasks, driven by the impedance controller (VICES baseline).

The models are edited as they load (:class:`mujoco.MjSpec`): torque actuators (``motor``
transmissions, control range = the torque limits below) are added on the arm joints; the
gripper actuation is kept as it is. Rewards, success, observations, horizons and the reset
distribution are those of the position-controlled tasks: each reset runs the task's own reset
with the original actuation (Meta-World's mocap weld, the Jaco's joint position servos and
gravity compensation), then hands the arm to the torque actuators.

- Meta-World (:class:`MetaWorldTorqueEnv`): the Sawyer's mocap weld is switched off after reset
  (``data.eq_active``; ``mj_resetData`` switches it back on for the next reset). The hand (body
  ``hand``) is driven by operational-space control of its position, its orientation held at the
  reset orientation. The task's rewards read only the gripper command of the action, which is
  passed as before.
- Jaco (:class:`JacoTorqueEnv`): the arm's position actuators (actuator group 1) and MuJoCo's
  passive gravity compensation of the robot bodies are switched off after reset and the torque
  actuators (group 2) on (``opt.disableactuator``, ``body_gravcomp``): gravity is carried by the
  torque actuators, within the torque limits. The fingers keep their position servos and tied
  delta command (``FINGER_DELTA`` per unit action).

Clocks: the controller runs at every simulator step (``sim_dt``: Meta-World 0.0025 s, Jaco
0.002 s) as ``mj_step1`` -> torques -> ``mj_step2``; the policy decides once per env step
(``control_dt``: 0.0125 s, 0.02 s), or once per k env steps with a holding head.

Torque limits (N m, per arm joint): Sawyer 80, 80, 40, 40, 9, 9, 9 (the effort limits of
Rethink's Sawyer URDF); Jaco 30.5 on joints 1-3 and 6.8 on joints 4-6 (the peak torques of
Kinova's K-75+ and K-58 actuators of the JACO2 arm). Both are stated from the vendors' published
figures as recalled, not re-checked against a datasheet here.

Info keys of every step besides the base env's: ``ctrl_gains_clipped`` (gain entries outside
their range, clipped), ``ctrl_torque_saturated`` (torque entries clipped at the limit, summed
over the simulator steps), ``ctrl_nonfinite`` (a torque was NaN / inf: the episode ends like an
unstable simulator, ``sim_unstable`` True).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from gymnasium.utils.ezpickle import EzPickle
from numpy.typing import ArrayLike

from ndp.envs import jaco
from ndp.envs.base import CTRL_INFO, fit_offscreen_buffer, sim_unstable, warning_count
from ndp.envs.impedance import ImpedanceArm, ImpedanceController
from ndp.envs.metaworld_env import MetaWorldEnv

if TYPE_CHECKING:
    from metaworld.sawyer_xyz_env import SawyerXYZEnv

SAWYER_JOINTS = tuple(f"right_j{i}" for i in range(7))
"""The Sawyer arm joints of the Meta-World models."""
SAWYER_TORQUE_LIMIT = (80.0, 80.0, 40.0, 40.0, 9.0, 9.0, 9.0)
"""Sawyer joint torque limits (N m)."""
JACO_TORQUE_LIMIT = (30.5, 30.5, 30.5, 6.8, 6.8, 6.8)
"""Jaco joint torque limits (N m)."""
TORQUE_PREFIX = "torque_"
"""Name prefix of the added torque actuators (``torque_<joint>``)."""
EE_MAX_DELTA = 0.05
"""Meta-World: largest end-effector target displacement per decision (m; robosuite's OSC)."""
JACO_EE_MAX_DELTA = 0.1
"""Jaco in end-effector space: largest target displacement per decision (m)."""
JACO_JOINT_MAX_DELTA = 0.5
"""Jaco in joint space: largest joint target displacement per decision (rad)."""
JACO_EE_LOW = np.array([-0.8, -0.6, 0.02])
"""Jaco end-effector target bounds (m, world frame): low ..."""
JACO_EE_HIGH = np.array([0.8, 1.2, 1.2])
"""... and high."""
__all__ = ["CTRL_INFO", "JacoTorqueEnv", "MetaWorldTorqueEnv"]


def _add_torque_actuators(
    spec: mujoco.MjSpec, joints: tuple[str, ...], limits: tuple[float, ...], group: int = 0
) -> None:
    """Add one motor (gear 1, control = torque in N m, clipped to +- limit) per joint."""
    for joint, lim in zip(joints, limits, strict=True):
        act = spec.add_actuator()
        act.name = TORQUE_PREFIX + joint
        act.target = joint
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = np.array([-lim, lim])
        act.group = group


def _gain_out_of_range(raw: np.ndarray, ctrl: ImpedanceController) -> int:
    """Entries of the kp / zeta part of a raw action outside ``[-1, 1]`` (clipped)."""
    n = ctrl.n_axes
    gains = raw[n : (3 if ctrl.learn_damping else 2) * n]
    return int(np.count_nonzero(np.abs(gains) > 1.0))


def _ctrl_info(clipped: int, saturated: int, finite: bool) -> dict[str, int]:
    """The controller's info counters of one env step."""
    return {
        "ctrl_gains_clipped": int(clipped),
        "ctrl_torque_saturated": int(saturated),
        "ctrl_nonfinite": int(not finite),
    }


# ---------------------------------------------------------------------- Meta-World (Sawyer)
@functools.cache
def _sawyer_torque_class(cls: type) -> type:
    """Subclass of a metaworld task whose model has the Sawyer torque actuators.

    Its ``do_simulation`` (used by the task's own reset, with the mocap weld on) takes the two
    gripper controls as before and leaves the torque actuators at zero.
    """

    def _initialize_simulation(self: SawyerXYZEnv) -> tuple[mujoco.MjModel, mujoco.MjData]:
        spec = mujoco.MjSpec.from_file(self.fullpath)
        _add_torque_actuators(spec, SAWYER_JOINTS, SAWYER_TORQUE_LIMIT)
        model = spec.compile()
        fit_offscreen_buffer(model, self.width, self.height)
        return model, mujoco.MjData(model)

    def do_simulation(self: SawyerXYZEnv, ctrl: ArrayLike, n_frames: int) -> None:
        self.data.ctrl[:] = 0.0
        self.data.ctrl[:2] = ctrl
        mujoco.mj_step(self.model, self.data, nstep=n_frames)
        mujoco.mj_rnePostConstraint(self.model, self.data)

    return type(
        cls.__name__ + "Torque",
        (cls,),
        {"_initialize_simulation": _initialize_simulation, "do_simulation": do_simulation},
    )


class MetaWorldTorqueEnv(MetaWorldEnv):
    """A Meta-World v3 task with the Sawyer's joints driven by torque (see the module docstring).

    Action [A] in ``[-1, 1]`` (clipped), A = ``controller.action_dim``: hand target displacement
    (xyz, m: ``controller.max_delta`` per unit) from the measured hand position, kp per axis,
    optionally the damping ratio per axis, and the absolute gripper command (-1 open, +1 closed).
    The target is clipped to metaworld's hand (mocap) bounds.
    """

    def __init__(
        self,
        task: str = "push-v3",
        controller: ImpedanceController | None = None,
        horizon: int = 150,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 480,
        camera_name: str = "corner",
        reward_version: str = "v2",
        fixed_goal: int | str | None = None,
    ) -> None:
        """Create the env (``controller``: the task table's row; None: the default OSC row;
        ``reward_version``, ``fixed_goal``: as :class:`ndp.envs.metaworld_env.MetaWorldEnv`)."""
        self.controller = controller if controller is not None else sawyer_controller()
        if self.controller.space != "ee" or not self.controller.gripper:
            raise ValueError("controller: Meta-World takes end-effector control with a gripper")
        super().__init__(
            task, horizon, render_mode, width, height, camera_name,
            reward_version=reward_version, fixed_goal=fixed_goal,
        )  # fmt: skip
        EzPickle.__init__(
            self, task, self.controller, horizon, render_mode, width, height, camera_name,
            reward_version, fixed_goal,
        )  # fmt: skip
        m = self.model
        self._weld = np.array(
            [i for i in range(m.neq) if m.eq_type[i] == mujoco.mjtEq.mjEQ_WELD], dtype=int
        )
        self.arm = ImpedanceArm(
            m,
            self.controller,
            SAWYER_JOINTS,
            tuple(TORQUE_PREFIX + j for j in SAWYER_JOINTS),
            ee=("body", "hand"),
            target_low=self.mw.mocap_low,
            target_high=self.mw.mocap_high,
        )
        self._frame_skip = int(self.mw.frame_skip)

    def _action_dim(self) -> int:
        return self.controller.action_dim

    def _task_class(self, cls: type) -> type:
        return _sawyer_torque_class(cls)

    def command_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Commanded state: the impedance target (m) and the last gripper command; the target
        is not differentiated (velocity 0) and the command's rate (1/s)."""
        pos = np.append(self.arm.goal, self._gripper)
        return pos, np.append(np.zeros(3), self._gripper_rate)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """The task's own reset (mocap weld on), then the weld off and the hand held where it is."""
        obs, info = super().reset(seed=seed, options=options)
        self.data.eq_active[self._weld] = 0
        self.data.ctrl[:] = 0.0
        self.data.ctrl[:2] = [-1.0, 1.0]  # the open gripper of metaworld's hand reset
        mujoco.mj_forward(self.model, self.data)
        self.arm.reset(self.data)
        info.update(_ctrl_info(0, 0, True))
        return obs, info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One env step: ``frame_skip`` simulator steps with fresh torques at each.

        Returns:
            As :meth:`MetaWorldEnv.step`, plus the controller counters (:data:`CTRL_INFO`).
        """
        raw = self._check_action(action)
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        mw, m, d = self.mw, self.model, self.data
        self._check_running(mw.curr_path_length)
        ctrl = self.controller
        warn_before = warning_count(d)
        clipped, grip = 0, self._gripper
        if mw.curr_path_length % ctrl.period == 0:  # a decision: new target, gains, gripper
            a = np.clip(raw, -1.0, 1.0)
            delta, kp, zeta, grip = ctrl.decode(a)
            clipped = _gain_out_of_range(raw, ctrl)
            clipped += self.arm.set_goal(d, delta, kp, zeta, ctrl.period * self._frame_skip)
        d.ctrl[:2] = [grip, -grip]
        saturated, finite = self.arm.step(d, self._frame_skip)
        mw.curr_path_length += 1
        self._gripper_rate = (grip - self._gripper) / self.control_dt
        self._gripper = grip
        cinfo = _ctrl_info(clipped, saturated, finite)
        if not finite or sim_unstable(d, warn_before):
            pos, vel = self.robot_state()
            return self._unstable_step(self._obs.copy(), pos, vel, cinfo)
        mujoco.mj_rnePostConstraint(m, d)
        for site in mw._target_site_config:
            mw._set_pos_site(*site)
        mujoco.mj_forward(m, d)
        obs = np.clip(
            mw._get_obs(), mw.sawyer_observation_space.low, mw.sawyer_observation_space.high
        ).astype(np.float64)
        mw_action = np.array([0.0, 0.0, 0.0, grip], dtype=np.float32)
        reward, mw_info = mw.evaluate_state(obs, mw_action)
        pos, vel = self.robot_state()
        info: dict[str, Any] = {k: float(v) for k, v in mw_info.items()}
        self._obs = obs
        info.update(self._state_info(bool(mw_info["success"] > 0.5), pos, vel))
        info.update(cinfo)
        truncated = mw.curr_path_length >= self.horizon
        return obs.copy(), float(reward), False, bool(truncated), info


def sawyer_controller(learn_damping: bool = False, period: int = 1) -> ImpedanceController:
    """The Meta-World task table's controller row (OSC of the hand position)."""
    return ImpedanceController(
        space="ee",
        max_delta=(EE_MAX_DELTA,) * 3,
        torque_limit=SAWYER_TORQUE_LIMIT,
        learn_damping=learn_damping,
        period=period,
    )


# ---------------------------------------------------------------------- Jaco
ARM_POSITION_GROUP = 1
"""Actuator group of the Jaco's arm position actuators in the torque model (off after reset)."""
TORQUE_GROUP = 2
"""Actuator group of the added torque actuators (off during the reset)."""


@functools.lru_cache(maxsize=1)
def _jaco_torque_base() -> mujoco.MjModel:
    kinova = jaco.jaco_asset_dir() / "meshes_decimated"
    assets = {p.name: p.read_bytes() for p in kinova.glob("*.stl")}
    spec = mujoco.MjSpec.from_string(jaco._compiled_model_xml(), assets=assets)
    for name in jaco.POSITION_ACTUATORS[:6]:
        spec.actuator(name).group = ARM_POSITION_GROUP
    _add_torque_actuators(spec, jaco.ARM_JOINTS, JACO_TORQUE_LIMIT, TORQUE_GROUP)
    return spec.compile()


def build_jaco_torque_model() -> mujoco.MjModel:
    """A fresh copy of the Jaco scene with the six torque actuators (group 2) added."""
    import copy

    return copy.deepcopy(_jaco_torque_base())


def jaco_controller(
    space: str = "joint", learn_damping: bool = False, period: int = 1
) -> ImpedanceController:
    """The Jaco task table's controller row: ``"joint"`` space (VICES's default on Throw / Pick)
    or ``"osc"`` / ``"ee"`` end-effector space (grip site position, orientation held)."""
    if space not in ("joint", "osc", "ee"):
        raise ValueError(f"space: expected 'joint', 'osc' or 'ee', got {space!r}")
    if space == "joint":
        max_delta: tuple[float, ...] = (JACO_JOINT_MAX_DELTA,) * 6
    else:
        max_delta = (JACO_EE_MAX_DELTA,) * 3
    return ImpedanceController(
        space="joint" if space == "joint" else "ee",
        max_delta=max_delta,
        torque_limit=JACO_TORQUE_LIMIT,
        learn_damping=learn_damping,
        period=period,
    )


class JacoTorqueEnv(jaco.JacoEnv):
    """Jaco Throw / Pick with the arm joints driven by torque (see the module docstring).

    Action [A] in ``[-1, 1]`` (clipped), A = ``controller.action_dim``: target displacement
    (joint space: rad per arm joint from the measured angles, clipped to the joint ranges;
    end-effector space: grip-site xyz in m from its measured position, clipped to
    ``JACO_EE_LOW`` / ``JACO_EE_HIGH``), kp per axis, optionally the damping ratio per axis,
    and the tied finger-target delta / ``FINGER_DELTA`` (as in :class:`ndp.envs.jaco.JacoEnv`).
    """

    def __init__(
        self,
        task: str = "throw",
        controller: ImpedanceController | None = None,
        horizon: int = 150,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 480,
        camera: str = "side",
        fixed_goal: int | str | None = None,
    ) -> None:
        """Create the env (``controller``: the task table's row; None: joint space;
        ``fixed_goal``: as :class:`ndp.envs.jaco.JacoEnv`)."""
        self.controller = controller if controller is not None else jaco_controller()
        if not self.controller.gripper:
            raise ValueError("controller: the Jaco tasks take a finger command")
        super().__init__(task, horizon, render_mode, width, height, camera, fixed_goal=fixed_goal)
        EzPickle.__init__(
            self, task, self.controller, horizon, render_mode, width, height, camera, fixed_goal
        )
        m = self.model
        ee = ("site", "jaco/hand/gripsite") if self.controller.space == "ee" else None
        if self.controller.space == "ee":
            low, high = JACO_EE_LOW, JACO_EE_HIGH
        else:
            low, high = self._ctrl_lo[:6], self._ctrl_hi[:6]
        self.arm = ImpedanceArm(
            m,
            self.controller,
            jaco.ARM_JOINTS,
            tuple(TORQUE_PREFIX + j for j in jaco.ARM_JOINTS),
            ee=ee,
            target_low=low,
            target_high=high,
        )
        self._robot_bodies = np.array(
            [b for b in range(m.nbody) if m.body(b).name.startswith("jaco/")], dtype=int
        )
        self._gravcomp = m.body_gravcomp[self._robot_bodies].copy()
        self._finger_cmd = 0.0

    def _action_dim(self) -> int:
        return self.controller.action_dim

    def _build_model(self) -> mujoco.MjModel:
        return build_jaco_torque_model()

    def _torque_mode(self, on: bool) -> None:
        """Switch between the reset's actuation (position servos, passive gravity
        compensation) and the torque actuators."""
        m = self.model
        if on:
            m.opt.disableactuator = 1 << ARM_POSITION_GROUP
            m.body_gravcomp[self._robot_bodies] = 0.0
        else:
            m.opt.disableactuator = 1 << TORQUE_GROUP
            m.body_gravcomp[self._robot_bodies] = self._gravcomp

    def command_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Commanded state: the joint impedance target (joint space; measured angles in
        end-effector space) and the tied finger target (rad); velocities 0 for the arm."""
        pos, _ = self.robot_state()
        if self.controller.space == "joint":
            pos[:6] = self.arm.goal
        pos[6] = self._target[6:].mean()
        return pos, np.append(np.zeros(6), self._target_rate[6])

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """The task's own reset with the position servos, then the torque actuators hold."""
        self._torque_mode(False)
        obs, info = super().reset(seed=seed, options=options)
        self._torque_mode(True)
        self.data.ctrl[self.arm.act] = 0.0
        mujoco.mj_forward(self.model, self.data)
        self.arm.reset(self.data)
        self._finger_cmd = 0.0
        info.update(_ctrl_info(0, 0, True))
        return obs, info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One env step (``FRAME_SKIP`` simulator steps with fresh torques at each).

        Returns:
            As :meth:`JacoEnv.step`, plus the controller counters (:data:`CTRL_INFO`).
        """
        raw = self._check_action(action)
        self._check_running(self._steps)
        ctrl = self.controller
        d = self.data
        decision = self._steps % ctrl.period == 0  # new target, gains and finger command
        clipped = 0
        if decision:
            a = np.clip(raw, -1.0, 1.0)
            delta, kp, zeta, self._finger_cmd = ctrl.decode(a)
            clipped = _gain_out_of_range(raw, ctrl)
        prev = self._target.copy()
        step = self._finger_cmd * jaco.FINGER_DELTA  # per env step, for the whole period
        fingers = np.clip(prev[6:] + step, self._ctrl_lo[6:], self._ctrl_hi[6:])
        self._target[6:] = fingers
        self._target_rate = np.zeros(7)
        self._target_rate[6] = float((fingers - prev[6:]).mean()) / jaco.CONTROL_DT
        d.ctrl[self._act[6:]] = fingers
        warn_before = warning_count(d)
        last_obs = self._obs()
        if decision:
            clipped += self.arm.set_goal(d, delta, kp, zeta, ctrl.period * jaco.FRAME_SKIP)
        saturated, finite = self.arm.step(d, jaco.FRAME_SKIP)
        self._steps += 1
        cinfo = _ctrl_info(clipped, saturated, finite)
        pos, vel = self.robot_state()
        if not finite or sim_unstable(d, warn_before):
            return self._unstable_step(last_obs, pos, vel, cinfo)
        reward, success = self._reward_success(self._cube_pos().copy())
        info = self._state_info(success, pos, vel)
        info.update(cinfo)
        return self._obs(), float(reward), False, self._steps >= self.horizon, info
