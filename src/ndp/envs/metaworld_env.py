"""Meta-World v3 tasks (metaworld 3.1.1) behind one adapter with seeded random goals.

Every reset samples a fresh object + goal configuration from the task's own distribution
(``_random_reset_space``, the same distribution ``metaworld.MT1`` draws its 50 goals from),
with the env's own rejection loops, using a generator seeded by ``reset(seed=...)`` (or by
``make_env(..., seed=...)`` on the first reset). The goal is observed (``_partially_observable``
off, as in Meta-World's MT benchmarks). Same seed, same sequence of tasks for every method.

Clocks: MuJoCo timestep 0.0025 s, ``frame_skip`` 5, so one env step = 0.0125 s (80 Hz).
``substeps=m`` (m in 1, 5; ``ndp rl eval --exec-k``) makes one env step ``5 / m`` simulator
steps (0.0125 / m s) in which an xyz action of 1 moves the hand target ``0.01 / m`` m; the
gripper command stays absolute. The observation keeps its meaning: its previous-frame block
[18:36] is the frame 0.0125 s (m env steps) earlier, as at ``substeps=1``.

Observation (39, float64): hand xyz [0:3], gripper opening [3], object block [4:18] (positions
and quaternions of up to two objects), the previous frame's 18 values [18:36], goal xyz [36:39].
"""

from __future__ import annotations

from collections import deque
from typing import Any

import mujoco
import numpy as np
from gymnasium.utils.ezpickle import EzPickle

from ndp.checks import check_choice
from ndp.envs.base import (
    NDPEnv,
    check_render_size,
    check_substeps,
    sim_unstable,
    warning_count,
)

REWARD_VERSIONS = ("v1", "v2")
"""Meta-World's reward functions: ``"v2"`` (metaworld's default, the one every study uses by
default) and ``"v1"`` (the pre-v2 shaped rewards the 2021 release trained on; metaworld 3.1.1
keeps both in each task's ``compute_reward``)."""

METAWORLD_POS_SCALE = 0.01
"""Metres the hand target (mocap) moves per env step for an xyz action of 1 (metaworld default)."""
ROBOT_JOINTS = frozenset([f"right_j{i}" for i in range(7)] + ["r_close", "l_close"])
"""Sawyer joints; every other joint of a Meta-World model is world (objects, doors, ...)."""
WORLD_OBS = np.r_[4:18, 22:36, 36:39]
"""Observation indices that describe the world (objects of both frames and the goal)."""
_REWARD_FROM_OBS_BOTH = (
    "basketball-v3",
    "bin-picking-v3",
    "box-close-v3",
    "button-press-topdown-v3",
    "button-press-topdown-wall-v3",
    "button-press-v3",
    "button-press-wall-v3",
    "coffee-button-v3",
    "coffee-pull-v3",
    "coffee-push-v3",
    "door-close-v3",
    "door-lock-v3",
    "door-unlock-v3",
    "drawer-close-v3",
    "drawer-open-v3",
    "faucet-close-v3",
    "faucet-open-v3",
    "hand-insert-v3",
    "handle-pull-side-v3",
    "handle-pull-v3",
    "lever-pull-v3",
    "peg-unplug-side-v3",
    "pick-out-of-hole-v3",
    "pick-place-v3",
    "pick-place-wall-v3",
    "plate-slide-back-side-v3",
    "plate-slide-back-v3",
    "plate-slide-side-v3",
    "plate-slide-v3",
    "push-back-v3",
    "push-v3",
    "push-wall-v3",
    "reach-v3",
    "reach-wall-v3",
    "shelf-place-v3",
    "soccer-v3",
    "stick-push-v3",
    "sweep-into-v3",
    "sweep-v3",
)
"""The Meta-World tasks whose v2 and v1 rewards both read the world only through the
observation (the measurements below, :data:`REWARD_FROM_OBS` and :data:`REWARD_FROM_OBS_V1`,
agree on these 39)."""
REWARD_FROM_OBS: frozenset[str] = frozenset((*_REWARD_FROM_OBS_BOTH, "hammer-v3"))
"""Meta-World tasks whose v2 reward reads the world only through the observation: their
stale-world reward needs no kinematics pass (``stale_reward``). Established by measurement, not
by reading code: on recorded noisy-expert states the observation-only and the full form agree
exactly for these 40 tasks and differ for the other 10 (tests/envs/test_env_metaworld.py checks
both ways on every task; the 10 read object or joint positions from the simulator)."""
REWARD_FROM_OBS_V1: frozenset[str] = frozenset(
    (
        *_REWARD_FROM_OBS_BOTH,
        "dial-turn-v3",
        "disassemble-v3",
        "door-open-v3",
        "handle-press-side-v3",
        "handle-press-v3",
        "stick-pull-v3",
        "window-close-v3",
        "window-open-v3",
    )
)
"""The same measurement for the v1 rewards (``reward_version="v1"``): 47 of the 49 tasks whose
v1 reward runs. v1 rewards read site and body positions besides the observation, but on these
tasks only robot sites (fingers, end effector: live in both forms) and sites fixed at reset
(the goal); hammer-v3 and peg-insert-side-v3 read world bodies (tests/envs/test_env_metaworld.py
checks both ways on every task)."""
V1_REWARD_BROKEN: frozenset[str] = frozenset({"assembly-v3"})
"""Tasks whose v1 reward does not run in metaworld 3.1.1 (assembly-v3: ``compute_reward``
reads ``heightTarget``, which nothing sets): ``reward_version="v1"`` is refused for them at
construction (tested)."""


def reward_from_obs(task: str, reward_version: str = "v2") -> bool:
    """Whether ``task``'s reward of ``reward_version`` reads the world only through the
    observation (measured: :data:`REWARD_FROM_OBS`, :data:`REWARD_FROM_OBS_V1`)."""
    check_reward_version(reward_version)
    return task in (REWARD_FROM_OBS if reward_version == "v2" else REWARD_FROM_OBS_V1)


def check_reward_version(value: object) -> str:
    """``reward_version`` checked (one of :data:`REWARD_VERSIONS`).

    Raises:
        ValueError: anything else (named in the message).
    """
    return check_choice("reward_version", value, REWARD_VERSIONS)


def metaworld_env_names() -> list[str]:
    """The 50 Meta-World v3 task names, in metaworld's order."""
    from metaworld.env_dict import ALL_V3_ENVIRONMENTS

    return list(ALL_V3_ENVIRONMENTS)


def _world_dofs(m: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """qpos and qvel indices of the world's (non-robot) joints."""
    world_q: list[int] = []
    world_v: list[int] = []
    for j in range(m.njnt):
        if m.joint(j).name in ROBOT_JOINTS:
            continue
        nq = {0: 7, 1: 4, 2: 1, 3: 1}[int(m.jnt_type[j])]
        nv = {0: 6, 1: 3, 2: 1, 3: 1}[int(m.jnt_type[j])]
        world_q += range(m.jnt_qposadr[j], m.jnt_qposadr[j] + nq)
        world_v += range(m.jnt_dofadr[j], m.jnt_dofadr[j] + nv)
    return np.array(world_q, dtype=int), np.array(world_v, dtype=int)


class MetaWorldEnv(NDPEnv, EzPickle):
    """One Meta-World v3 task with random goals on every reset and a configurable horizon.

    Options of the 2021 release's conditions (defaults: the fair ones): ``reward_version="v1"``
    trains on the v1 shaped reward (the reward only: ``success`` and metaworld's other info
    keys stay the v2 evaluation, so success means the same under both rewards), and
    ``fixed_goal=SEED`` gives every episode the same object + goal configuration.

    Actions [4] in ``[-1, 1]`` (clipped): hand-target displacement / ``METAWORLD_POS_SCALE`` for
    xyz and the absolute gripper command (-1 open, +1 closed). The DMP-driven robot state (D = 4)
    is the hand position (m, body ``hand``) with its linear velocity (m/s), and the last gripper
    command (unitless) with its rate of change (1/s).
    """

    # declared as gymnasium.Env declares it (a ClassVar would clash with its declaration)
    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 80}  # noqa: RUF012

    def __init__(
        self,
        task: str = "reach-v3",
        horizon: int = 150,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 480,
        camera_name: str = "corner",
        substeps: int = 1,
        reward_version: str = "v2",
        fixed_goal: int | str | None = None,
    ) -> None:
        """Create the env.

        Args:
            task: A Meta-World v3 name, e.g. ``"push-v3"``.
            horizon: Env steps per episode (the paper uses 150; Meta-World's own is 500).
            render_mode: ``None`` or ``"rgb_array"``.
            width: Rendered frame width (px).
            height: Rendered frame height (px).
            camera_name: A Meta-World camera (``corner``, ``corner2``, ``corner3``,
                ``topview``, ``behindGripper``, ``gripperPOV``).
            substeps: m, a divisor of metaworld's frame skip 5: one env step is ``5 / m``
                simulator steps and an xyz action moves the hand target ``0.01 / m`` m per unit
                (the same speed per second; see the module docstring). ``horizon`` counts these
                shorter steps.
            reward_version: ``"v2"`` (metaworld's default) or ``"v1"`` (the release's shaped
                rewards; success stays the v2 evaluation).
            fixed_goal: None (a fresh seeded configuration every reset) or the seed of the one
                configuration every reset uses.
        """
        from metaworld.env_dict import ALL_V3_ENVIRONMENTS

        EzPickle.__init__(
            self, task, horizon, render_mode, width, height, camera_name, substeps,
            reward_version, fixed_goal,
        )  # fmt: skip
        if task not in ALL_V3_ENVIRONMENTS:
            raise ValueError(f"task: expected a Meta-World v3 name, got {task!r}")
        self.reward_version = check_reward_version(reward_version)
        if self.reward_version == "v1" and task in V1_REWARD_BROKEN:
            raise ValueError(
                f"reward_version: {task}'s v1 reward does not run in metaworld 3.1.1 (it reads "
                "an attribute nothing sets); use 'v2'"
            )
        self._setup(horizon, render_mode, action_dim=self._action_dim())
        self._set_fixed_goal(fixed_goal, task)
        self.task = task
        width, height = check_render_size("width", width), check_render_size("height", height)
        self._make_task_env(task, render_mode, camera_name, width, height)
        env = self.mw
        self.model: mujoco.MjModel = env.model
        self.data: mujoco.MjData = env.data
        self.observation_space = env.sawyer_observation_space
        m = self.model
        self._world_q, self._world_v = _world_dofs(m)
        self._hand = m.body("hand").id
        self._gripper = -1.0
        self._gripper_rate = 0.0
        self._obs: np.ndarray | None = None
        self._vel6 = np.zeros(6)
        self._mocap_vel = np.zeros(3)
        self.substeps = check_substeps(substeps, int(env.frame_skip))
        self.control_dt = float(m.opt.timestep * env.frame_skip) / self.substeps
        # the current-frame blocks (obs[:18]) of the last `substeps` env steps (substeps > 1)
        self._frames: deque[np.ndarray] = deque(maxlen=self.substeps)

    def _make_task_env(
        self, task: str, render_mode: str | None, camera_name: str, width: int, height: int
    ) -> None:
        """Create ``self.mw``, the metaworld task env, set up as metaworld's own benchmark
        construction does it but with the random reset vector drawn fresh from our seeded
        generator at every reset."""
        from metaworld.env_dict import ALL_V3_ENVIRONMENTS

        env = self._task_class(ALL_V3_ENVIRONMENTS[task])(
            render_mode=render_mode, camera_name=camera_name, width=width, height=height
        )
        env._set_task_called = True
        env._freeze_rand_vec = False
        env.seeded_rand_vec = True
        env._partially_observable = False
        del env.sawyer_observation_space  # cached property: recompute with the goal visible
        env.max_path_length = self.horizon
        self.mw = env

    def release_config(self, task: str) -> np.ndarray | None:
        """The release's reset vector of ``task`` (``ndp.envs.release.RELEASE_CONFIGS``)."""
        from ndp.envs.release import release_config

        return release_config(task)

    def _action_dim(self) -> int:
        """Size of one action (4; the torque-actuated variant overrides it)."""
        return 4

    def _task_class(self, cls: type) -> type:
        """The metaworld task class to instantiate (the torque-actuated variant overrides it)."""
        return cls

    # ------------------------------------------------------------------ state access
    def robot_state(self) -> tuple[np.ndarray, np.ndarray]:
        """DMP-driven robot state now.

        Returns:
            ``(pos [4], vel [4])``: hand xyz (m) and last gripper command; hand linear velocity
            (m/s, world frame) and the gripper command's rate (1/s).
        """
        mujoco.mj_objectVelocity(
            self.model, self.data, mujoco.mjtObj.mjOBJ_BODY, self._hand, self._vel6, 0
        )
        pos = np.append(self.data.xpos[self._hand], self._gripper)
        vel = np.append(self._vel6[3:], self._gripper_rate)
        return pos, vel

    def command_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Commanded state now: what the xyz actions move (the mocap target leads the hand by up
        to 3 cm at full speed and the hand coasts after it stops).

        Returns:
            ``(pos [4], vel [4])``: mocap target xyz (m) and the last gripper command; the
            target's velocity over the last env step (m/s) and the command's rate (1/s).
        """
        pos = np.append(self.data.mocap_pos[0], self._gripper)
        vel = np.append(self._mocap_vel, self._gripper_rate)
        return pos, vel

    def world_snapshot(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copy of the world state: world qpos, world qvel and the last observation.

        Returns:
            ``(qpos_world, qvel_world, obs [39])``.
        """
        assert self._obs is not None
        return (
            self.data.qpos[self._world_q].copy(),
            self.data.qvel[self._world_v].copy(),
            self._obs.copy(),
        )

    def stale_reward(
        self,
        snapshot: tuple[np.ndarray, np.ndarray, np.ndarray],
        action: np.ndarray,
        from_obs: bool | None = None,
    ) -> float:
        """Task reward for the live robot and the world of ``snapshot``.

        The world joints are set to the snapshot, positions are recomputed (``mj_kinematics``,
        ``mj_comPos``), the task's own ``compute_reward`` runs on the current observation whose
        world part (``WORLD_OBS``) is the snapshot's, and the live state is restored and
        recomputed. ``compute_reward`` of the v3 tasks has no side effects on the env once the
        episode's first step has run (checked for all 50 tasks in tests/envs; see docs/envs.md).

        Tasks whose reward reads the world only through the observation (``reward_from_obs`` of
        the task table, :data:`REWARD_FROM_OBS`) skip the two kinematics passes: the reward of
        the observation with the snapshot's world part is the same number (tested on recorded
        states for every task in tests/envs).

        Args:
            snapshot: From :meth:`world_snapshot`.
            action: The sub-action [4] just executed (some rewards use the gripper command).
            from_obs: Force the observation-only form (True) or the full one (False); None:
                the task's flag.

        Returns:
            The stale-world reward.
        """
        assert self._obs is not None
        qw, vw, obs_w = snapshot
        if from_obs is None:
            from_obs = reward_from_obs(self.task, self.reward_version)
        if from_obs:
            obs = self._obs.copy()
            obs[WORLD_OBS] = obs_w[WORLD_OBS]
            return self.task_reward(action, obs)
        m, d = self.model, self.data
        live_q = d.qpos[self._world_q].copy()
        live_v = d.qvel[self._world_v].copy()
        obs = self._obs.copy()
        obs[WORLD_OBS] = obs_w[WORLD_OBS]
        d.qpos[self._world_q] = qw
        d.qvel[self._world_v] = vw
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        try:
            reward = self.task_reward(action, obs)
        finally:
            d.qpos[self._world_q] = live_q
            d.qvel[self._world_v] = live_v
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
        return reward

    def task_reward(self, action: np.ndarray, obs: np.ndarray) -> float:
        """The task's reward of ``reward_version`` for ``action`` [4] and ``obs`` [39] in the
        simulator's current state (metaworld's ``compute_reward``; the v1 branch runs with the
        task's version switched for the call, so metaworld's own step keeps the v2 evaluation).
        """
        mw = self.mw
        a = np.asarray(action, dtype=np.float64)
        if self.reward_version == "v2":
            return float(mw.compute_reward(a, obs)[0])
        mw.reward_function_version = "v1"
        try:
            return float(mw.compute_reward(a, obs)[0])
        finally:
            mw.reward_function_version = "v2"

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset with a new random object + goal configuration (seeded)."""
        self._reset_rng(seed)
        # metaworld draws its reset vector (objects, goal) from this, and nothing else
        self.mw.np_random = self._task_rng()
        release = self.release_config(self.task) if self.fixed_goal == "release" else None
        if release is not None:  # the release's one configuration instead of a draw
            self.mw._last_rand_vec = release
        self.mw._freeze_rand_vec = release is not None
        obs, _ = self.mw.reset()
        self._gripper = -1.0  # metaworld's hand reset leaves the gripper open (command -1)
        self._gripper_rate = 0.0
        self._mocap_vel = np.zeros(3)
        self._unstable = False
        self._obs = np.asarray(obs, dtype=np.float64)
        self._frames.clear()
        self._frames.extend([self._obs[:18].copy()] * self.substeps)
        pos, vel = self.robot_state()
        return self._obs.copy(), self._state_info(False, pos, vel)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One env step.

        Args:
            action: [4]; clipped to ``[-1, 1]``.

        Returns:
            ``(obs [39], reward, terminated (always False), truncated, info)``; info has
            metaworld's keys plus ``success`` (bool), ``robot_pos`` [4], ``robot_vel`` [4],
            ``sim_unstable``.

        Raises:
            ValueError: wrong shape or non-finite values in ``action``.
        """
        a = self._check_action(action)
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        self._check_running(self.mw.curr_path_length)
        a = np.clip(a, -1.0, 1.0).astype(np.float32)
        warn_before = warning_count(self.data)
        prev_frame = self._frames[0]  # substeps > 1: the frame `substeps` env steps back
        mocap_before = self.data.mocap_pos[0].copy()
        obs, reward, _, truncated, mw_info = self._mw_step(a)
        self._mocap_vel = (self.data.mocap_pos[0] - mocap_before) / self.control_dt
        self._gripper_rate = (float(a[3]) - self._gripper) / self.control_dt
        self._gripper = float(a[3])
        unstable = sim_unstable(self.data, warn_before)
        pos, vel = self.robot_state()
        info: dict[str, Any] = {k: float(v) for k, v in mw_info.items()}
        if unstable:
            return self._unstable_step(self._obs.copy(), pos, vel, info)
        if self.reward_version != "v2":  # on metaworld's observation, as its own reward
            reward = self.task_reward(a, np.asarray(obs, dtype=np.float64))
        self._obs = np.asarray(obs, dtype=np.float64)
        if self.substeps > 1:  # previous frame: `substeps` env steps (0.0125 s) ago
            self._frames.append(self._obs[:18].copy())
            self._obs[18:36] = prev_frame
        info.update(self._state_info(bool(mw_info["success"] > 0.5), pos, vel))
        return self._obs.copy(), float(reward), False, bool(truncated), info

    def _mw_step(self, a: np.ndarray) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """metaworld's step; with ``substeps`` m > 1 it runs ``frame_skip / m`` simulator steps
        and moves the hand target ``action_scale / m`` per unit xyz action (both restored after,
        so that resets, which step the simulator ``frame_skip`` times, are unchanged). metaworld
        computes the reward on its own observation, whose previous frame is one env step back."""
        mw = self.mw
        out: tuple[Any, Any, bool, bool, dict[str, Any]]
        if self.substeps == 1:
            out = mw.step(a)
            return out
        skip, scale = mw.frame_skip, mw.action_scale
        mw.frame_skip, mw.action_scale = skip // self.substeps, scale / self.substeps
        try:
            out = mw.step(a)
            return out
        finally:
            mw.frame_skip, mw.action_scale = skip, scale

    def render(self) -> np.ndarray | None:
        """Upright RGB frame [H, W, 3] uint8 (``render_mode="rgb_array"``)."""
        if not self._render_guard():
            return None
        frame = self._render_frame(self.mw.render)
        # metaworld's cameras come out of MuJoCo's renderer bottom row first: flip to upright.
        return None if frame is None else np.ascontiguousarray(frame[::-1])

    def close(self) -> None:
        """Close the Meta-World env (and its renderer)."""
        self.mw.close()
