"""Reward variants at the env-step level: the env's own (dense), sparse success, and smooth.

Issue 59 ("why NDP loses") asks whether a reward that favours trajectory action spaces changes
the comparison. A variant is a :class:`RewardVariant` wrapper directly around the per-step env
(``ndp.envs.make_env(task, reward=..., smooth_lambda=...)``), so every method sees the same
reward per env step: PPO (k = 1), PPO-multi and NDP through :class:`ndp.envs.ChunkedEnv` (each
sub-step's reward and ``sub_rewards_live``), the SAC family, Dyn-E and every evaluation env.
Success (``info["success"]``, hence ``success_any`` and the evaluation's success) stays the
task's own.

- ``"dense"``: the env's own reward (no wrapper; the default).
- ``"sparse"``: ``r_t = 1`` at the first env step whose ``info["success"]`` is true, else 0;
  the episode terminates at that step (``terminated=True``), so its return is 1 or 0.
- ``"smooth"``: ``r_t = env reward - smooth_lambda * ||a_t - a_{t-1}||^2``, ``a_t`` the executed
  action (clipped to the action bounds, in the action space's dtype), ``a_{-1} := a_0`` (no
  penalty at the first step of an episode; ``reset`` forgets the previous action).

The stale-world rule (:mod:`ndp.envs.chunked`) recomputes the rewards of sub-steps 1..k-1 from
a stale world snapshot with ``env.unwrapped.stale_reward``, below this wrapper: a sparse or
smooth reward is not defined there, and :class:`ndp.envs.ChunkedEnv` refuses the combination
at k > 1 (:func:`check_stale_world`).

:data:`DEFAULT_SMOOTH_LAMBDA` = 0.25 was chosen on push-v3 (v2 reward) with
``benchmarks/smooth_lambda.py``: the zoo's push-v3 PPO, PPO-multi and NDP policies, acting
stochastically as in training, change their executed action by a mean ``||a_t - a_{t-1}||^2`` of
3.1 per env step for a mean reward of 5.1 per step (10 episodes each); the price at which the
penalty is 15 % of the reward there (meaningful, not dominant) is 0.245, rounded to 0.25.
docs/envs.md gives the numbers per policy (and that at initialisation, where push-v3 pays about
0.05 per step, any such price outweighs the task's reward).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

REWARDS = ("dense", "sparse", "smooth")
"""Reward variants of ``make_env(reward=...)`` (``TrainConfig.reward``)."""
DEFAULT_SMOOTH_LAMBDA = 0.25
"""The smooth reward's price per unit squared action change where none is given (module
docstring: how it was chosen)."""


def check_reward(reward: object) -> str:
    """``reward`` checked: one of :data:`REWARDS`.

    Raises:
        ValueError: ``reward: expected one of dense, sparse, smooth, got 'x'``.
    """
    if not isinstance(reward, str) or reward not in REWARDS:
        raise ValueError(f"reward: expected one of {', '.join(REWARDS)}, got {reward!r}")
    return reward


def check_smooth_lambda(smooth_lambda: object, reward: str = "smooth") -> float:
    """The smooth reward's lambda: None gives :data:`DEFAULT_SMOOTH_LAMBDA`.

    Args:
        smooth_lambda: a finite number >= 0, or None.
        reward: the reward it goes with; a lambda given (not None) with another reward than
            ``"smooth"`` is refused (it would not be used).

    Raises:
        ValueError: negative, non-finite or not a number; or given with another reward.
    """
    if smooth_lambda is None:
        return DEFAULT_SMOOTH_LAMBDA
    if reward != "smooth":
        raise ValueError(
            f"smooth_lambda: only the 'smooth' reward has a price, got smooth_lambda="
            f"{smooth_lambda!r} with reward={reward!r} (leave it out, or use reward='smooth')"
        )
    if (
        isinstance(smooth_lambda, bool)
        or not isinstance(smooth_lambda, (int, float, np.integer, np.floating))
        or not math.isfinite(float(smooth_lambda))
        or smooth_lambda < 0
    ):
        raise ValueError(f"smooth_lambda: expected a finite number >= 0, got {smooth_lambda!r}")
    return float(smooth_lambda)


def smooth_penalties(actions: np.ndarray, smooth_lambda: float) -> np.ndarray:
    """The smooth reward's penalty of each step of one episode.

    Args:
        actions: [T, A] executed actions a_0 .. a_{T-1}.
        smooth_lambda: the price lambda (>= 0).

    Returns:
        [T] float64: ``lambda * ||a_t - a_{t-1}||^2`` with ``a_{-1} := a_0`` (entry 0 is 0).
    """
    a = np.asarray(actions, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"actions: expected shape [T, A], got {a.shape}")
    out = np.zeros(len(a))
    out[1:] = smooth_lambda * np.sum(np.diff(a, axis=0) ** 2, axis=1)
    return out


def sparse_rewards(success: np.ndarray) -> tuple[np.ndarray, int | None]:
    """The sparse reward of each step of one episode and where it ends.

    Args:
        success: [T] the task's success flag after each step.

    Returns:
        (rewards [T] float64: 1 at the first successful step, 0 elsewhere; the index of that
        step, where the episode terminates, or None when no step succeeded).
    """
    s = np.asarray(success, dtype=bool)
    if s.ndim != 1:
        raise ValueError(f"success: expected shape [T], got {s.shape}")
    out = np.zeros(len(s))
    hits = np.flatnonzero(s)
    if len(hits) == 0:
        return out, None
    out[hits[0]] = 1.0
    return out, int(hits[0])


class RewardVariant(gym.Wrapper):
    """A per-step env with the sparse or smooth reward (see the module docstring).

    Each step's info gains ``env_reward`` (the env's own reward) and, for ``"smooth"``,
    ``smooth_penalty`` (what was subtracted).
    """

    def __init__(self, env: gym.Env, reward: str, smooth_lambda: float | None = None) -> None:
        """Wrap ``env``.

        Args:
            env: a per-step env with a 1-D Box action space whose step info has ``success``.
            reward: ``"sparse"`` or ``"smooth"`` (``"dense"`` needs no wrapper).
            smooth_lambda: the smooth reward's price (None: :data:`DEFAULT_SMOOTH_LAMBDA`).

        Raises:
            ValueError: an unknown or dense reward, a bad ``smooth_lambda``, or a non-Box
                action space.
        """
        super().__init__(env)
        if check_reward(reward) == "dense":
            raise ValueError("reward: 'dense' is the env's own reward; do not wrap the env")
        self.reward = reward
        price = check_smooth_lambda(smooth_lambda, reward)  # given with 'sparse': refused
        self.smooth_lambda: float | None = price if reward == "smooth" else None
        """The smooth reward's price (None for the sparse reward)."""
        box = env.action_space
        if not isinstance(box, spaces.Box) or len(box.shape) != 1:
            raise ValueError(f"env: expected a 1-D Box action space, got {box}")
        self._box = box
        self._prev: np.ndarray | None = None
        self._over = False

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the env; the previous action and the episode's success are forgotten."""
        self._prev = None
        self._over = False
        return self.env.reset(seed=seed, options=options)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """One env step with the variant's reward.

        Raises:
            RuntimeError: a step after the sparse reward ended the episode (call reset()).
            ValueError: the sparse reward on an env whose step info has no ``success``.
        """
        if self._over:
            raise RuntimeError("episode is over: call reset()")
        obs, r, terminated, truncated, info = self.env.step(action)
        info = dict(info)
        info["env_reward"] = float(r)
        if self.reward == "sparse":
            if "success" not in info:
                raise ValueError("env: the sparse reward needs info['success'] from env.step")
            success = bool(info["success"])
            terminated = bool(terminated) or success
            self._over = success
            return obs, 1.0 if success else 0.0, terminated, truncated, info
        box = self._box
        executed = np.clip(np.asarray(action, dtype=np.float64), box.low, box.high)
        a = executed.astype(box.dtype).astype(np.float64)  # what the env ran
        prev = a if self._prev is None else self._prev
        self._prev = a
        assert self.smooth_lambda is not None  # set for the smooth reward
        penalty = self.smooth_lambda * float(np.sum((a - prev) ** 2))
        info["smooth_penalty"] = penalty
        return obs, float(r) - penalty, terminated, truncated, info


def reward_of(env: gym.Env) -> str:
    """The reward variant of ``env`` (a :class:`RewardVariant` anywhere in its wrappers), else
    ``"dense"``."""
    e: Any = env
    while isinstance(e, gym.Wrapper):
        if isinstance(e, RewardVariant):
            return e.reward
        e = e.env
    return "dense"


def check_stale_world(reward: str, stale_world: bool, k: int) -> None:
    """Refuse a sparse or smooth reward with the stale-world rule at k > 1.

    Raises:
        ValueError: one line naming both options.
    """
    if reward != "dense" and stale_world and k > 1:
        raise ValueError(
            f"reward: {reward!r} is ill-defined with the stale-world rule at k={k} (it "
            "recomputes sub-step rewards from a stale world snapshot); set stale_world=False "
            f"(--reward {reward} --no-stale-world) or use k = 1"
        )
