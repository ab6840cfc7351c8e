"""A toy task for fast tests of the RL stack: a point mass reaching a random goal (pure numpy).

The robot is a point in the plane (or in space), ``p`` in ``[-1, 1]^D``, position-controlled like
Meta-World's mocap hand: an action ``a`` in ``[-1, 1]^D`` moves the point by ``ACTION_SCALE * a``
per env step (clipped to the box). At reset the start is uniform in ``[-0.5, 0.5]^D`` and the goal
is the start plus a uniform offset in ``[-0.5, 0.5]^D`` (clipped to ``[-0.9, 0.9]``), at least
``MIN_GOAL_DIST`` away from the start.

Clocks: one env step lasts ``CONTROL_DT`` seconds; there is no finer simulator step.

Conventions shared with the package's other environments (``ndp.envs``):

- ``robot_state() -> (pos [D], vel [D])`` in physical units (m, m/s): the DoF a DMP drives.
- ``world_snapshot()`` and ``stale_reward(snapshot, action)`` for the stale-world rule (the only
  world state is the goal, which never moves, so the stale reward equals the live one).
- info of ``reset`` and ``step``: ``success`` (bool), ``robot_pos`` [D], ``robot_vel`` [D].

Reward: minus the distance to the goal (m). Success: distance below ``SUCCESS_RADIUS``.
Episodes are truncated at ``horizon`` steps; with ``terminate_on_success=True`` they terminate on
success (used by tests of the termination / truncation distinction).

:func:`ndp.envs.spec.toy_spec` returns the task's :class:`ndp.envs.spec.TaskSpec` (a row of
``ndp.envs.TASKS``); its inverse controller maps DMP trajectory points to bounded displacement
actions like every delta-controlled task.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
from gymnasium import spaces

from ndp.envs.base import NDPEnv, check_render_size, defer_seed

if TYPE_CHECKING:
    from typing_extensions import Unpack

ACTION_SCALE = 0.05
"""Displacement (m) per env step for an action of 1."""
CONTROL_DT = 0.05
"""Seconds per env step."""
SUCCESS_RADIUS = 0.05
"""Success when the point is within this distance (m) of the goal."""
MIN_GOAL_DIST = 0.2
"""The goal is drawn at least this far (m) from the start."""
MAX_GOAL_OFFSET = 0.5
"""The goal is the start plus an offset drawn uniformly in ``[-0.5, 0.5]^D`` (then clipped)."""
DEFAULT_HORIZON = 50
"""Env steps per episode."""


class PointMassEnv(NDPEnv):
    """Point mass reaching a random goal; see the module docstring.

    Observation [3 D]: position, velocity (m/s) and goal. Action [D] in [-1, 1].
    """

    # declared as gymnasium.Env declares it (a ClassVar would clash with its declaration)
    metadata: dict[str, Any] = {  # noqa: RUF012
        "render_modes": ["rgb_array"],
        "render_fps": round(1.0 / CONTROL_DT),
    }

    def __init__(
        self,
        dim: int = 2,
        horizon: int = DEFAULT_HORIZON,
        terminate_on_success: bool = False,
        render_mode: str | None = None,
        fixed_goal: int | str | None = None,
        width: int = 96,
        height: int = 96,
    ) -> None:
        """Create the env.

        Args:
            dim: 2 or 3.
            horizon: env steps per episode (truncation).
            terminate_on_success: end the episode (terminated) when the goal is reached.
            render_mode: ``None`` or ``"rgb_array"`` (a top view of the box, ``width`` x
                ``height`` px).
            fixed_goal: None (a fresh seeded start and goal every reset) or the seed of the one
                start and goal every reset uses.
            width: Rendered frame width (px).
            height: Rendered frame height (px).
        """
        if dim not in (2, 3):
            raise ValueError(f"dim: expected 2 or 3, got {dim!r}")
        self._setup(horizon, render_mode, action_dim=int(dim))
        self.width = check_render_size("width", width)
        self.height = check_render_size("height", height)
        self._set_fixed_goal(fixed_goal, "point-mass")
        self.dim = int(dim)
        self.terminate_on_success = bool(terminate_on_success)
        # position in the box [-1, 1], velocity at most ACTION_SCALE / CONTROL_DT, goal in
        # [-0.9, 0.9]: every observation entry is bounded
        vmax = ACTION_SCALE / CONTROL_DT
        high = np.concatenate([np.ones(self.dim), np.full(self.dim, vmax), np.ones(self.dim)])
        self.observation_space = spaces.Box(-high, high, shape=(3 * self.dim,), dtype=np.float64)
        self._pos = np.zeros(self.dim)
        self._vel = np.zeros(self.dim)
        self._goal = np.zeros(self.dim)
        self._steps = 0

    # ------------------------------------------------------------------ state access
    def robot_state(self) -> tuple[np.ndarray, np.ndarray]:
        """``(pos [D], vel [D])`` of the point (m, m/s), copies."""
        return self._pos.copy(), self._vel.copy()

    def command_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The commanded state: the point follows its commands exactly (= :meth:`robot_state`)."""
        return self.robot_state()

    def world_snapshot(self) -> np.ndarray:
        """The world state (the goal) [D], a copy."""
        goal: np.ndarray = self._goal.copy()
        return goal

    def stale_reward(self, snapshot: np.ndarray, action: np.ndarray | None = None) -> float:
        """Reward with the live point and the goal from ``snapshot`` (pure)."""
        del action
        return -float(np.linalg.norm(snapshot - self._pos))

    def _obs(self) -> np.ndarray:
        return np.concatenate([self._pos, self._vel, self._goal])

    def _dist(self) -> float:
        return float(np.linalg.norm(self._goal - self._pos))

    def _info(self) -> dict[str, Any]:
        pos, vel = self.robot_state()
        return {"success": self._dist() < SUCCESS_RADIUS, "robot_pos": pos, "robot_vel": vel}

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Draw a start in ``[-0.5, 0.5]^D`` and a goal near it; returns ``(obs [3D], info)``."""
        self._reset_rng(seed)
        rng = self._task_rng()
        self._pos = rng.uniform(-0.5, 0.5, self.dim)
        self._vel = np.zeros(self.dim)
        while True:
            offset = rng.uniform(-MAX_GOAL_OFFSET, MAX_GOAL_OFFSET, self.dim)
            self._goal = np.clip(self._pos + offset, -0.9, 0.9)
            if self._dist() >= MIN_GOAL_DIST:
                break
        self._steps = 0
        return self._obs(), self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Move by ``ACTION_SCALE * clip(action)``; returns the gymnasium 5-tuple."""
        a = np.asarray(action, dtype=np.float64).reshape(self.dim)
        if not np.isfinite(a).all():
            raise ValueError(f"action: expected finite values, got {a.tolist()}")
        a = np.clip(a, -1.0, 1.0)
        new = np.clip(self._pos + ACTION_SCALE * a, -1.0, 1.0)
        self._vel = (new - self._pos) / CONTROL_DT
        self._pos = new
        self._steps += 1
        info = self._info()
        terminated = bool(self.terminate_on_success and info["success"])
        truncated = self._steps >= self.horizon
        return self._obs(), -self._dist(), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """A ``height`` x ``width`` RGB top view of the box [-1, 1]^2 (x to the right, y down;
        goal green, point red), or ``None`` without render_mode."""
        if self.render_mode != "rgb_array":
            return None
        w, h = self.width, self.height
        img = np.full((h, w, 3), 255, dtype=np.uint8)
        half = max(1, round(min(w, h) / 48))  # a 5 px marker at the default 96 x 96

        def _px(p: np.ndarray) -> tuple[int, int]:
            c = np.clip((p[0] + 1.0) / 2.0 * (w - 1), 0, w - 1)
            r = np.clip((p[1] + 1.0) / 2.0 * (h - 1), 0, h - 1)
            return round(float(r)), round(float(c))

        for p, colour in ((self._goal, (0, 160, 0)), (self._pos, (220, 0, 0))):
            r, c = _px(p)
            img[max(r - half, 0) : r + half + 1, max(c - half, 0) : c + half + 1] = colour
        return img


class PointMassOptions(TypedDict, total=False):
    """:class:`PointMassEnv`'s keywords besides dim, horizon and render_mode."""

    terminate_on_success: bool
    fixed_goal: int | str | None
    width: int
    height: int


def make_point_mass_env(
    *,
    seed: int | None = None,
    horizon: int | None = None,
    render_mode: str | None = None,
    dim: int = 2,
    **kw: Unpack[PointMassOptions],
) -> PointMassEnv:
    """Factory with the signature of ``ndp.envs.make_env`` (without the name)."""
    env = PointMassEnv(
        dim=dim,
        horizon=DEFAULT_HORIZON if horizon is None else horizon,
        render_mode=render_mode,
        **kw,
    )
    defer_seed(env, seed)
    return env
