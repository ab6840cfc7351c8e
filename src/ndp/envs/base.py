"""What every env family of the package shares, written once (:class:`NDPEnv`).

- Argument checks: ``render_mode`` against ``metadata["render_modes"]``, a positive
  ``horizon`` and the rendered frame size (one-line ``ValueError`` naming the argument).
- Deferred seeding: :meth:`NDPEnv.seed_next_reset` stores a seed that the next ``reset()``
  without a seed uses (``make_env(..., seed=...)``); :func:`defer_seed` is the factories' half
  (also seeds the action space's sampler).
- The unstable-simulator rule of the MuJoCo envs: a step after which MuJoCo counted a bad
  qpos / qvel / qacc warning, or whose qpos / qvel are not finite, ends the episode by truncation
  with reward 0, the previous observation and ``info["sim_unstable"] = True``; further steps raise
  until ``reset()``.
- The robot-state info keys the chunked wrapper reads (``success``, ``robot_pos``,
  ``robot_vel``, ``sim_unstable``).
- The ``[-1, 1]^A`` float32 action box and the render guard.

Subclasses provide ``robot_state()`` (and ``world_snapshot`` / ``stale_reward`` /
``command_state`` for :class:`ndp.envs.ChunkedEnv`), ``reset`` and ``step``.
"""

from __future__ import annotations

import gc
import os
import sys
from collections.abc import Callable
from typing import Any, SupportsInt

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike

SIM_UNSTABLE = "sim_unstable"
"""Info key: the simulator went unstable and the episode was truncated."""
CTRL_INFO = ("ctrl_gains_clipped", "ctrl_torque_saturated", "ctrl_nonfinite")
"""Info counters of the torque-actuated envs (``ndp.envs.torque``): gain entries clipped to
their range, torque entries clipped at the limit (over the simulator steps), a non-finite
torque (the episode then ends like an unstable simulator). ``ChunkedEnv`` sums them over a
decision (0 for envs without them)."""


def check_render_mode(render_mode: str | None, modes: list[str] | tuple[str, ...]) -> None:
    """Raise unless ``render_mode`` is None or one of ``modes``.

    Raises:
        ValueError: ``render_mode: expected None or 'rgb_array', got 'human'``.
    """
    if render_mode is not None and render_mode not in modes:
        allowed = " or ".join(["None", *(repr(m) for m in modes)])
        raise ValueError(f"render_mode: expected {allowed}, got {render_mode!r}")


MAX_RENDER_SIZE = 4096
"""Largest rendered frame side (px) the envs accept."""


def check_render_size(name: str, value: object) -> int:
    """``int(value)`` if it is an integer frame side in ``[1, MAX_RENDER_SIZE]`` px.

    Raises:
        ValueError: ``width: expected an integer from 1 to 4096 (px), got 0``.
    """
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer))
        or not 1 <= int(value) <= MAX_RENDER_SIZE
    ):
        raise ValueError(
            f"{name}: expected an integer from 1 to {MAX_RENDER_SIZE} (px), got {value!r}"
        )
    return int(value)


def fit_offscreen_buffer(model: mujoco.MjModel, width: int, height: int) -> None:
    """Grow ``model``'s offscreen framebuffer (in place) so that a ``width`` x ``height`` frame
    fits; MuJoCo's renderer refuses a frame larger than it."""
    vis = model.vis.global_
    vis.offwidth, vis.offheight = max(vis.offwidth, int(width)), max(vis.offheight, int(height))


def check_horizon(horizon: SupportsInt | str) -> int:
    """``int(horizon)`` if it is at least 1.

    Raises:
        ValueError: ``horizon: expected a positive int, got 0``.
    """
    try:
        value = int(horizon)
    except (TypeError, ValueError):
        value = 0
    if value < 1:
        raise ValueError(f"horizon: expected a positive int, got {horizon!r}")
    return value


def divisors(n: int) -> tuple[int, ...]:
    """The positive divisors of ``n`` >= 1, ascending (``divisors(10) == (1, 2, 5, 10)``)."""
    return tuple(d for d in range(1, int(n) + 1) if n % d == 0)


def check_substeps(substeps: object, frame_skip: int) -> int:
    """``int(substeps)`` if it divides ``frame_skip`` (the simulator steps of one env step).

    An env built with ``substeps = m`` cuts each of its env steps into m shorter ones of
    ``frame_skip / m`` simulator steps each (``ndp rl eval --exec-k``; docs/policies.md).

    Raises:
        ValueError: ``substeps: expected a divisor of the frame skip 5 (1, 5), got 2``.
    """
    allowed = divisors(frame_skip)
    if (
        isinstance(substeps, bool)
        or not isinstance(substeps, (int, np.integer))
        or int(substeps) not in allowed
    ):
        raise ValueError(
            f"substeps: expected a divisor of the frame skip {frame_skip} "
            f"({', '.join(map(str, allowed))}), got {substeps!r}"
        )
    return int(substeps)


def defer_seed(env: gym.Env, seed: int | None) -> None:
    """Seed the first ``reset()`` that is not given a seed, and the action space's sampler
    (the ``seed`` argument of the factories); None leaves both unseeded."""
    if seed is not None:
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or int(seed) < 0:
            raise ValueError(f"seed: expected None or an integer >= 0, got {seed!r}")
        env.seed_next_reset(int(seed))  # type: ignore[attr-defined]
        env.action_space.seed(int(seed))


def warning_count(data: mujoco.MjData) -> int:
    """Total of MuJoCo's instability warnings (bad qpos / qvel / qacc) so far."""
    w = data.warning
    return int(
        w[int(mujoco.mjtWarning.mjWARN_BADQPOS)].number
        + w[int(mujoco.mjtWarning.mjWARN_BADQVEL)].number
        + w[int(mujoco.mjtWarning.mjWARN_BADQACC)].number
    )


RELEASE_GOAL = "release"
"""``fixed_goal`` value of the 2021 release's ONE hard-coded task configuration (the same for
every run and seed; ``docs/rl-release.md``): the env classes that have one define it
(``release_config``); the others refuse it at construction."""


def check_fixed_goal(value: object) -> int | str | None:
    """``fixed_goal`` checked: None, an integer >= 0 (numpy integers accepted: the seed of one
    configuration) or ``"release"`` (:data:`RELEASE_GOAL`).

    Raises:
        ValueError: anything else (named in the message).
    """
    if value is None:
        return None
    if value == RELEASE_GOAL:
        return RELEASE_GOAL
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ValueError(f"fixed_goal: expected None, an integer >= 0 or 'release', got {value!r}")
    return int(value)


def sim_unstable(data: mujoco.MjData, warnings_before: int) -> bool:
    """True if MuJoCo warned since ``warnings_before`` (:func:`warning_count`) or qpos / qvel
    hold a NaN or inf."""
    return warning_count(data) > warnings_before or not (
        np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    )


class NDPEnv(gym.Env):
    """Base of the package's envs: checks, deferred seeding, the unstable-simulator rule.

    A subclass sets ``metadata["render_modes"]`` (the modes :meth:`_setup` accepts besides
    None), calls :meth:`_setup` in its ``__init__`` (after its own argument checks),
    :meth:`_reset_rng` at the start of ``reset`` and, in a MuJoCo ``step``,
    :meth:`_check_running`, :meth:`_check_action` and :meth:`_unstable_step`.
    """

    horizon: int
    """Env steps per episode."""
    _unstable: bool = False
    """The simulator went unstable this episode (MuJoCo envs; cleared by reset)."""
    _pending_seed: int | None = None
    """Seed for the next ``reset()`` that is not given one."""
    fixed_goal: int | str | None = None
    """None: every reset draws a fresh task configuration (objects, goal) from the seeded
    ``np_random``; an int: every reset draws it from a fresh generator seeded with this value,
    so every episode has the same configuration (``goals="per-seed"`` of a run); ``"release"``:
    the 2021 release's one hard-coded configuration (:meth:`release_config`;
    ``goals="release"``)."""

    def _setup(self, horizon: SupportsInt | str, render_mode: str | None, action_dim: int) -> None:
        """Check and store ``horizon`` and ``render_mode``; set the ``[-1, 1]^action_dim``
        float32 action space.

        Raises:
            ValueError: horizon below 1 (or not a number); render mode not None or one of
                ``metadata["render_modes"]``.
        """
        horizon = check_horizon(horizon)
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.horizon = horizon
        self.render_mode = render_mode
        self.action_space = spaces.Box(-1.0, 1.0, shape=(int(action_dim),), dtype=np.float32)
        self._unstable = False
        self._pending_seed = None

    # ------------------------------------------------------------------ seeding
    def seed_next_reset(self, seed: int | None) -> None:
        """Use ``seed`` on the next reset that is not given one (``make_env(seed=...)``)."""
        self._pending_seed = seed

    def _reset_rng(self, seed: int | None) -> None:
        """``gymnasium.Env.reset(seed=...)`` with the deferred seed where ``seed`` is None (the
        deferred seed is then used up; an explicit ``seed`` leaves it for a later reset)."""
        if seed is None and self._pending_seed is not None:
            seed, self._pending_seed = self._pending_seed, None
        super().reset(seed=seed)

    def _set_fixed_goal(self, fixed_goal: object, task: str = "") -> None:
        """Check and store ``fixed_goal`` (None, an int >= 0, or ``"release"`` where
        :meth:`release_config` has one for ``task``).

        Raises:
            ValueError: a bad value, or ``"release"`` for a task the release did not fix.
        """
        self.fixed_goal = check_fixed_goal(fixed_goal)
        if self.fixed_goal == RELEASE_GOAL and self.release_config(task) is None:
            from ndp.envs.release import RELEASE_GOAL_TASKS

            raise ValueError(
                f"fixed_goal: 'release' (the 2021 release's hard-coded configuration) exists for "
                f"{', '.join(RELEASE_GOAL_TASKS)}, not {task or type(self).__name__!r}"
            )

    def release_config(self, task: str) -> np.ndarray | None:
        """The 2021 release's hard-coded task configuration of ``task`` (what this env's reset
        draws at random otherwise), or None where the release had none (the default)."""
        return None

    def _task_rng(self) -> np.random.Generator:
        """The generator this reset's task configuration is drawn from: ``np_random`` (fresh
        goals), or a new generator seeded with ``fixed_goal`` (the same goal every reset; with
        ``"release"`` the env uses :meth:`release_config` instead of drawing)."""
        if self.fixed_goal is None:
            return self.np_random
        if isinstance(self.fixed_goal, str):  # "release": the env uses release_config
            return np.random.default_rng(0)
        return np.random.default_rng(self.fixed_goal)

    # ------------------------------------------------------------------ step helpers
    def _check_action(self, action: ArrayLike) -> np.ndarray:
        """``action`` as float64 of the action space's shape, finite (not yet clipped).

        Raises:
            ValueError: wrong shape, or NaN / inf values.
        """
        a = np.asarray(action, dtype=np.float64)
        shape = self.action_space.shape
        if a.shape != shape:
            raise ValueError(f"action: expected shape {shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError("action: expected finite values, got NaN or inf")
        return a

    def _check_running(self, steps: int) -> None:
        """Raise if the episode ended (``steps`` reached the horizon, or the simulator went
        unstable).

        Raises:
            RuntimeError: ``episode is over: call reset()``.
        """
        if self._unstable or steps >= self.horizon:
            raise RuntimeError("episode is over: call reset()")

    @staticmethod
    def _state_info(
        success: bool, pos: np.ndarray, vel: np.ndarray, unstable: bool = False
    ) -> dict[str, Any]:
        """The info keys of every reset and step: ``success``, ``robot_pos``, ``robot_vel``,
        ``sim_unstable``."""
        return {"success": success, "robot_pos": pos, "robot_vel": vel, SIM_UNSTABLE: unstable}

    def _unstable_step(
        self,
        last_obs: np.ndarray,
        pos: np.ndarray,
        vel: np.ndarray,
        info: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """End the episode on an unstable simulator: mark it, and return the step's tuple.

        Args:
            last_obs: The observation before the step (returned as this step's).
            pos: Robot position now (non-finite values are replaced by finite ones).
            vel: Robot velocity now (likewise).
            info: Info to extend (e.g. the simulator's own keys); None: a new one.

        Returns:
            ``(last_obs, 0.0, False, True, info)`` with ``success`` False and
            ``sim_unstable`` True.
        """
        self._unstable = True
        info = {} if info is None else info
        info.update(self._state_info(False, np.nan_to_num(pos), np.nan_to_num(vel), True))
        return last_obs, 0.0, False, True, info

    def _render_frame(self, draw: Callable[[], np.ndarray | None]) -> np.ndarray | None:
        """``draw()`` (the env's own rendering call) with the OpenGL failures of a machine
        without a display turned into one line naming ``MUJOCO_GL`` and what to set."""
        hook = sys.unraisablehook
        try:
            return draw()
        except Exception as exc:  # mujoco.FatalError, GLFW / EGL / OSMesa errors
            text = f"{type(exc).__name__}: {exc}"
            words = ("OpenGL", "EGL", "GLFW", "glfw", "DISPLAY", "display", "GL context")
            if type(exc).__name__ != "FatalError" and not any(w in text for w in words):
                raise
            # the half-built renderer in this traceback fails again in its __del__ when freed
            # with it (a second traceback of MuJoCo's): muted while it goes
            sys.unraisablehook = lambda *_: None
        try:
            gc.collect()
        finally:
            sys.unraisablehook = hook
        gl = os.environ.get("MUJOCO_GL", "(unset)")
        raise OSError(
            f"render: MuJoCo could not create an OpenGL context with MUJOCO_GL={gl} "
            f"({text.splitlines()[0][:160]}); on a machine without a display set "
            "MUJOCO_GL=egl (GPU or Mesa EGL) or MUJOCO_GL=osmesa"
        )

    def _render_guard(self) -> bool:
        """True if a frame can be rendered; else warns (as gymnasium does) and returns False."""
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode='rgb_array'")
            return False
        return True
