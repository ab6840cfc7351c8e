"""A vector env of chunked envs in worker processes, several envs per worker, shared memory.

:class:`WorkerVectorEnv` runs ``num_envs`` :class:`ndp.envs.ChunkedEnv` copies in ``workers``
subprocesses (env ``i`` lives in worker ``i * workers // num_envs``: contiguous slices). Actions,
observations and every per-step info array of the chunked env live in shared memory; a step
sends one short message per worker and waits for one reply, so the main process's cost per
step does not grow with the observation size. Each worker steps its envs one after the other
with one torch thread.

It behaves like gymnasium's ``SyncVectorEnv`` with ``AutoresetMode.SAME_STEP`` over the same
env factories (the trainer uses either): ``reset(seed=[...])`` seeds env i with ``seed[i]``;
when an episode ends, the returned observation and the info are the reset's (keys the reset
info lacks are 0 there), the finished step's whole info is under ``info["final_info"]`` and its
observation under ``info["final_obs"]``.
Given the same seeds and actions it returns the same arrays as the sync env (tested).

A worker's exception is re-raised in the main process with the worker's traceback; a worker
that dies (killed, segfault) raises :class:`WorkerError` naming it.
"""

from __future__ import annotations

import ctypes
import itertools
import multiprocessing as mp
import os
import traceback
from collections.abc import Callable, Mapping, Sequence
from multiprocessing.connection import Connection
from multiprocessing.context import BaseContext
from typing import Any, cast

import gymnasium as gym
import numpy as np
from numpy.typing import DTypeLike

from ndp.chunk_info import info_schema  # the step info's arrays, from its schema


def widen_info_arrays(
    vector_infos: dict[str, object], env_info: Mapping[str, object], n: int
) -> None:
    """Before gymnasium's ``_add_info`` adds env ``i``'s info to ``vector_infos``: an array
    [n, *s] that the info's value [*p, *s] (more leading axes) cannot be written into is
    widened to [n, *p, *s], each row repeated along the new axes (in place).

    A chunked env's reset info has ``robot_pos`` [D] where its step info has [k+1, D]; when an
    earlier env of a same-step-autoreset vector env has just reset, gymnasium sized the array
    from that reset. Widened, the reset rows hold the reset state k+1 times, as the worker env's
    shared arrays do (:class:`WorkerVectorEnv`).
    """
    for key, value in env_info.items():
        old = vector_infos.get(key)
        if not (isinstance(old, np.ndarray) and isinstance(value, np.ndarray)):
            continue
        row = old.shape[1:]
        extra = value.ndim - len(row)
        if old.dtype == object or extra <= 0 or value.shape[extra:] != row:
            continue
        grown = np.zeros((n, *value.shape), dtype=old.dtype)
        grown[:] = old.reshape((n,) + (1,) * extra + row)
        vector_infos[key] = grown


class SyncChunkedVectorEnv(gym.vector.SyncVectorEnv):
    """gymnasium's ``SyncVectorEnv`` whose info arrays take a reset's rows and a step's rows in
    any env order (:func:`widen_info_arrays`); the same arrays as :class:`WorkerVectorEnv`."""

    def _add_info(
        self, vector_infos: dict[str, Any], env_info: dict[str, Any], env_num: int
    ) -> dict[str, Any]:
        widen_info_arrays(vector_infos, env_info, self.num_envs)
        return super()._add_info(vector_infos, env_info, env_num)


class AsyncChunkedVectorEnv(gym.vector.AsyncVectorEnv):
    """gymnasium's ``AsyncVectorEnv`` with :class:`SyncChunkedVectorEnv`'s info arrays."""

    def _add_info(
        self, vector_infos: dict[str, Any], env_info: dict[str, Any], env_num: int
    ) -> dict[str, Any]:
        widen_info_arrays(vector_infos, env_info, self.num_envs)
        return super()._add_info(vector_infos, env_info, env_num)


class WorkerError(RuntimeError):
    """An env worker failed or died."""


class _Shared:
    """Named numpy arrays [E, ...] in one shared block (created, or attached in a worker).

    The block is a ``multiprocessing.RawArray`` handed to the workers at start: every numpy
    view keeps it alive, so no view can outlive its memory (a ``SharedMemory`` unmapped on
    close would leave dangling views).
    """

    def __init__(
        self,
        layout: dict[str, tuple[tuple[int, ...], DTypeLike]],
        raw: ctypes.Array[ctypes.c_byte] | None = None,
        ctx: BaseContext | None = None,
    ):
        self.layout = layout
        offsets, size = {}, 0
        for key, (shape, dtype) in layout.items():
            size = -(-size // 8) * 8  # 8-byte alignment
            offsets[key] = size
            size += int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize
        if raw is None:
            raw = (ctx or mp).RawArray("b", max(size, 8))
        self.raw = raw
        buf = memoryview(raw).cast("B")
        self.arrays = {
            key: np.frombuffer(
                buf, dtype=dtype, count=int(np.prod(shape, dtype=np.int64)), offset=offsets[key]
            ).reshape(shape)
            for key, (shape, dtype) in layout.items()
        }


def _layout(
    num_envs: int, obs_dim: int, k: int, action_dim: int, dof: int
) -> dict[str, tuple[tuple[int, ...], DTypeLike]]:
    """Name -> (shape, dtype) of the shared arrays of ``num_envs`` chunked envs."""
    lay: dict[str, tuple[tuple[int, ...], DTypeLike]] = {
        "actions": ((num_envs, k, action_dim), np.float64),
        "obs": ((num_envs, obs_dim), np.float64),
        "final_obs": ((num_envs, obs_dim), np.float64),
        "reward": ((num_envs,), np.float64),
        "terminated": ((num_envs,), np.bool_),
        "truncated": ((num_envs,), np.bool_),
    }
    for key, (shape, dtype) in info_schema(k, dof).items():
        lay[f"info/{key}"] = ((num_envs, *shape), dtype)
        lay[f"final/{key}"] = ((num_envs, *shape), dtype)
    return lay


class _Slice:
    """Envs ``lo .. lo + len(envs) - 1`` stepped in this process, writing to the shared arrays."""

    def __init__(self, envs: list[gym.Env], lo: int, arrays: dict[str, np.ndarray]) -> None:
        self.envs, self.lo, self.a = envs, lo, arrays
        self.info_keys = [key[5:] for key in arrays if key.startswith("info/")]

    def _write_info(self, prefix: str, i: int, info: dict[str, Any]) -> None:
        for key in self.info_keys:
            if key in info:
                self.a[f"{prefix}/{key}"][i] = info[key]

    def _write_reset(self, i: int, obs: np.ndarray, info: dict[str, Any]) -> None:
        for key in self.info_keys:
            self.a[f"info/{key}"][i] = 0
        self._write_info("info", i, info)
        self.a["obs"][i] = obs

    def step(self) -> None:
        a = self.a
        for j, env in enumerate(self.envs):
            i = self.lo + j
            obs, r, term, trunc, info = env.step(a["actions"][i])
            a["reward"][i], a["terminated"][i], a["truncated"][i] = r, term, trunc
            self._write_info("info", i, info)
            if term or trunc:
                a["final_obs"][i] = obs
                self._write_info("final", i, info)
                self._write_reset(i, *env.reset())
            else:
                a["obs"][i] = obs

    def reset(self, seeds: Sequence[int | None]) -> None:
        for j, env in enumerate(self.envs):
            self._write_reset(self.lo + j, *env.reset(seed=seeds[j]))

    def close(self) -> None:
        for env in self.envs:
            env.close()


def _worker(
    index: int,
    lo: int,
    hi: int,
    fns: Sequence[Callable[[], gym.Env]],
    raw: ctypes.Array[ctypes.c_byte],
    layout: dict[str, tuple[tuple[int, ...], DTypeLike]],
    conn: Connection,
) -> None:
    """Worker loop: own envs lo..hi-1, answer 'reset', 'step', 'spaces', 'close' over ``conn``."""
    try:
        import torch

        torch.set_num_threads(1)
        envs = [fn() for fn in fns]
        part = _Slice(envs, lo, _Shared(layout, raw).arrays)
        conn.send(("ready", None))
        while True:
            cmd, arg = conn.recv()
            if cmd == "step":
                part.step()
                conn.send(("ok", None))
            elif cmd == "reset":
                part.reset(arg)
                conn.send(("ok", None))
            elif cmd == "spaces":
                conn.send(("ok", (envs[0].observation_space, envs[0].action_space)))
            elif cmd == "close":
                part.close()
                conn.send(("ok", None))
                break
            else:
                raise ValueError(f"unknown command {cmd!r}")
    except (KeyboardInterrupt, EOFError):
        pass
    except BaseException as exc:  # report to the main process
        try:
            conn.send(("error", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"))
        except (BrokenPipeError, OSError):
            pass
    finally:
        conn.close()


def default_workers(num_envs: int) -> int:
    """One worker per core this process may use, at most one per env."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, num_envs))


class WorkerVectorEnv(gym.vector.VectorEnv):
    """``num_envs`` chunked envs in ``workers`` subprocesses (see the module docstring).

    Args:
        env_fns: one picklable factory per env, each returning a :class:`ChunkedEnv`.
        obs_dim: observation size O.
        k: sub-steps per decision.
        action_dim: A.
        dof: D, size of the robot state in the info.
        workers: slices of envs stepped in parallel (None: one per core, at most ``num_envs``).
        main_steps: the main process steps slice 0 itself (``workers - 1`` subprocesses);
            False: ``workers`` subprocesses and the main process only waits.
        context: multiprocessing start method ('spawn' is safe beside torch's threads).
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        obs_dim: int,
        k: int,
        action_dim: int,
        dof: int,
        workers: int | None = None,
        main_steps: bool = True,
        context: str = "spawn",
    ) -> None:
        n = len(env_fns)
        if n < 1:
            raise ValueError("env_fns: expected at least one env factory")
        w = default_workers(n) if workers is None else int(workers)
        if not 1 <= w <= n:
            raise ValueError(f"workers: expected 1..{n} (num_envs), got {workers!r}")
        self.num_envs = n
        self.num_workers = w
        self._layout = _layout(n, obs_dim, k, action_dim, dof)
        ctx = mp.get_context(context)
        self._shared = _Shared(self._layout, ctx=ctx)
        self._a = self._shared.arrays
        self._closed = False
        bounds = [i * n // w for i in range(w + 1)]
        self._slices = list(itertools.pairwise(bounds))
        self._local: _Slice | None = None
        if main_steps:
            import torch

            threads = torch.get_num_threads()  # env factories may set 1 (for workers)
            lo, hi = self._slices[0]
            self._local = _Slice([fn() for fn in env_fns[lo:hi]], lo, self._a)
            torch.set_num_threads(threads)
        self._remote = self._slices[1:] if main_steps else self._slices
        self._conns, self._procs = [], []
        for idx, (lo, hi) in enumerate(self._remote):
            parent, child = ctx.Pipe()
            # typeshed types get_context(str) as BaseContext, which lacks the Process that every
            # start method's context has
            proc = ctx.Process(  # type: ignore[attr-defined]
                target=_worker,
                name=f"ndp-env-worker-{idx}",
                daemon=True,
                args=(idx, lo, hi, list(env_fns[lo:hi]), self._shared.raw, self._layout, child),
            )
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)
        try:
            self._gather("ready")
        except WorkerError as exc:
            self.close()
            raise WorkerError(
                f"{exc} while starting. Workers start with the '{context}' method, which "
                "re-imports the main script: guard a script's entry point with "
                "`if __name__ == '__main__':`, or use vector='sync'."
            ) from None
        if self._local is not None:
            env0 = self._local.envs[0]
            obs_space, act_space = env0.observation_space, env0.action_space
        else:
            self._send_all("spaces", None)
            spaces_ = self._gather("spaces")[0]  # the worker's (observation, action) spaces
            obs_space, act_space = cast("tuple[gym.Space[Any], gym.Space[Any]]", spaces_)
        self.single_observation_space = obs_space
        self.single_action_space = act_space
        self.observation_space = gym.vector.utils.batch_space(obs_space, n)
        self.action_space = gym.vector.utils.batch_space(act_space, n)
        self.metadata = {"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP}

    # ------------------------------------------------------------------ plumbing
    def _send_all(self, cmd: str, args: object) -> None:
        for idx, conn in enumerate(self._conns):
            arg = args[idx] if isinstance(args, list) else args
            try:
                conn.send((cmd, arg))
            except (BrokenPipeError, OSError) as exc:
                raise self._dead(idx) from exc

    def _dead(self, idx: int) -> WorkerError:
        code = self._procs[idx].exitcode
        return WorkerError(
            f"env worker {self._name(idx)} died (exit code {code}); the vector "
            "env is unusable, close it and start again"
        )

    def _name(self, idx: int) -> str:
        """Worker name: its slice (slice 0 is the main process's when ``main_steps``)."""
        return str(idx + (1 if self._local is not None else 0))

    def _gather(self, what: str) -> list[object]:
        """Each worker's answer payload, in order; WorkerError naming the failed ones."""
        out: list[object] = []
        errors: list[str] = []
        for idx, conn in enumerate(self._conns):
            try:
                status, payload = conn.recv()
            except (EOFError, OSError) as exc:
                raise self._dead(idx) from exc
            if status == "error":
                errors.append(f"env worker {self._name(idx)} ({what}): {payload}")
            out.append(payload)
        if errors:
            raise WorkerError("\n".join(errors))
        return out

    def _infos(self, done: np.ndarray | None) -> dict[str, Any]:
        a = self._a
        infos: dict[str, Any] = {
            key[5:]: arr.copy() for key, arr in a.items() if key.startswith("info/")
        }
        if done is not None and done.any():
            infos["final_info"] = {
                key[6:]: arr.copy() for key, arr in a.items() if key.startswith("final/")
            }
            final_obs = np.empty(self.num_envs, dtype=object)
            for i in np.flatnonzero(done):
                final_obs[i] = a["final_obs"][i].copy()
            infos["final_obs"] = final_obs
        return infos

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | Sequence[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every env; ``seed``: one per env, or an int (env i gets seed + i)."""
        if self._closed:
            raise WorkerError("reset: the vector env is closed")
        if isinstance(seed, int):
            seeds: list[int | None] = [seed + i for i in range(self.num_envs)]
        elif seed is None:
            seeds = [None] * self.num_envs
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed: expected {self.num_envs} seeds, got {len(seeds)}")
        self._send_all("reset", [seeds[lo:hi] for lo, hi in self._remote])
        if self._local is not None:
            lo, hi = self._slices[0]
            self._local.reset(seeds[lo:hi])
        self._gather("reset")
        return self._a["obs"].copy(), self._infos(None)

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with its [k, A] actions (``actions`` [E, k, A])."""
        self.step_async(actions)
        return self.step_wait()

    def step_async(self, actions: np.ndarray) -> None:
        """Start a step of every env (``actions`` [E, k, A]); :meth:`step_wait` returns it. With
        ``main_steps=False`` this returns at once and the workers step while the caller works;
        else the main process's slice is stepped here first."""
        if self._closed:
            raise WorkerError("step: the vector env is closed")
        a = self._a
        acts = np.asarray(actions, dtype=np.float64)
        if acts.shape != a["actions"].shape:
            raise ValueError(f"actions: expected shape {a['actions'].shape}, got {acts.shape}")
        a["actions"][:] = acts
        self._send_all("step", None)
        if self._local is not None:  # slice 0 here while the workers step theirs
            try:
                self._local.step()
            except BaseException:
                try:  # leave the workers idle before raising this process's error
                    self._gather("step")
                except WorkerError:
                    pass
                raise

    def step_wait(
        self,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Wait for the step :meth:`step_async` started; returns it as :meth:`step` does
        (copies: the next step may start at once)."""
        a = self._a
        self._gather("step")
        term, trunc = a["terminated"].copy(), a["truncated"].copy()
        return (a["obs"].copy(), a["reward"].copy(), term, trunc, self._infos(term | trunc))

    def close(self, **kwargs: object) -> None:
        """Stop the workers and free the shared memory (idempotent)."""
        if self._closed:
            return
        self._closed = True
        for conn in self._conns:
            try:
                conn.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
        for conn in self._conns:
            try:
                if conn.poll(5):
                    conn.recv()
            except (EOFError, OSError):
                pass
            conn.close()
        for proc in self._procs:
            proc.join(timeout=5)
            if proc.is_alive():
                proc.terminate()
                proc.join(timeout=1)
        if self._local is not None:
            self._local.close()
            self._local = None

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass


StepResult = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]
"""One vector step's (observations, rewards, terminated, truncated, infos)."""


def concat_steps(parts: Sequence[StepResult]) -> StepResult:
    """The step of the envs of ``parts`` (consecutive env groups, each a same-step-autoreset
    :class:`WorkerVectorEnv`'s step) as one vector env's: arrays concatenated along the env
    axis; ``final_info`` / ``final_obs`` when an episode ended in any group (a group without
    one contributes zero rows / None, which no reader looks at: only the ended envs' rows are
    read)."""
    obs = np.concatenate([p[0] for p in parts])
    rew = np.concatenate([p[1] for p in parts])
    term = np.concatenate([p[2] for p in parts])
    trunc = np.concatenate([p[3] for p in parts])
    infos: dict[str, Any] = {
        key: np.concatenate([p[4][key] for p in parts])
        for key in parts[0][4]
        if key not in ("final_info", "final_obs")
    }
    ended = [p for p in parts if "final_info" in p[4]]
    if ended:
        ref = ended[0][4]["final_info"]
        fin: dict[str, Any] = {}
        for key, val in ref.items():
            rows = []
            for p in parts:
                own = p[4].get("final_info")
                rows.append(
                    own[key]
                    if own is not None
                    else np.zeros((len(p[1]), *val.shape[1:]), dtype=val.dtype)
                )
            fin[key] = np.concatenate(rows)
        infos["final_info"] = fin
        fobs = np.empty(len(rew), dtype=object)
        lo = 0
        for p in parts:
            n = len(p[1])
            if "final_obs" in p[4]:
                fobs[lo : lo + n] = p[4]["final_obs"]
            lo += n
        infos["final_obs"] = fobs
    return obs, rew, term, trunc, infos


class OverlapVectorEnv(gym.vector.VectorEnv):
    """``num_envs`` chunked envs in two groups (the first and the second half), each a
    :class:`WorkerVectorEnv` whose envs all step in worker processes: the on-policy trainer
    steps one group while it computes the other group's decision (``vector='overlap'``,
    :meth:`ndp.rl.onpolicy.trainer.Trainer.collect`).

    As a vector env (:meth:`reset`, :meth:`step`) it steps both groups at once and returns the
    same arrays as :class:`WorkerVectorEnv` over the same factories (tested); :attr:`groups`
    are the two halves for the interleaved rollout.

    Args:
        env_fns: one picklable factory per env (an even number, at least 2).
        obs_dim, k, action_dim, dof: as :class:`WorkerVectorEnv`'s.
        workers: worker processes in all (None: one per core); each group gets half (at
            least one).
        context: multiprocessing start method.
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        obs_dim: int,
        k: int,
        action_dim: int,
        dof: int,
        workers: int | None = None,
        context: str = "spawn",
    ) -> None:
        n = len(env_fns)
        if n < 2 or n % 2:
            raise ValueError(f"num_envs: the overlapped vector env needs an even number >= 2, "
                             f"got {n}")  # fmt: skip
        h = n // 2
        w = default_workers(n) if workers is None else int(workers)
        per = max(1, w // 2)
        self.num_envs = n
        self.bounds = ((0, h), (h, n))
        """The groups' env ranges [lo, hi)."""
        self.groups: list[WorkerVectorEnv] = []
        """The two groups (env rows ``bounds[g]``)."""
        try:
            for lo, hi in self.bounds:
                self.groups.append(
                    WorkerVectorEnv(
                        env_fns[lo:hi],
                        obs_dim,
                        k,
                        action_dim,
                        dof,
                        min(per, h),
                        main_steps=False,
                        context=context,
                    )
                )
        except BaseException:
            self.close()
            raise
        g0 = self.groups[0]
        self.single_observation_space = g0.single_observation_space
        self.single_action_space = g0.single_action_space
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, n)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, n)
        self.metadata = {"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP}

    def reset(
        self, *, seed: int | Sequence[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every env; ``seed``: one per env, or an int (env i gets seed + i)."""
        if seed is None:
            parts = [g.reset() for g in self.groups]
        else:
            seeds = (
                [seed + i for i in range(self.num_envs)] if isinstance(seed, int) else list(seed)
            )
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed: expected {self.num_envs} seeds, got {len(seeds)}")
            parts = [
                g.reset(seed=seeds[lo:hi])
                for g, (lo, hi) in zip(self.groups, self.bounds, strict=True)
            ]
        obs = np.concatenate([p[0] for p in parts])
        infos = {key: np.concatenate([p[1][key] for p in parts]) for key in parts[0][1]}
        return obs, infos

    def step(self, actions: np.ndarray) -> StepResult:
        """Step both groups at once (``actions`` [E, k, A])."""
        acts = np.asarray(actions, dtype=np.float64)
        for g, (lo, hi) in zip(self.groups, self.bounds, strict=True):
            g.step_async(acts[lo:hi])
        return concat_steps([g.step_wait() for g in self.groups])

    def close(self, **kwargs: object) -> None:
        """Stop both groups' workers (idempotent)."""
        for g in self.groups:
            g.close()
