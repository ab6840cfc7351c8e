"""Chunked execution: one decision = k robot sub-steps, with the stale-world reward rule.

The three clocks (docs/envs.md): simulator step (``spec.sim_dt``), env step = one sub-step
(``spec.control_dt``), decision = ``k`` sub-steps. This wrapper owns the last one; it never infers
anything from ``step % k``.

Stale world rule (ndp-method.md section 3): the world (objects, goal) is observed once per
decision, right after its first sub-step. Sub-step 0's reward is the env's own reward; the reward
of sub-steps 1..k-1 is recomputed by the env's ``stale_reward(snapshot, action)`` from the live
robot state and the world snapshot taken after sub-step 0. Success is always the env's live
success (it is an evaluation metric, not a training signal). ``k = 1`` is plain per-step
execution; ``stale_world=False`` uses the env's live reward at every sub-step.

Envs used with ``stale_world=True`` must provide, on ``env.unwrapped``:
``robot_state() -> (pos [D], vel [D])``, ``world_snapshot() -> object`` and
``stale_reward(snapshot, action) -> float`` (pure: no side effects).
"""

from __future__ import annotations

from typing import Any, Protocol, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ndp.checks import check_flag
from ndp.chunk_info import ChunkInfo
from ndp.envs.base import CTRL_INFO
from ndp.envs.rewards import check_stale_world, reward_of


class _RobotEnv(Protocol):
    """What the wrapper calls on ``env.unwrapped`` (the module docstring; the last two only
    with ``stale_world``)."""

    def robot_state(self) -> tuple[np.ndarray, np.ndarray]: ...

    def world_snapshot(self) -> object: ...

    def stale_reward(self, snapshot: object, action: np.ndarray) -> float: ...


EXECUTIONS = ("all", "first-held")
"""How :class:`ChunkedEnv` runs a decision's k sub-actions: each in turn ('all'), or only the
first, held for the k sub-steps ('first-held': the 2021 release's defect, an early return and
an indentation slip, reproduced as a labelled condition)."""


class ChunkedEnv(gym.Wrapper):
    """Execute k sub-actions per step; report per-sub-step rewards, masks and robot states.

    ``step(actions [k, A])`` returns ``(obs, reward, terminated, truncated, info)`` where
    ``reward`` is the sum of the executed sub-steps' rewards and ``info`` holds (fixed shapes):

    - ``sub_rewards`` float64 [k]: reward of each sub-step (stale rule applied), 0 where padded.
    - ``sub_rewards_live`` float64 [k]: the env's own (live-world) reward of each sub-step.
    - ``sub_mask`` float64 [k]: 1 for executed sub-steps, 0 after an early stop.
    - ``sub_success`` float64 [k]: live success at each executed sub-step.
    - ``success`` bool: success at the last executed sub-step.
    - ``success_decision`` bool: success at any sub-step of THIS decision.
    - ``success_any`` bool: success at any sub-step of the episode so far (reset by ``reset``).
    - ``robot_pos`` / ``robot_vel`` float64 [k+1, D]: DMP-driven robot state at each sub-step
      boundary (row 0 = before the first sub-action); rows after an early stop repeat the last
      executed state.
    - ``dmp_y0`` / ``dmp_dy0`` float64 [D]: measured robot state now (a DMP start).
    - ``cmd_y0`` / ``cmd_dy0`` float64 [D]: commanded state now (``env.unwrapped.command_state()``
      where the env has it: the target the actions move; else the measured state).
    - ``n_substeps`` int: sub-steps executed.
    - ``sim_unstable`` bool: the simulator went unstable (the episode was truncated).
    - ``ctrl_gains_clipped`` / ``ctrl_torque_saturated`` / ``ctrl_nonfinite`` int: the
      torque-actuated envs' controller counters summed over the executed sub-steps (0 for
      other envs; ``ndp.envs.base.CTRL_INFO``).

    ``reset`` info has ``robot_pos``, ``robot_vel``, ``dmp_y0``, ``dmp_dy0``, ``cmd_y0``,
    ``cmd_dy0`` [D] and ``success_any`` False.
    """

    def __init__(
        self, env: gym.Env, k: int, stale_world: bool = True, execution: str = "all"
    ) -> None:
        """Wrap ``env``.

        Args:
            env: A per-step env whose action space is a 1-D Box [A].
            k: Sub-steps per decision (>= 1).
            stale_world: Apply the stale-world reward rule at sub-steps 1..k-1.
            execution: 'all' (run the k sub-actions in turn) or 'first-held' (run the first
                sub-action k times, the 2021 release's execution; :data:`EXECUTIONS`).

        Raises:
            ValueError: bad ``k`` or ``execution``, a non-Box action space, an env without
                the methods the wrapper needs, or a sparse or smooth reward
                (:mod:`ndp.envs.rewards`) with ``stale_world`` at k > 1.
        """
        super().__init__(env)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
            raise ValueError(f"k: expected an int >= 1, got {k!r}")
        if execution not in EXECUTIONS:
            raise ValueError(
                f"execution: expected one of {', '.join(EXECUTIONS)}, got {execution!r}"
            )
        check_flag("stale_world", stale_world)  # "no" would apply the rule
        check_stale_world(reward_of(env), bool(stale_world), int(k))
        self.execution = str(execution)
        box = env.action_space
        if not isinstance(box, spaces.Box) or len(box.shape) != 1:
            raise ValueError(f"env: expected a 1-D Box action space, got {box}")
        base = env.unwrapped
        # the stale-world rule only acts at k > 1 (an env without it runs k = 1 either way)
        stale = bool(stale_world) and int(k) > 1
        needed = ["robot_state"] + (["world_snapshot", "stale_reward"] if stale else [])
        missing = [m for m in needed if not callable(getattr(base, m, None))]
        if missing:
            raise ValueError(f"env: expected env.unwrapped to provide {missing}")
        robot = cast(_RobotEnv, base)  # its methods checked just above
        self.k = int(k)
        self.stale_world = bool(stale_world)
        self._base = robot
        self._low = np.asarray(box.low, dtype=np.float64)
        self._high = np.asarray(box.high, dtype=np.float64)
        self.action_space = spaces.Box(
            np.tile(box.low, (self.k, 1)), np.tile(box.high, (self.k, 1)), dtype=box.dtype
        )
        self.dof = len(np.asarray(robot.robot_state()[0]))
        self._last_state: tuple[np.ndarray, np.ndarray] | None = None
        cmd = getattr(base, "command_state", None)
        self._command_state = cmd if callable(cmd) else robot.robot_state
        self._success_any = False

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the env and all per-episode bookkeeping."""
        obs, info = self.env.reset(seed=seed, options=options)
        self._success_any = False
        pos, vel = (np.asarray(x, dtype=np.float64) for x in self._base.robot_state())
        self._last_state = (pos.copy(), vel.copy())
        info = dict(info)
        cpos, cvel = (np.asarray(x, dtype=np.float64) for x in self._command_state())
        info.update(
            robot_pos=pos.copy(),
            robot_vel=vel.copy(),
            dmp_y0=pos,
            dmp_dy0=vel,
            cmd_y0=cpos,
            cmd_dy0=cvel,
            success_any=False,
        )
        return obs, info

    def _sub_actions(self, actions: np.ndarray) -> np.ndarray:
        """The k sub-actions to execute: checked, clipped to the env's bounds, in its dtype."""
        a = np.asarray(actions, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise ValueError(f"actions: expected shape {self.action_space.shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError("actions: expected finite values, got NaN or inf")
        a = np.clip(a, self._low, self._high).astype(self.env.action_space.dtype)
        if self.execution == "first-held":  # the release's: sub-action 0, held k env steps
            a = np.repeat(a[:1], self.k, axis=0)
        return a

    def step(self, actions: np.ndarray) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Run up to k sub-steps.

        Args:
            actions: [k, A] sub-actions, executed in order; clipped to the env's bounds.

        Returns:
            ``(obs, reward, terminated, truncated, info)``, see the class docstring.

        Raises:
            ValueError: wrong shape or non-finite values in ``actions``.
        """
        a = self._sub_actions(actions)
        k, dof = self.k, self.dof
        sub_r = np.zeros(k)
        sub_live = np.zeros(k)
        mask = np.zeros(k)
        sub_succ = np.zeros(k)
        rpos = np.zeros((k + 1, dof))
        rvel = np.zeros((k + 1, dof))
        # the state the previous decision ended in (nothing moves between two calls)
        rpos[0], rvel[0] = (
            self._last_state if self._last_state is not None else (self._base.robot_state())
        )
        snapshot = None
        ctrl = dict.fromkeys(CTRL_INFO, 0)
        terminated = truncated = unstable = False
        obs: Any = None
        n = 0
        for i in range(k):
            obs, r, terminated, truncated, info = self.env.step(a[i])
            n = i + 1
            unstable = bool(info.get("sim_unstable", False))
            sub_live[i] = float(r)
            if self.stale_world and i > 0 and not unstable:
                sub_r[i] = float(self._base.stale_reward(snapshot, a[i]))
            else:
                sub_r[i] = float(r)
            if self.stale_world and i == 0 and not unstable:
                snapshot = self._base.world_snapshot()
            mask[i] = 1.0
            for key in CTRL_INFO:
                ctrl[key] += int(info.get(key, 0))
            sub_succ[i] = float(bool(info.get("success", False)))
            if "robot_pos" in info and "robot_vel" in info:
                rpos[i + 1], rvel[i + 1] = info["robot_pos"], info["robot_vel"]
            else:
                rpos[i + 1], rvel[i + 1] = self._base.robot_state()
            if terminated or truncated:
                break
        rpos[n + 1 :] = rpos[n]
        rvel[n + 1 :] = rvel[n]
        self._last_state = (rpos[n].copy(), rvel[n].copy())
        cpos, cvel = (np.asarray(x, dtype=np.float64) for x in self._command_state())
        success_decision = bool(sub_succ[:n].any())
        self._success_any = self._success_any or success_decision
        out = ChunkInfo(
            sub_rewards=sub_r,
            sub_rewards_live=sub_live,
            sub_mask=mask,
            sub_success=sub_succ,
            success=bool(sub_succ[n - 1]),
            success_decision=success_decision,
            success_any=self._success_any,
            robot_pos=rpos,
            robot_vel=rvel,
            dmp_y0=rpos[n].copy(),
            dmp_dy0=rvel[n].copy(),
            cmd_y0=cpos,
            cmd_dy0=cvel,
            n_substeps=n,
            sim_unstable=unstable,
            **ctrl,
        ).as_dict()
        return obs, float(sub_r.sum()), bool(terminated), bool(truncated), out
