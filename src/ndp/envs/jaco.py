"""Kinova Jaco tasks of the paper, re-created on MuJoCo 3.3: Throw and Pick.

The arm (6 hinge joints) and the 3-finger hand come from the Jaco model shipped inside the
installed ``dm_control`` 1.0.28 package (``dm_control/third_party/kinova``); they are loaded from
there at run time, never copied, and attached with :class:`mujoco.MjSpec` to the scene written for
this package (``assets/jaco_scene.xml``: floor, a 0.08 m / 0.2 kg cube, an open basket, cameras and
the position actuators).

Control: joint-angle position control with delta targets. An action ``a`` in ``[-1, 1]^7`` moves
the six arm joint targets by ``a[:6] * ARM_DELTA`` rad and the one tied finger target (the same
command for the three fingers) by ``a[6] * FINGER_DELTA`` rad; targets are clipped to the
actuators' control ranges. Gravity is compensated on the robot bodies (``gravcomp=1``), as on the
real arm's controller.

Clocks: simulator step ``SIM_DT`` = 0.002 s; one env step = ``FRAME_SKIP`` = 10 simulator steps =
``CONTROL_DT`` = 0.02 s (50 Hz). ``substeps=m`` (m in 1, 2, 5, 10; ``ndp rl eval --exec-k``)
makes one env step ``10 / m`` simulator steps (0.02 / m s) in which an action of 1 moves the joint
targets ``ARM_DELTA / m`` / ``FINGER_DELTA / m`` rad (the same speed per second).

DMP-driven robot state (D = 7): the six arm joint angles and the mean finger angle, in rad, and
their velocities in rad/s.
"""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.utils.ezpickle import EzPickle

from ndp.envs.base import (
    NDPEnv,
    check_render_size,
    check_substeps,
    fit_offscreen_buffer,
    sim_unstable,
    warning_count,
)

SIM_DT = 0.002
"""MuJoCo timestep (s)."""
FRAME_SKIP = 10
"""Simulator steps per env step."""
CONTROL_DT = SIM_DT * FRAME_SKIP
"""Seconds per env step (one sub-step of a chunked decision)."""
ARM_DELTA = 0.1
"""Arm joint-target change (rad) for an action of 1."""
FINGER_DELTA = 0.1
"""Finger joint-target change (rad) for an action of 1 (all three fingers, tied)."""
ARM_JOINTS = tuple(f"jaco/joint_{i}" for i in range(1, 7))
FINGER_JOINTS = tuple(f"jaco/hand/finger_{i}" for i in range(1, 4))
POSITION_ACTUATORS = tuple(f"a_joint_{i}" for i in range(1, 7)) + tuple(
    f"a_finger_{i}" for i in range(1, 4)
)
"""The scene's position actuators: six arm joints, then the three fingers."""
FINGER_OPEN = 0.15
"""Finger angle (rad) fully open (joint lower limit)."""
FINGER_CLOSED = 1.35
"""Finger angle (rad) fully closed (joint upper limit)."""
CUBE_HALF = 0.04
"""Half edge of the cube (m)."""
BASKET_INNER_HALF = 0.15
"""Inner half-width of the basket (m)."""
BASKET_RIM = 0.12
"""Height of the basket walls (m)."""
THROW_DISTANCE = 0.9
"""Nominal horizontal distance (m, along +y) from the cube's start to the basket centre."""
HOLD_OFFSET = 0.03
"""Throw start: the cube's centre is placed this far (m) beyond the grip site along the approach."""
PICK_LIFT = 0.10
"""Pick success: the cube's centre rises this much (m) above its resting height while held."""
HOLD_RADIUS = 0.08
"""Held: the cube's centre is within this distance (m) of the hand's grip site ..."""
HOLD_FINGER = 0.5
"""... and the mean finger angle (rad) is above this (fingers at least partly closed)."""

OBS_BOUND = np.array([10.0] * 9 + [100.0] * 9 + [5.0] * 3 + [1.0] * 4 + [100.0] * 3 + [5.0] * 6)
"""Observation bounds [34]: angles (rad; targets are clipped to +-6.3), joint velocities
(rad/s), cube position (m), quaternion, cube velocity (m/s), grip site and target (m)."""

# Home pose for Pick (hand pointing down, grip site about 0.3 m above the cube's nominal spot) and
# carry pose for Throw (cube in the closed hand); found with jaco_ik and stored as constants.
PICK_HOME = np.array([-1.416, 3.719, 1.846, -2.703, -1.507, 0.501])  # grip site (0, 0.5, 0.3)
THROW_HOME = np.array([-1.347, 3.327, 1.414, -2.722, -1.456, 0.555])  # grip site (0, 0.35, 0.35)


def jaco_asset_dir() -> Path:
    """Directory of the Jaco MJCF files inside the installed dm_control package.

    Returns:
        ``.../site-packages/dm_control/third_party/kinova``.

    Raises:
        ImportError: dm_control is not installed.
    """
    spec = importlib.util.find_spec("dm_control")  # locates the package without importing it
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("the Jaco tasks need dm_control==1.0.28 (pip install dm_control==1.0.28)")
    return Path(next(iter(spec.submodule_search_locations))) / "third_party" / "kinova"


@functools.lru_cache(maxsize=1)
def _compiled_model_xml() -> str:
    """Compose scene + arm + hand once per process and return the compiled model's XML."""
    kinova = jaco_asset_dir()
    scene = Path(__file__).with_name("assets") / "jaco_scene.xml"
    root = mujoco.MjSpec.from_file(str(scene))
    arm = mujoco.MjSpec.from_file(str(kinova / "jaco_arm.xml"))
    hand = mujoco.MjSpec.from_file(str(kinova / "jaco_hand.xml"))
    meshdir = str(kinova / "meshes_decimated")
    arm.meshdir = meshdir
    hand.meshdir = meshdir
    arm.attach(hand, prefix="hand/", site=arm.site("wristsite"))
    root.attach(arm, prefix="jaco/", site=root.site("robot_base"))
    for body in root.bodies:
        if body.name.startswith("jaco/"):
            body.gravcomp = 1.0
    root.compile()
    xml: str = root.to_xml()
    return xml


@functools.lru_cache(maxsize=1)
def _base_model() -> mujoco.MjModel:
    kinova = jaco_asset_dir() / "meshes_decimated"
    assets = {p.name: p.read_bytes() for p in kinova.glob("*.stl")}
    xml = _compiled_model_xml()
    # to_xml writes mesh files relative to the meshdir; point it at the dm_control mesh folder.
    return mujoco.MjModel.from_xml_string(xml, assets)


def build_jaco_model() -> mujoco.MjModel:
    """A fresh copy of the Jaco scene model (composed once per process, then copied).

    Returns:
        The compiled :class:`mujoco.MjModel` (nq = 16: cube free joint 7 + 6 arm + 3 fingers).
    """
    import copy

    return copy.deepcopy(_base_model())


def jaco_ik(
    model: mujoco.MjModel,
    target_pos: np.ndarray,
    approach: np.ndarray | None = None,
    q0: np.ndarray | None = None,
    iters: int = 200,
    site: str = "jaco/hand/gripsite",
) -> np.ndarray:
    """Damped least-squares inverse kinematics of the arm for the grip site (scripted motions).

    Args:
        model: A Jaco model from :func:`build_jaco_model`.
        target_pos: Desired site position [3] (m, world frame).
        approach: Desired direction [3] of the site's z axis (the hand's approach axis);
            default straight down.
        q0: Initial arm joint angles [6] (rad); default ``PICK_HOME``.
        iters: Gauss-Newton iterations.
        site: Site to place.

    Returns:
        Arm joint angles [6] (rad), limited joints clipped to their ranges, others wrapped to
        within pi of ``q0``.
    """
    approach = np.array([0.0, 0.0, -1.0]) if approach is None else np.asarray(approach, float)
    approach = approach / np.linalg.norm(approach)
    q: np.ndarray = (PICK_HOME if q0 is None else np.asarray(q0, float)).copy()
    ref = q.copy()
    data = mujoco.MjData(model)
    qadr = np.array([model.joint(j).qposadr[0] for j in ARM_JOINTS])
    vadr = np.array([model.joint(j).dofadr[0] for j in ARM_JOINTS])
    limited = np.array([bool(model.joint(j).limited[0]) for j in ARM_JOINTS])
    lo = np.array([model.joint(j).range[0] for j in ARM_JOINTS])
    hi = np.array([model.joint(j).range[1] for j in ARM_JOINTS])
    sid = model.site(site).id
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    for _ in range(iters):
        data.qpos[qadr] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        err_p = target_pos - data.site_xpos[sid]
        zaxis = data.site_xmat[sid].reshape(3, 3)[:, 2]
        err_r = np.cross(zaxis, approach)
        mujoco.mj_jacSite(model, data, jacp, jacr, sid)
        jac = np.vstack([jacp[:, vadr], jacr[:, vadr]])
        err = np.concatenate([err_p, err_r])
        dq = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), err)
        q = q + np.clip(dq, -0.3, 0.3)
        q = np.where(limited, np.clip(q, lo, hi), ref + (q - ref + np.pi) % (2 * np.pi) - np.pi)
    return q


class JacoEnv(NDPEnv, EzPickle):
    """Jaco arm with a 0.08 m, 0.2 kg cube; ``task`` selects Throw or Pick.

    Observation (float64, 34; clipped to ``OBS_BOUND``): arm joint angles [6], finger angles [3],
    arm joint velocities [6], finger velocities [3], cube position [3], cube quaternion [4],
    cube linear velocity [3], grip-site position [3], target position [3] (basket centre for
    Throw; the lift target above the cube's start for Pick), in metres, radians and seconds.

    Throw: the cube starts held in the closed hand; the basket's centre is ``THROW_DISTANCE``
    (+- 0.05 m, seeded) beyond the cube along +y. Reward = minus the cube's horizontal distance
    to the basket centre (m). Success: the cube's centre is inside the basket (within the inner
    half-width in x and y, below the rim).

    Pick: the cube rests on the floor in front of the arm (position jittered +- 0.05 m, seeded),
    hand open above it. Reward = the cube's height above its resting height (m) while it is held
    (cube centre within ``HOLD_RADIUS`` of the grip site and fingers closed past ``HOLD_FINGER``),
    else 0. Success: held and lifted by at least ``PICK_LIFT``.

    Episodes end by truncation at ``horizon`` steps, or early (``truncated=True`` with
    ``info["sim_unstable"]``) if the simulator goes unstable; there is no other termination.
    """

    # declared as gymnasium.Env declares it (a ClassVar would clash with its declaration)
    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 50}  # noqa: RUF012

    def __init__(
        self,
        task: str = "throw",
        horizon: int = 150,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 480,
        camera: str = "side",
        substeps: int = 1,
        fixed_goal: int | str | None = None,
    ) -> None:
        """Create the env.

        Args:
            task: ``"throw"`` or ``"pick"``.
            horizon: Env steps per episode (each ``CONTROL_DT / substeps`` s).
            render_mode: ``None`` or ``"rgb_array"``.
            width: Rendered frame width (px).
            height: Rendered frame height (px).
            camera: Camera name in the scene (``"side"`` or ``"front"``).
            substeps: m, a divisor of ``FRAME_SKIP``: one env step is ``FRAME_SKIP / m``
                simulator steps and an action moves the targets ``1 / m`` as far (see the
                module docstring).
            fixed_goal: None (a fresh seeded cube / basket jitter every reset), the seed of
                the one jitter every reset uses, or ``"release"`` (no jitter: the release's
                one basket / cube place).
        """
        EzPickle.__init__(
            self, task, horizon, render_mode, width, height, camera, substeps, fixed_goal
        )
        self.substeps = check_substeps(substeps, FRAME_SKIP)
        self._frame_skip = FRAME_SKIP // self.substeps
        self.control_dt = CONTROL_DT / self.substeps
        if task not in ("throw", "pick"):
            raise ValueError(f"task: expected 'throw' or 'pick', got {task!r}")
        self._setup(horizon, render_mode, action_dim=self._action_dim())
        self._set_fixed_goal(fixed_goal, task)
        self.task = task
        self.width = check_render_size("width", width)
        self.height = check_render_size("height", height)
        self.camera = camera
        self.model = self._build_model()
        fit_offscreen_buffer(self.model, self.width, self.height)  # the scene's is 640 x 480
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._arm_q = np.array([m.joint(j).qposadr[0] for j in ARM_JOINTS])
        self._arm_v = np.array([m.joint(j).dofadr[0] for j in ARM_JOINTS])
        self._fin_q = np.array([m.joint(j).qposadr[0] for j in FINGER_JOINTS])
        self._fin_v = np.array([m.joint(j).dofadr[0] for j in FINGER_JOINTS])
        self._cube_q = m.joint("cube").qposadr[0]
        self._cube_v = m.joint("cube").dofadr[0]
        self._grip = m.site("jaco/hand/gripsite").id
        self._basket_mocap = m.body("basket").mocapid[0]
        self._act = np.array([m.actuator(a).id for a in POSITION_ACTUATORS])
        self._ctrl_lo = m.actuator_ctrlrange[self._act, 0].copy()
        self._ctrl_hi = m.actuator_ctrlrange[self._act, 1].copy()
        self.observation_space = spaces.Box(-OBS_BOUND, OBS_BOUND, dtype=np.float64)
        self._target = np.zeros(9)
        self._target_rate = np.zeros(7)
        self._goal = np.zeros(3)
        self._cube_rest_z = CUBE_HALF
        self._steps = 0
        self._renderer: mujoco.Renderer | None = None

    def _action_dim(self) -> int:
        """Size of one action (7; the torque-actuated variant overrides it)."""
        return 7

    def _build_model(self) -> mujoco.MjModel:
        """The model of this env (the torque-actuated variant adds its actuators)."""
        return build_jaco_model()

    @property
    def joint_targets(self) -> np.ndarray:
        """Current position targets [9] (rad): 6 arm joints, then the 3 (tied) fingers."""
        targets: np.ndarray = self._target.copy()
        return targets

    # ------------------------------------------------------------------ state access
    def robot_state(self) -> tuple[np.ndarray, np.ndarray]:
        """DMP-driven robot state now.

        Returns:
            ``(pos [7], vel [7])``: six arm joint angles and the mean finger angle (rad), and
            their velocities (rad/s).
        """
        q = self.data.qpos
        v = self.data.qvel
        pos = np.concatenate([q[self._arm_q], [q[self._fin_q].mean()]])
        vel = np.concatenate([v[self._arm_v], [v[self._fin_v].mean()]])
        return pos, vel

    def command_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Commanded state now: what the actions move (the joint position targets lead the joints).

        Returns:
            ``(pos [7], vel [7])``: six arm joint targets and the tied finger target (rad), and
            their rate of change over the last env step (rad/s).
        """
        t = self._target
        pos = np.concatenate([t[:6], [t[6:].mean()]])
        return pos, self._target_rate.copy()

    def world_snapshot(self) -> np.ndarray:
        """Copy of the world (non-robot) state: cube position [3] and quaternion [4], and goal [3].

        Returns:
            Array [10].
        """
        c = self._cube_q
        snapshot: np.ndarray = np.concatenate([self.data.qpos[c : c + 7], self._goal]).copy()
        return snapshot

    def _cube_pos(self) -> np.ndarray:
        c = self._cube_q
        pos: np.ndarray = self.data.qpos[c : c + 3]
        return pos

    def _reward_success(self, cube_pos: np.ndarray) -> tuple[float, bool]:
        """Reward and success from the live robot and a (possibly stale) cube position [3]."""
        if self.task == "throw":
            d = float(np.linalg.norm(cube_pos[:2] - self._goal[:2]))
            inside = bool(
                np.all(np.abs(cube_pos[:2] - self._goal[:2]) < BASKET_INNER_HALF)
                and cube_pos[2] < BASKET_RIM
            )
            return -d, inside
        grip = self.data.site_xpos[self._grip]
        held = bool(
            np.linalg.norm(cube_pos - grip) < HOLD_RADIUS
            and self.data.qpos[self._fin_q].mean() > HOLD_FINGER
        )
        lift = float(cube_pos[2] - self._cube_rest_z)
        reward = max(lift, 0.0) if held else 0.0
        return reward, bool(held and lift >= PICK_LIFT)

    def stale_reward(self, snapshot: np.ndarray, action: np.ndarray | None = None) -> float:
        """Reward of the current step with the live robot and the world from ``snapshot``.

        Args:
            snapshot: From :meth:`world_snapshot`.
            action: Unused (the Jaco rewards do not depend on the action).

        Returns:
            The reward; pure (no side effects on the env).
        """
        del action
        return self._reward_success(snapshot[:3])[0]

    def _obs(self) -> np.ndarray:
        q, v = self.data.qpos, self.data.qvel
        c, cv = self._cube_q, self._cube_v
        obs = np.concatenate(
            [
                q[self._arm_q],
                q[self._fin_q],
                v[self._arm_v],
                v[self._fin_v],
                q[c : c + 3],
                q[c + 3 : c + 7],
                v[cv : cv + 3],
                self.data.site_xpos[self._grip],
                self._goal,
            ]
        )
        clipped: np.ndarray = np.clip(obs, -OBS_BOUND, OBS_BOUND)
        return clipped

    def release_config(self, task: str) -> np.ndarray | None:
        """The release's basket (Throw) or cube (Pick) jitter, 0: the nominal place
        (``ndp.envs.release.RELEASE_CONFIGS``)."""
        from ndp.envs.release import release_config

        return release_config(task)

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset; ``seed`` re-seeds the jitter of cube (Pick) or basket (Throw) positions."""
        self._reset_rng(seed)
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        release = self.release_config(self.task) if self.fixed_goal == "release" else None
        jitter = self._task_rng().uniform(-0.05, 0.05, size=2) if release is None else release
        if self.task == "pick":
            home, fingers = PICK_HOME, FINGER_OPEN
            cube = np.array([jitter[0], 0.5 + jitter[1], CUBE_HALF])
            d.mocap_pos[self._basket_mocap] = [1.5, -1.5, 0.0]  # out of the way
        else:
            home, fingers = THROW_HOME, FINGER_CLOSED
            cube = None
        d.qpos[self._arm_q] = home
        d.qpos[self._fin_q] = FINGER_OPEN if cube is None else fingers
        self._target = np.concatenate([home, np.full(3, fingers)])
        self._target_rate = np.zeros(7)
        d.ctrl[self._act] = self._target
        if cube is None:
            # Throw: hold the cube kinematically at the grip site while the fingers close on it.
            mujoco.mj_forward(m, d)
            grip_rot = d.site_xmat[self._grip].reshape(3, 3)
            hold = d.site_xpos[self._grip] + HOLD_OFFSET * grip_rot[:, 2]
            quat = np.array([1.0, 0.0, 0.0, 0.0])
            for _ in range(150):
                d.qpos[self._cube_q : self._cube_q + 3] = hold
                d.qpos[self._cube_q + 3 : self._cube_q + 7] = quat
                d.qvel[self._cube_v : self._cube_v + 6] = 0.0
                mujoco.mj_step(m, d)
            for _ in range(100):  # let go of the kinematic hold and settle in the hand
                mujoco.mj_step(m, d)
            cube_now = d.qpos[self._cube_q : self._cube_q + 3]
            self._goal = np.array(
                [cube_now[0] + jitter[0], cube_now[1] + THROW_DISTANCE + jitter[1], 0.0]
            )
            d.mocap_pos[self._basket_mocap] = self._goal
            self._cube_rest_z = CUBE_HALF
        else:
            d.qpos[self._cube_q : self._cube_q + 3] = cube
            d.qpos[self._cube_q + 3 : self._cube_q + 7] = [1.0, 0.0, 0.0, 0.0]
            for _ in range(20):
                mujoco.mj_step(m, d)
            self._cube_rest_z = float(d.qpos[self._cube_q + 2])
            self._goal = cube + np.array([0.0, 0.0, PICK_LIFT])
        d.time = 0.0
        mujoco.mj_forward(m, d)
        self._steps = 0
        self._unstable = False
        pos, vel = self.robot_state()
        reward, success = self._reward_success(self._cube_pos().copy())
        del reward
        return self._obs(), self._state_info(success, pos, vel)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One env step (``FRAME_SKIP / substeps`` simulator steps).

        Args:
            action: [7] in ``[-1, 1]`` (clipped): arm joint-target deltas / ``ARM_DELTA`` and the
                tied finger-target delta / ``FINGER_DELTA`` (each divided by ``substeps``).

        Returns:
            ``(obs [34], reward, terminated (always False), truncated, info)``; info has
            ``success``, ``robot_pos`` [7], ``robot_vel`` [7], ``sim_unstable``.

        Raises:
            ValueError: wrong shape or non-finite values in ``action``.
        """
        a = self._check_action(action)
        self._check_running(self._steps)
        a = np.clip(a, -1.0, 1.0)
        delta = np.concatenate([a[:6] * ARM_DELTA, np.full(3, a[6] * FINGER_DELTA)])
        if self.substeps > 1:
            delta = delta / self.substeps
        prev = self._target
        self._target = np.clip(self._target + delta, self._ctrl_lo, self._ctrl_hi)
        moved = self._target - prev
        self._target_rate = np.concatenate([moved[:6], [moved[6:].mean()]]) / self.control_dt
        d = self.data
        d.ctrl[self._act] = self._target
        warn_before = warning_count(d)
        last_obs = self._obs()
        mujoco.mj_step(self.model, d, nstep=self._frame_skip)
        self._steps += 1
        unstable = sim_unstable(d, warn_before)
        pos, vel = self.robot_state()
        if unstable:
            return self._unstable_step(last_obs, pos, vel)
        reward, success = self._reward_success(self._cube_pos().copy())
        truncated = self._steps >= self.horizon
        info = self._state_info(success, pos, vel)
        return self._obs(), float(reward), False, truncated, info

    def render(self) -> np.ndarray | None:
        """Upright RGB frame [H, W, 3] uint8 from ``self.camera`` (``render_mode="rgb_array"``)."""
        if not self._render_guard():
            return None

        def draw() -> np.ndarray:
            if self._renderer is None:
                self._renderer = mujoco.Renderer(self.model, height=self.height, width=self.width)
            self._renderer.update_scene(self.data, camera=self.camera)
            frame: np.ndarray = self._renderer.render().copy()
            return frame

        return self._render_frame(draw)

    def close(self) -> None:
        """Free the renderer."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
