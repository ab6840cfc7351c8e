"""Demonstration files: expert rollouts recorded per env step, in one documented ``.npz``.

Format (``ndp-demos`` version 1; S = recorded steps over all episodes, N = episodes, O = obs
size, A = action size, D = DMP-driven DoF of the task):

    obs         float32 [S, O]  observation before the step's action
    actions     float32 [S, A]  the action taken, in [-1, 1]
    rewards     float32 [S]     the env's reward of the step
    success     bool    [S]     success after the step
    episode     int64   [S]     episode index 0..N-1 (steps of an episode are contiguous)
    robot_pos   float64 [S, D]  measured robot state before the step (physical units)
    robot_vel   float64 [S, D]
    cmd_pos     float64 [S, D]  commanded state before the step (mocap / joint targets; equals
    cmd_vel     float64 [S, D]  the measured state for tasks without a command)
    seeds       int64   [N]     reset seed of each episode (goals drawn from the task's seeded
                                distribution, as in RL runs)
    episode_success bool [N]    success at any step of the episode
    meta        str             JSON: format, version, task, horizon, expert, command line

Users' own demonstrations load the same way (``load_demos``); the arrays above are required.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ndp.bc.experts import expert_for
from ndp.checks import check_int
from ndp.chunk_info import dmp_start
from ndp.io import atomic_save_npz

if TYPE_CHECKING:
    from ndp.bc.experts import Expert
    from ndp.envs import ChunkedEnv
    from ndp.envs.base import NDPEnv

DEMO_FORMAT = "ndp-demos"
DEMO_VERSION = 1
_REQUIRED = {
    "obs": 2,
    "actions": 2,
    "rewards": 1,
    "success": 1,
    "episode": 1,
    "robot_pos": 2,
    "robot_vel": 2,
    "cmd_pos": 2,
    "cmd_vel": 2,
    "seeds": 1,
    "episode_success": 1,
}
"""Array name -> number of dimensions."""


@dataclass(frozen=True)
class Demos:
    """Recorded demonstrations (shapes in the module docstring)."""

    task: str
    obs: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    success: np.ndarray
    episode: np.ndarray
    robot_pos: np.ndarray
    robot_vel: np.ndarray
    cmd_pos: np.ndarray
    cmd_vel: np.ndarray
    seeds: np.ndarray
    episode_success: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def n_episodes(self) -> int:
        return len(self.seeds)

    def first(self, n: int) -> Demos:
        """The first ``n`` episodes."""
        if not 1 <= n <= self.n_episodes:
            raise ValueError(f"n: expected 1..{self.n_episodes} episodes, got {n}")
        keep = self.episode < n
        return Demos(
            self.task,
            **{k: getattr(self, k)[keep] for k in _STEP_ARRAYS},
            seeds=self.seeds[:n],
            episode_success=self.episode_success[:n],
            meta=dict(self.meta),
        )


_STEP_ARRAYS = ("obs", "actions", "rewards", "success", "episode", "robot_pos", "robot_vel",
                "cmd_pos", "cmd_vel")  # fmt: skip


def collect(
    task: str,
    episodes: int,
    seed: int = 0,
    keep_failures: bool = False,
    horizon: int | None = None,
    max_attempts: int | None = None,
) -> Demos:
    """Roll out the task's scripted expert (:func:`ndp.bc.experts.expert_for`).

    Episode ``i`` (counting attempts) resets with seed ``seed + i``; unless ``keep_failures``,
    only successful episodes are kept, until ``episodes`` are recorded.

    Raises:
        ValueError: bad arguments, or fewer successful episodes than asked within
            ``max_attempts`` (default ``3 * episodes + 10``).
    """
    from ndp.envs import ChunkedEnv, make_env
    from ndp.envs.spec import get_task_spec

    check_int("episodes", episodes, 1)
    spec = get_task_spec(task)
    expert = expert_for(spec.name)
    env = ChunkedEnv(make_env(spec.name, horizon=horizon), k=1, stale_world=False)
    attempts = max_attempts if max_attempts is not None else 3 * episodes + 10
    rows: dict[str, list[object]] = {k: [] for k in _STEP_ARRAYS}
    seeds: list[int] = []
    ep_success: list[bool] = []
    try:
        for attempt in range(attempts):
            if len(seeds) == episodes:
                break
            ep, any_success = _record_episode(env, expert, seed + attempt)
            if any_success or keep_failures:
                ep["episode"] = [len(seeds)] * len(ep["obs"])
                for k in _STEP_ARRAYS:
                    rows[k].extend(ep[k])
                seeds.append(seed + attempt)
                ep_success.append(any_success)
    finally:
        env.close()
    if len(seeds) < episodes:
        raise ValueError(
            f"episodes: the expert of {spec.name} succeeded in {len(seeds)} of {attempts} "
            f"attempts, fewer than the {episodes} asked (use keep_failures to record failures)"
        )
    meta = {
        "format": DEMO_FORMAT,
        "version": DEMO_VERSION,
        "task": spec.name,
        "horizon": horizon or spec.horizon,
        "expert": type(expert).__name__,
        "seed": seed,
        "keep_failures": keep_failures,
    }
    return _demos_from_rows(spec.name, rows, seeds, ep_success, meta)


def _record_episode(
    env: ChunkedEnv, expert: Expert, seed: int
) -> tuple[dict[str, list[object]], bool]:
    """One expert episode reset with ``seed``: per-step rows and whether it ever succeeded."""
    base = cast("NDPEnv", env.unwrapped)  # a task family's env (ndp.envs.base)
    obs, info = env.reset(seed=seed)
    expert.reset(base, obs, info)
    ep: dict[str, list[object]] = {k: [] for k in _STEP_ARRAYS}
    any_success = False
    while True:
        a = np.asarray(expert.act(base, obs, info), dtype=np.float64)
        ep["obs"].append(np.asarray(obs, dtype=np.float32))
        ep["actions"].append(a.astype(np.float32))
        frames = (
            ("measured", "robot_pos", "robot_vel"),
            ("commanded", "cmd_pos", "cmd_vel"),
        )
        for frame, kp, kv in frames:
            y0, dy0 = dmp_start(info, frame)
            ep[kp].append(y0)
            ep[kv].append(dy0)
        obs, r, term, trunc, info = env.step(a[None])
        ep["rewards"].append(np.float32(r))
        ep["success"].append(bool(info["success"]))
        any_success |= bool(info["success"])
        if term or trunc:
            return ep, any_success


def _demos_from_rows(
    task: str,
    rows: dict[str, list[object]],
    seeds: list[int],
    ep_success: list[bool],
    meta: dict[str, object],
) -> Demos:
    """Stack the recorded per-step rows into a :class:`Demos` with the documented dtypes."""
    arrays = {k: np.asarray(v) for k, v in rows.items()}
    return Demos(
        task,
        arrays["obs"].astype(np.float32),
        arrays["actions"].astype(np.float32),
        arrays["rewards"].astype(np.float32),
        arrays["success"].astype(bool),
        arrays["episode"].astype(np.int64),
        **{
            k: arrays[k].astype(np.float64)
            for k in ("robot_pos", "robot_vel", "cmd_pos", "cmd_vel")
        },
        seeds=np.asarray(seeds, dtype=np.int64),
        episode_success=np.asarray(ep_success, dtype=bool),
        meta=meta,
    )


def save_demos(demos: Demos, path: str | Path) -> Path:
    """Write ``demos`` to ``path`` (.npz, atomically)."""
    path = Path(path)
    meta = {**demos.meta, "format": DEMO_FORMAT, "version": DEMO_VERSION, "task": demos.task}
    arrays = {k: getattr(demos, k) for k in _REQUIRED}
    atomic_save_npz(path, meta=np.asarray(json.dumps(meta)), **arrays)
    return path


def load_demos(path: str | Path) -> Demos:
    """Read and validate a demonstrations file.

    Raises:
        FileNotFoundError: no such file.
        ValueError: unreadable, a missing or misshaped array, NaN / Inf, actions outside
            [-1, 1], or inconsistent episodes (one line naming the field).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"demos: no such file {path}")
    try:
        z = np.load(path, allow_pickle=False)
        files = set(z.files)
    except Exception as exc:  # numpy raises several types for garbage
        raise ValueError(f"demos: cannot read {path} ({type(exc).__name__}: {exc})") from None
    for name, ndim in (*_REQUIRED.items(), ("meta", 0)):
        if name not in files:
            raise ValueError(f"demos: {path} has no array {name!r} (see ndp.bc.demos)")
        if z[name].ndim != ndim:
            raise ValueError(
                f"{name}: expected {ndim} dimensions in {path}, got shape {z[name].shape}"
            )
    try:
        meta = json.loads(str(z["meta"]))
    except json.JSONDecodeError:
        raise ValueError(f"meta: {path} holds no JSON metadata") from None
    task = meta.get("task")
    if not isinstance(task, str):
        raise ValueError(f"meta: {path} names no task")
    s = len(z["obs"])
    for name in _STEP_ARRAYS:
        if len(z[name]) != s:
            raise ValueError(
                f"{name}: expected {s} rows (one per step) in {path}, got {len(z[name])}"
            )
        if z[name].dtype.kind == "f" and not np.isfinite(z[name]).all():
            raise ValueError(f"{name}: NaN or Inf in {path}")
    if s == 0:
        raise ValueError(f"obs: {path} holds no steps")
    if np.abs(z["actions"]).max() > 1.0 + 1e-6:
        raise ValueError(f"actions: expected values in [-1, 1] in {path}")
    ep = z["episode"]
    n = len(z["seeds"])
    if len(z["episode_success"]) != n or ep.min() < 0 or ep.max() >= n or np.any(np.diff(ep) < 0):
        raise ValueError(f"episode: expected contiguous indices 0..{n - 1} in {path}")
    return Demos(
        task,
        **{k: np.asarray(z[k]) for k in _STEP_ARRAYS},
        seeds=np.asarray(z["seeds"]),
        episode_success=np.asarray(z["episode_success"]).astype(bool),
        meta=meta,
    )
