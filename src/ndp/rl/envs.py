"""Tasks and seeded vector environments for the trainer.

:func:`resolve_task` turns a name into a :class:`TaskHandle` (spec + per-step env factory): any
name or alias of ``ndp.envs.TASKS``, the toy tasks of :mod:`ndp.envs.point_mass` included.
:func:`make_vector_env` builds ``num_envs`` :class:`ndp.envs.ChunkedEnv` copies (k sub-steps per
decision) in a vector env with same-step autoreset: when an episode ends, the returned
observation and info are the reset ones and the finished step's info is under
``info["final_info"]`` (its observation under ``final_obs``). Kinds (``vector``):

- ``"sync"``: gymnasium's ``SyncVectorEnv``, one process (debugging, determinism tests), as
  :class:`ndp.envs.vector.SyncChunkedVectorEnv` (its info arrays take one env's reset beside
  another's step);
- ``"workers"``: :class:`ndp.envs.vector.WorkerVectorEnv`, ``env_workers`` subprocesses with
  several envs each and shared-memory arrays (same numbers as sync, both cores busy);
- ``"async"``: gymnasium's ``AsyncVectorEnv``, one subprocess per env (likewise);
- ``"auto"``: ``workers`` with one worker per core when this process may use two or more cores
  and there are two or more envs, else ``sync``;
- ``"overlap"``: :class:`ndp.envs.vector.OverlapVectorEnv`, two env groups (halves) all in
  worker processes (``env_workers`` split between them): the on-policy trainer computes one
  group's decision while the other group steps (an even ``num_envs``).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

from ndp.chunk_info import dmp_start, dmp_start_keys
from ndp.envs import get_task_spec, make_env, task_options
from ndp.envs.chunked import ChunkedEnv
from ndp.envs.envpool_backend import check_backend
from ndp.envs.factory import RELEASE9, check_observation
from ndp.envs.rewards import check_reward, check_smooth_lambda
from ndp.envs.spec import TaskSpec
from ndp.envs.vector import (
    AsyncChunkedVectorEnv,
    OverlapVectorEnv,
    SyncChunkedVectorEnv,
    WorkerVectorEnv,
    default_workers,
)

if TYPE_CHECKING:
    from typing_extensions import Unpack  # typing's from Python 3.11

    from ndp.rl.config import EnvOptions, TrainConfig


@dataclass(frozen=True)
class TaskHandle:
    """A resolved task."""

    spec: TaskSpec
    """The task spec (the task table's row)."""
    make: Callable[..., gym.Env]
    """``make(seed=None, horizon=None, render_mode=None) -> per-step gymnasium.Env``."""


def resolve_task(name: str, **options: Unpack[EnvOptions]) -> TaskHandle:
    """Resolve a task name or alias through ``ndp.envs.TASKS`` (the toy tasks included).

    ``options``: task options every env of the handle gets (``reward_version``,
    ``fixed_goal``, ``observation``, ``reward``, ``smooth_lambda``, ``backend``:
    ``ndp.envs.make_env``; a run's are ``TrainConfig.env_options()``), checked here against
    the task's row.

    Raises:
        ValueError: unknown name (the message lists close names), or a bad option.
    """
    spec = get_task_spec(name)
    observation = check_observation(spec, options.pop("observation", "full"))
    reward = check_reward(options.pop("reward", "dense"))
    backend = options.pop("backend", "metaworld")
    price = options.pop("smooth_lambda", None)
    check_smooth_lambda(price, reward)
    version, goal = options.pop("reward_version", "v2"), options.pop("fixed_goal", None)
    if options:  # a keyword that is no task option (as a call with it would say)
        raise TypeError(
            f"resolve_task() got an unexpected keyword argument {next(iter(options))!r}"
        )
    kw = task_options(spec, version, goal)
    if backend != "metaworld":
        # the run's k and stale-world rule are checked by resolve_config / make_vector_env
        check_backend(backend, spec, reward_version=kw.get("reward_version", "v2"),
                      fixed_goal=kw.get("fixed_goal"))  # fmt: skip
        kw["backend"] = backend
    if reward != "dense":
        kw["reward"] = reward
    if price is not None:
        kw["smooth_lambda"] = price
    if observation != "full":
        kw["observation"] = observation
        spec = dataclasses.replace(spec, obs_dim=len(RELEASE9))
    return TaskHandle(spec, functools.partial(make_env, spec.name, **kw))


def _make_chunked(
    make: Callable[..., gym.Env],
    k: int,
    stale_world: bool,
    horizon: int | None,
    render_mode: str | None = None,
    execution: str = "all",
) -> ChunkedEnv:
    """Env-worker entry: one chunked env (torch kept to one thread in worker processes; in
    the trainer's own process its ``--torch-threads`` stay)."""
    import multiprocessing

    if multiprocessing.parent_process() is not None:
        import torch

        torch.set_num_threads(1)
    env = make(horizon=horizon, render_mode=render_mode)
    return ChunkedEnv(env, k, stale_world=stale_world, execution=execution)


def make_vector_env(
    task: TaskHandle,
    k: int,
    num_envs: int,
    stale_world: bool = True,
    horizon: int | None = None,
    vector: str = "sync",
    env_workers: int | None = None,
    execution: str = "all",
) -> gym.vector.VectorEnv:
    """``num_envs`` chunked copies of a task in a vector env (same-step autoreset).

    Seed it with ``reset(seed=[...])``. Actions are [num_envs, k, A]. ``vector`` and
    ``env_workers``: see the module docstring (``resolve_vector``); ``stale_world`` and
    ``execution``: :class:`ndp.envs.ChunkedEnv`'s.
    """
    fns = [
        functools.partial(_make_chunked, task.make, k, stale_world, horizon, None, execution)
        for _ in range(num_envs)
    ]
    kind, workers = resolve_vector(vector, num_envs, env_workers)
    if kind == "overlap":
        spec = task.spec
        return OverlapVectorEnv(
            fns,
            spec.obs_dim,
            k,
            spec.action_dim,
            spec.dmp_dofs,
            env_workers,
        )
    if kind == "workers":
        spec = task.spec
        return WorkerVectorEnv(fns, spec.obs_dim, k, spec.action_dim, spec.dmp_dofs, workers)
    if kind == "async":
        return AsyncChunkedVectorEnv(fns, autoreset_mode=AutoresetMode.SAME_STEP)
    return SyncChunkedVectorEnv(fns, autoreset_mode=AutoresetMode.SAME_STEP)


VECTOR_KINDS = ("auto", "sync", "workers", "async", "overlap")
"""Accepted values of ``vector``."""


def resolve_vector(vector: str, num_envs: int, env_workers: int | None) -> tuple[str, int]:
    """(kind, workers) that ``make_vector_env`` builds for ``vector`` ('auto' decided here)."""
    if vector not in VECTOR_KINDS:
        raise ValueError(f"vector: expected one of {', '.join(VECTOR_KINDS)}, got {vector!r}")
    workers = default_workers(num_envs) if env_workers is None else int(env_workers)
    if vector == "auto":
        vector = "workers" if workers >= 2 else "sync"
    return vector, workers


def env_seeds(seed: int, num_envs: int, epoch: int = 0) -> list[int]:
    """Distinct per-env reset seeds for a run seed (``epoch`` > 0 after a resume)."""
    base = np.random.SeedSequence([seed, epoch]).generate_state(num_envs)
    return [int(s) for s in base]


def step_info(
    infos: dict[str, Any], done: np.ndarray, key: str, default: float = 0.0
) -> np.ndarray:
    """The finished step's value of ``key`` per env (``final_info`` where the episode ended).

    Args:
        infos: info dict of a same-step-autoreset vector env.
        done: [E] bool, episodes that ended at this step.
        key: an info key of :class:`ndp.envs.ChunkedEnv`.step.
        default: fill for envs that lack the key.

    Returns:
        Array [E, ...] of the step's values.
    """
    vals = np.asarray(infos[key]) if key in infos else None
    if done.any():
        fin = infos.get("final_info", {})
        fvals = np.asarray(fin[key]) if key in fin else None
        if fvals is not None:
            vals = fvals.copy() if vals is None else vals.copy()
            vals[done] = fvals[done]
    if vals is None:
        return np.full(len(done), default)
    return vals


def decision_rewards(
    infos: dict[str, Any], done: np.ndarray, num_envs: int, k: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sub-rewards as trained [E, k], live sub-rewards [E, k], executed mask [E, k]) of one
    decision of a chunked vector env (the live ones equal the trained ones where the env does
    not report them)."""
    sub_r = step_info(infos, done, "sub_rewards").reshape(num_envs, k)
    mask = step_info(infos, done, "sub_mask").reshape(num_envs, k)
    live = sub_r
    if "sub_rewards_live" in infos or "final_info" in infos:
        rep = step_info(infos, done, "sub_rewards_live", np.nan).reshape(num_envs, -1)
        if rep.shape == sub_r.shape and not np.isnan(rep).any():
            live = rep
    return sub_r, live, mask


class EpisodeTracker:
    """Running return (as trained and live), length per env, and the rows of finished episodes.

    Each finished episode appends ``(success_any, success_final, return, length, return_live)``
    to the given list (the trainers' ``charts/*`` metrics are means over these rows).
    """

    def __init__(self, num_envs: int) -> None:
        self.ret = np.zeros(num_envs)
        self.ret_live = np.zeros(num_envs)
        self.length = np.zeros(num_envs, dtype=np.int64)

    def add(
        self,
        infos: dict[str, Any],
        done: np.ndarray,
        sub_r: np.ndarray,
        live: np.ndarray,
        mask: np.ndarray,
        out: list[tuple[float, float, float, float, float]],
    ) -> None:
        """Add one decision's sub-rewards [E, k] (trained and live) and mask [E, k]; episodes
        that ended (``done`` [E]) are appended to ``out`` and their counters reset."""
        self.ret += (sub_r * mask).sum(1)
        self.ret_live += (live * mask).sum(1)
        self.length += mask.sum(1).astype(np.int64)
        if not done.any():
            return
        s_any = step_info(infos, done, "success_any")
        s_fin = step_info(infos, done, "success")
        for i in np.flatnonzero(done):
            out.append((float(s_any[i]), float(s_fin[i]), float(self.ret[i]),
                        float(self.length[i]), float(self.ret_live[i])))  # fmt: skip
        self.ret[done] = 0.0
        self.ret_live[done] = 0.0
        self.length[done] = 0


class FrameRecorder(gym.Wrapper):
    """Append ``env.render()`` to ``frames`` after every reset and env step (for mp4s)."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.frames: list[np.ndarray] = []

    def reset(
        self, *, seed: int | None = None, options: dict[str, object] | None = None
    ) -> tuple[np.ndarray, dict[str, object]]:
        out = self.env.reset(seed=seed, options=options)
        self.frames.append(np.asarray(self.env.render()))
        return out

    def step(
        self, action: np.ndarray
    ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, object]]:
        out = self.env.step(action)
        self.frames.append(np.asarray(self.env.render()))
        return out


def decision_start(
    info: dict[str, Any], n: int, source: str = "measured"
) -> tuple[np.ndarray, np.ndarray]:
    """The next decision's DMP start (physical y0, dy0) [E, D] from a vector env's info.

    ``source``: 'measured' (the robot) or 'commanded' (the target the actions move)
    (:func:`ndp.chunk_info.dmp_start`); an env without them: its ``robot_pos`` / ``robot_vel``."""
    ky, _ = dmp_start_keys(source)
    if ky in info:
        return dmp_start(info, source, n)
    else:
        y0, dy0 = info["robot_pos"], info["robot_vel"]
        if np.ndim(y0) == 3:  # [E, k+1, D] step info: the state after the last sub-step
            y0, dy0 = y0[:, -1], dy0[:, -1]
    return (
        np.asarray(y0, dtype=np.float64).reshape(n, -1),
        np.asarray(dy0, dtype=np.float64).reshape(n, -1),
    )


def run_envs(cfg: TrainConfig, task: TaskHandle) -> tuple[gym.vector.VectorEnv, int]:
    """The training envs of an RL run and their observation size: ``cfg.num_envs`` chunked
    copies of ``task`` (:func:`make_vector_env`) with the run's k, stale-world rule, horizon,
    vector kind, workers and execution (``cfg``: a resolved ``TrainConfig``)."""
    envs = make_vector_env(task, cfg.k, cfg.num_envs, cfg.stale_world, cfg.horizon, cfg.vector,
                           cfg.env_workers, cfg.execution)  # fmt: skip
    shape = envs.single_observation_space.shape
    assert shape is not None  # a Box (ChunkedEnv's observation space is the task's)
    return envs, int(np.prod(shape))
