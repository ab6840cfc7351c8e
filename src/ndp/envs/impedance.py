"""Variable impedance control at the simulator's rate (the VICES baseline's low-level controller).

VICES (Martin-Martin et al., IROS 2019): the policy chooses a target displacement and the
stiffness of an impedance controller; the controller computes joint torques at every simulator
step and holds the target between decisions. Two spaces, both with gravity, Coriolis and passive
(joint damping) compensation from MuJoCo's bias forces, ``c = qfrc_bias - qfrc_passive``:

- end-effector space (operational-space control, OSC), with ``J`` [6, n] the end-effector
  Jacobian (``mj_jacBody`` / ``mj_jacSite``) and ``M`` [n, n] the arm's block of the joint-space
  mass matrix (``mj_fullM``)::

      Lambda = (J M^-1 J^T)^-1                              operational-space inertia [6, 6]
      F      = Lambda (kp * e - kv * (J qdot))             e = [x_d - x, orientation error]
      tau    = J^T F + N^T M (kn (q_0 - q) - 2 sqrt(kn) qdot) + c
      N      = I - Jbar J,  Jbar = M^-1 J^T Lambda         null space of the task [n, n]

  the null-space posture term pulls towards the pose ``q_0`` at reset with ``kn`` =
  :data:`NULL_KP`; the orientation is held at the reset orientation with ``kp`` =
  :data:`ORI_KP` and damping ratio 1;
- joint space: ``tau = M (kp * (q_d - q) - kv * qdot) + c``.

``kv = 2 sqrt(kp) zeta`` (per axis). The policy's action (:class:`ImpedanceController`, a row
of the task table) maps ``[-1, 1]`` to a target displacement per axis (relative to the measured
position, as robosuite's delta controllers do), per-axis ``kp`` in :data:`KP_RANGE`, optionally
``zeta`` in :data:`ZETA_RANGE` (else :data:`DEFAULT_ZETA`), and the gripper command. The target and
the gains move linearly from their previous values to the new ones over the first
``ramp_ratio`` (20 %) of the policy period, then stay until the next decision.

Shapes: n arm joints, m = 6 (OSC: 3 position + 3 orientation) or n (joint space) controlled
axes of which the policy moves ``n_axes`` (OSC: the 3 position axes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal, NoReturn

import mujoco
import numpy as np

from ndp.checks import check_int, plain_numbers

KP_RANGE = (10.0, 300.0)
"""Stiffness range per axis (robosuite's variable-impedance range; 1/s^2, mass-normalised)."""
ZETA_RANGE = (0.0, 2.0)
"""Damping-ratio range per axis (robosuite's)."""
DEFAULT_ZETA = 1.0
"""Damping ratio when the policy does not choose it (critical damping)."""
RAMP_RATIO = 0.2
"""Fraction of the policy period over which target and gains are interpolated (robosuite)."""
NULL_KP = 10.0
"""Stiffness of the OSC null-space posture term (robosuite's default)."""
ORI_KP = 150.0
"""OSC stiffness of the held orientation (robosuite's default kp; damping ratio 1)."""

Space = Literal["ee", "joint"]


def damping_gain(kp: np.ndarray, zeta: np.ndarray) -> np.ndarray:
    """``kv = 2 sqrt(kp) zeta`` elementwise (arrays of one shape)."""
    gain: np.ndarray = 2.0 * np.sqrt(kp) * zeta
    return gain


def unit_to_range(a: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Map ``a`` in ``[-1, 1]`` linearly to ``[lo, hi]`` (no clipping)."""
    return lo + (np.asarray(a, dtype=np.float64) + 1.0) * (0.5 * (hi - lo))


def clip_gains(
    kp: np.ndarray,
    zeta: np.ndarray,
    kp_range: tuple[float, float] = KP_RANGE,
    zeta_range: tuple[float, float] = ZETA_RANGE,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Clip gains to their ranges; non-finite gains become the range's low end.

    Args:
        kp: stiffness per axis [n].
        zeta: damping ratio per axis [n].
        kp_range: (low, high) of kp.
        zeta_range: (low, high) of zeta.

    Returns:
        ``(kp [n], zeta [n], clipped)``: the clipped gains and how many entries were changed.
    """
    kp = np.asarray(kp, dtype=np.float64)
    zeta = np.asarray(zeta, dtype=np.float64)
    kp_c = np.clip(np.nan_to_num(kp, nan=kp_range[0]), *kp_range)
    z_c = np.clip(np.nan_to_num(zeta, nan=zeta_range[0]), *zeta_range)
    clipped = int(np.count_nonzero(kp_c != kp) + np.count_nonzero(z_c != zeta))
    return kp_c, z_c, clipped


def orientation_error(rot_d: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Rotation from ``rot`` to ``rot_d`` as a world-frame vector (small-angle form).

    Args:
        rot_d: desired rotation matrix [3, 3] (columns: body axes in the world frame).
        rot: current rotation matrix [3, 3].

    Returns:
        [3]: ``0.5 * sum_i rot[:, i] x rot_d[:, i]`` (exact direction, magnitude sin(angle)),
        written with one product ``P = rot @ rot_d.T`` (``np.cross`` costs ten times more).
    """
    p = rot @ rot_d.T
    return 0.5 * np.array([p[1, 2] - p[2, 1], p[2, 0] - p[0, 2], p[0, 1] - p[1, 0]])


def osc_torque(
    jac: np.ndarray,
    jm: np.ndarray,
    bias: np.ndarray,
    err: np.ndarray,
    vel: np.ndarray,
    kp: np.ndarray,
    kv: np.ndarray,
    posture: np.ndarray | None = None,
) -> np.ndarray:
    """Operational-space impedance torques (see the module docstring).

    Args:
        jac: end-effector Jacobian J [m, n] (rows: the controlled axes, columns: joints).
        jm: ``J M^-1`` [m, n] (MuJoCo: ``mj_solveM`` of the Jacobian's rows).
        bias: compensation torques [n] (``qfrc_bias - qfrc_passive``).
        err: task-space error [m] (target - current; orientation rows: an orientation error).
        vel: task-space velocity [m] (``jac @ qvel``).
        kp: stiffness per axis [m].
        kv: damping gain per axis [m].
        posture: null-space posture torque before projection ``M (kn (q_0 - q) - 2 sqrt(kn)
            qdot)`` [n] (MuJoCo: ``mj_mulM``); None: no null-space term.

    Returns:
        Joint torques [n].
    """
    lam_inv = jm @ jac.T
    try:
        lam = np.linalg.inv(lam_inv)
    except np.linalg.LinAlgError:
        lam = np.linalg.pinv(lam_inv)
    tau = jac.T @ (lam @ (kp * err - kv * vel))
    if posture is not None:
        # (I - J^T Jbar^T) posture with Jbar^T = Lambda J M^-1
        tau = tau + posture - jac.T @ (lam @ (jm @ posture))
    out: np.ndarray = tau + bias
    return out


def osc_torque_dense(
    jac: np.ndarray,
    mass: np.ndarray,
    bias: np.ndarray,
    err: np.ndarray,
    vel: np.ndarray,
    kp: np.ndarray,
    kv: np.ndarray,
    qvel: np.ndarray,
    null_err: np.ndarray | None = None,
    null_kp: float = NULL_KP,
) -> np.ndarray:
    """:func:`osc_torque` from a dense mass matrix ``mass`` [n, n] (tests, reference).

    ``null_err`` [n] = ``q_0 - q`` gives the posture term with stiffness ``null_kp`` and
    ``qvel`` [n] the joint velocities; the other arguments are :func:`osc_torque`'s.
    """
    jm = jac @ np.linalg.inv(mass)
    posture = None
    if null_err is not None:
        posture = mass @ (null_kp * null_err - 2.0 * math.sqrt(null_kp) * qvel)
    return osc_torque(jac, jm, bias, err, vel, kp, kv, posture)


def joint_impedance_torque(
    mass: np.ndarray,
    bias: np.ndarray,
    err: np.ndarray,
    qvel: np.ndarray,
    kp: np.ndarray,
    kv: np.ndarray,
) -> np.ndarray:
    """Joint-space impedance torques ``M (kp * err - kv * qvel) + bias``.

    Args:
        mass: arm mass matrix [n, n].
        bias: compensation torques [n].
        err: joint error ``q_d - q`` [n].
        qvel: joint velocities [n].
        kp: stiffness per joint [n].
        kv: damping gain per joint [n].

    Returns:
        Joint torques [n].
    """
    out: np.ndarray = mass @ (kp * err - kv * qvel) + bias
    return out


@dataclass(frozen=True)
class ImpedanceController:
    """The VICES action layout and controller constants of one task (data of the task table).

    Action (``[-1, 1]`` each, ``action_dim`` = 2 n_axes (+ n_axes with ``learn_damping``) + 1
    with a gripper): ``[delta (n_axes), kp (n_axes), zeta (n_axes, optional), gripper]``.
    """

    kind: ClassVar[str] = "impedance"
    space: Space
    """'ee' (operational-space control of the end-effector position, orientation held) or
    'joint' (joint-space impedance on every arm joint)."""
    max_delta: tuple[float, ...]
    """Largest target displacement per axis and decision (m or rad), relative to the measured
    position; length n_axes (3 for 'ee', the arm joints for 'joint')."""
    torque_limit: tuple[float, ...]
    """Torque limit per arm joint (N m), the torque actuators' control range."""
    learn_damping: bool = False
    """The policy also chooses the damping ratio per axis (else :attr:`zeta`)."""
    zeta: float = DEFAULT_ZETA
    """Damping ratio when not learned."""
    kp_range: tuple[float, float] = KP_RANGE
    """Stiffness range (the action's kp part maps [-1, 1] onto it)."""
    zeta_range: tuple[float, float] = ZETA_RANGE
    """Damping-ratio range (the action's zeta part maps [-1, 1] onto it)."""
    gripper: bool = True
    """The last action entry is the task's gripper command (handled by the env as before)."""
    ramp_ratio: float = RAMP_RATIO
    """Fraction of the policy period over which target and gains are interpolated."""
    period: int = 1
    """Env steps per policy decision (the policy clock: ``period * control_dt`` s). With
    ``period`` > 1 (VICES low-frequency) the action of the first env step of each period sets
    target, gains and gripper for the whole period; the actions of its other steps are ignored."""
    null_kp: float = NULL_KP
    """OSC null-space posture stiffness."""
    ori_kp: float = ORI_KP
    """OSC stiffness of the held orientation."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        if self.space not in ("ee", "joint"):
            raise ValueError(f"space: expected 'ee' or 'joint', got {self.space!r}")
        if not self.max_delta or any(not d > 0 for d in self.max_delta):
            raise ValueError(f"max_delta: expected positive bounds, got {self.max_delta!r}")
        if not self.torque_limit or any(not t > 0 for t in self.torque_limit):
            raise ValueError(f"torque_limit: expected positive limits, got {self.torque_limit!r}")
        lo, hi = self.kp_range
        if not 0 < lo <= hi:
            raise ValueError(f"kp_range: expected 0 < low <= high, got {self.kp_range!r}")
        lo, hi = self.zeta_range
        if not 0 <= lo <= hi:
            raise ValueError(f"zeta_range: expected 0 <= low <= high, got {self.zeta_range!r}")
        check_int("period", self.period, 1)
        if not 0 < self.ramp_ratio <= 1:
            raise ValueError(f"ramp_ratio: expected a number in (0, 1], got {self.ramp_ratio!r}")

    @property
    def n_axes(self) -> int:
        """Axes the policy moves (3 in end-effector space, the arm joints in joint space)."""
        return len(self.max_delta)

    @property
    def action_dim(self) -> int:
        """A: delta, kp, optional zeta, optional gripper."""
        n = self.n_axes
        return n * (3 if self.learn_damping else 2) + int(self.gripper)

    def decode(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Split and scale one action [A] (already clipped to ``[-1, 1]``).

        Returns:
            ``(delta [n_axes], kp [n_axes], zeta [n_axes], gripper)``; gripper 0.0 without one.
        """
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (self.action_dim,):
            raise ValueError(f"action: expected shape ({self.action_dim},), got {a.shape}")
        n = self.n_axes
        delta = a[:n] * np.asarray(self.max_delta)
        kp = unit_to_range(a[n : 2 * n], *self.kp_range)
        if self.learn_damping:
            zeta = unit_to_range(a[2 * n : 3 * n], *self.zeta_range)
        else:
            zeta = np.full(n, float(self.zeta))
        grip = float(a[-1]) if self.gripper else 0.0
        return delta, kp, zeta, grip

    def __call__(self, traj: object, robot_pos: object = None, clip: bool = True) -> NoReturn:
        """Trajectories -> actions is not defined for impedance control (no NDP head here)."""
        raise ValueError(
            "controller: the impedance-controlled (torque) tasks take VICES actions; an NDP "
            "trajectory head needs a task with a DeltaController"
        )


def _as_slice(idx: np.ndarray) -> slice | np.ndarray:
    """``idx`` as a slice if it is a run of consecutive integers, else unchanged."""
    if len(idx) and np.array_equal(idx, np.arange(idx[0], idx[0] + len(idx))):
        return slice(int(idx[0]), int(idx[0]) + len(idx))
    return idx


class ImpedanceArm:
    """Run-time state of an :class:`ImpedanceController` on one MuJoCo model.

    Holds the target and gains between decisions, interpolates them over the first
    ``ramp_ratio`` of each policy period, and computes the torques of one simulator step from
    ``data`` after ``mj_step1`` (positions, velocities, mass matrix and bias forces of the current
    state; the caller writes the torques to ``data.ctrl`` and calls ``mj_step2``).

    Args:
        model: the compiled model.
        ctrl: the task's controller row.
        joints: names of the n arm joints (hinges), in the order of ``torque_limit``.
        actuators: names of the n torque actuators (one per arm joint, same order).
        ee: end-effector ``("body" | "site", name)`` (OSC only).
        target_low: lower bound [n_axes] of the target (m or rad), or None.
        target_high: upper bound [n_axes] of the target, or None.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        ctrl: ImpedanceController,
        joints: tuple[str, ...],
        actuators: tuple[str, ...],
        ee: tuple[str, str] | None = None,
        target_low: np.ndarray | None = None,
        target_high: np.ndarray | None = None,
    ) -> None:
        if len(joints) != len(ctrl.torque_limit) or len(actuators) != len(joints):
            raise ValueError(
                f"joints: expected {len(ctrl.torque_limit)} joints and actuators, got "
                f"{len(joints)} and {len(actuators)}"
            )
        if ctrl.space == "joint" and ctrl.n_axes != len(joints):
            raise ValueError(f"max_delta: expected {len(joints)} joint bounds, got {ctrl.n_axes}")
        if ctrl.space == "ee" and (ctrl.n_axes != 3 or ee is None):
            raise ValueError("ee: end-effector control needs 3 position bounds and an ee name")
        self.model = model
        self.ctrl = ctrl
        self.qadr = np.array([model.joint(j).qposadr[0] for j in joints])
        self.dofs = np.array([model.joint(j).dofadr[0] for j in joints])
        self.act = np.array([model.actuator(a).id for a in actuators])
        # the same indices as slices where contiguous (views: no copy at every simulator step)
        self._q, self._v, self._a = (_as_slice(i) for i in (self.qadr, self.dofs, self.act))
        self.limit = np.asarray(ctrl.torque_limit, dtype=np.float64)
        self.ee_kind, self.ee_id = "body", -1
        if ee is not None:
            kind, name = ee
            if kind not in ("body", "site"):
                raise ValueError(f"ee: expected ('body' | 'site', name), got {ee!r}")
            self.ee_kind = kind
            self.ee_id = model.body(name).id if kind == "body" else model.site(name).id
        self.low = None if target_low is None else np.asarray(target_low, dtype=np.float64)
        self.high = None if target_high is None else np.asarray(target_high, dtype=np.float64)
        nv = model.nv
        n = ctrl.n_axes
        mid_kp = 0.5 * (ctrl.kp_range[0] + ctrl.kp_range[1])
        self.goal = np.zeros(n)
        self.goal_from = np.zeros(n)
        self.kp = np.full(n, mid_kp)
        self.kp_from = self.kp.copy()
        self.zeta = np.full(n, float(ctrl.zeta))
        self.zeta_from = self.zeta.copy()
        self.ramp_steps = 1
        self.step_in_period = 0
        self.rot_goal = np.eye(3)
        self.posture = np.zeros(len(joints))
        self.ori_kp = np.full(3, float(ctrl.ori_kp))
        self.ori_kv = damping_gain(self.ori_kp, np.ones(3))
        self._jfull = np.zeros((6, nv))
        self._jm = np.zeros((6, nv))
        self._vfull = np.zeros(nv)
        self._mv = np.zeros(nv)
        self._err = np.zeros(6)
        self._gains = np.concatenate([np.zeros(3), self.ori_kp])
        self._damp = np.concatenate([np.zeros(3), self.ori_kv])

    # ------------------------------------------------------------------ measurements
    def position(self, data: mujoco.MjData) -> np.ndarray:
        """Measured position of the controlled axes [n_axes]: ee xyz (m) or joint angles."""
        if self.ctrl.space == "joint":
            pos: np.ndarray = data.qpos[self.qadr].copy()
            return pos
        if self.ee_kind == "body":
            pos = data.xpos[self.ee_id].copy()
            return pos
        pos = data.site_xpos[self.ee_id].copy()
        return pos

    def rotation(self, data: mujoco.MjData) -> np.ndarray:
        """End-effector rotation matrix [3, 3]."""
        x = data.xmat if self.ee_kind == "body" else data.site_xmat
        rot: np.ndarray = x[self.ee_id].reshape(3, 3).copy()
        return rot

    # ------------------------------------------------------------------ commands
    def reset(self, data: mujoco.MjData) -> None:
        """Hold the current position and orientation; the posture is the current pose."""
        self.goal = self.position(data)
        self.goal_from = self.goal.copy()
        mid_kp = 0.5 * (self.ctrl.kp_range[0] + self.ctrl.kp_range[1])
        self.kp = np.full(self.ctrl.n_axes, mid_kp)
        self.kp_from = self.kp.copy()
        self.zeta = np.full(self.ctrl.n_axes, float(self.ctrl.zeta))
        self.zeta_from = self.zeta.copy()
        self.posture = data.qpos[self.qadr].copy()
        if self.ctrl.space == "ee":
            self.rot_goal = self.rotation(data)
        self.ramp_steps = 1
        self.step_in_period = 1

    def set_goal(
        self,
        data: mujoco.MjData,
        delta: np.ndarray,
        kp: np.ndarray,
        zeta: np.ndarray,
        period_steps: int,
    ) -> int:
        """Start a new policy period: target = measured position + ``delta`` (clipped to the
        target bounds), gains clipped to their ranges, both ramped from the values in force now.

        Args:
            data: the simulator state at the decision.
            delta: displacement [n_axes] (m or rad).
            kp: stiffness [n_axes].
            zeta: damping ratio [n_axes].
            period_steps: simulator steps until the next decision.

        Returns:
            How many gain entries were clipped.
        """
        goal_now, kp_now, zeta_now = self._interpolated()
        kp, zeta, clipped = clip_gains(kp, zeta, self.ctrl.kp_range, self.ctrl.zeta_range)
        goal = self.position(data) + np.asarray(delta, dtype=np.float64)
        if self.low is not None and self.high is not None:
            goal = np.clip(goal, self.low, self.high)
        self.goal_from, self.kp_from, self.zeta_from = goal_now, kp_now, zeta_now
        self.goal, self.kp, self.zeta = goal, kp, zeta
        self.ramp_steps = max(1, math.ceil(self.ctrl.ramp_ratio * int(period_steps)))
        self.step_in_period = 0
        return clipped

    def _interpolated(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(target, kp, zeta) in force at the current step of the period."""
        frac = min(1.0, self.step_in_period / self.ramp_steps)
        if frac >= 1.0:
            return self.goal, self.kp, self.zeta
        return (
            self.goal_from + frac * (self.goal - self.goal_from),
            self.kp_from + frac * (self.kp - self.kp_from),
            self.zeta_from + frac * (self.zeta - self.zeta_from),
        )

    # ------------------------------------------------------------------ torques
    def torque(self, data: mujoco.MjData) -> np.ndarray:
        """Unclipped torques [n] for the current state (``data`` after ``mj_step1``: the mass
        matrix's factorisation, Jacobian and bias forces of this state); advances the
        interpolation by one simulator step.

        The whole model's mass matrix is used through MuJoCo (``mj_mulM``, ``mj_solveM``: the
        arm's dynamics including the gripper it carries); the torques are its arm rows."""
        self.step_in_period += 1
        goal, kp, zeta = self._interpolated()
        m, d, dofs, qadr = self.model, data, self._v, self._q
        qvel = d.qvel[dofs]
        kv = 2.0 * np.sqrt(kp) * zeta
        vfull, mv = self._vfull, self._mv
        if self.ctrl.space == "joint":
            vfull[dofs] = kp * (goal - d.qpos[qadr]) - kv * qvel
            mujoco.mj_mulM(m, d, mv, vfull)
            joint_tau: np.ndarray = mv[dofs] + d.qfrc_bias[dofs] - d.qfrc_passive[dofs]
            return joint_tau
        jac, jm, err, gains, damp = self._jfull, self._jm, self._err, self._gains, self._damp
        if self.ee_kind == "body":
            mujoco.mj_jacBody(m, d, jac[:3], jac[3:], self.ee_id)
            x, rot = d.xpos[self.ee_id], d.xmat[self.ee_id]
        else:
            mujoco.mj_jacSite(m, d, jac[:3], jac[3:], self.ee_id)
            x, rot = d.site_xpos[self.ee_id], d.site_xmat[self.ee_id]
        mujoco.mj_solveM(m, d, jm, jac)
        err[:3] = goal - x
        err[3:] = orientation_error(self.rot_goal, rot.reshape(3, 3))
        gains[:3] = kp
        damp[:3] = kv
        kn = self.ctrl.null_kp
        vfull[dofs] = kn * (self.posture - d.qpos[qadr]) - 2.0 * math.sqrt(kn) * qvel
        mujoco.mj_mulM(m, d, mv, vfull)
        tau = osc_torque(jac, jm, d.qfrc_bias - d.qfrc_passive, err, jac @ d.qvel, gains, damp, mv)
        return tau[dofs]

    def step(self, data: mujoco.MjData, nstep: int) -> tuple[int, bool]:
        """Run ``nstep`` simulator steps with fresh torques at each (``mj_step1``, torques to the
        actuators, ``mj_step2``); other controls in ``data.ctrl`` are left as set.

        Returns:
            ``(saturated, finite)``: torque entries clipped at their limits over the steps, and
            False if a torque was not finite (that step and the rest are then not run).
        """
        m, act, limit = self.model, self._a, self.limit
        saturated = 0
        for _ in range(int(nstep)):
            mujoco.mj_step1(m, data)
            tau = self.torque(data)
            if not math.isfinite(float(tau.sum())):  # NaN / inf anywhere
                data.ctrl[act] = 0.0
                return saturated, False
            over = np.abs(tau) > limit
            if over.any():
                saturated += int(np.count_nonzero(over))
                tau = np.minimum(np.maximum(tau, -limit), limit)
            data.ctrl[act] = tau
            mujoco.mj_step2(m, data)
        return saturated, True
