"""WorkerVectorEnv: same arrays as gymnasium's SyncVectorEnv, worker errors and deaths reported."""

from __future__ import annotations

import functools
import os
import signal

import gymnasium as gym
import numpy as np
import pytest

from ndp.envs import get_task_spec
from ndp.envs.vector import WorkerVectorEnv, default_workers
from ndp.rl.envs import _make_chunked, resolve_task, step_info


def _fns(task: str, n: int, k: int, horizon: int):
    make = resolve_task(task).make
    return [functools.partial(_make_chunked, make, k, True, horizon) for _ in range(n)]


def _venv(task="point-mass", n=3, k=2, horizon=7, workers=2, main_steps=True):
    spec = get_task_spec(task)
    return WorkerVectorEnv(
        _fns(task, n, k, horizon),
        spec.obs_dim,
        k,
        spec.action_dim,
        spec.dmp_dofs,
        workers=workers,
        main_steps=main_steps,
    )


@pytest.mark.parametrize("workers,main_steps", [(2, True), (3, False)])
def test_worker_env_matches_sync_env_step_by_step(workers, main_steps):
    n, k, horizon = 3, 2, 7  # episodes end every 4 decisions (mid-decision at the horizon)
    sync = gym.vector.SyncVectorEnv(
        _fns("point-mass", n, k, horizon), autoreset_mode=gym.vector.AutoresetMode.SAME_STEP
    )
    work = _venv(n=n, k=k, horizon=horizon, workers=workers, main_steps=main_steps)
    try:
        assert work.num_workers == workers and len(work._procs) == workers - main_steps
        assert work.single_observation_space == sync.single_observation_space
        o1, i1 = sync.reset(seed=[3, 4, 5])
        o2, i2 = work.reset(seed=[3, 4, 5])
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(i1["cmd_y0"], i2["cmd_y0"])
        rng = np.random.default_rng(0)
        ends = 0
        for _ in range(12):
            act = rng.uniform(-1.5, 1.5, size=(n, k, 2))
            s1, s2 = sync.step(act), work.step(act)
            for x, y in zip(s1[:4], s2[:4], strict=True):
                np.testing.assert_array_equal(x, y)
            done = s1[2] | s1[3]
            ends += int(done.sum())
            for key in (
                "sub_rewards",
                "sub_mask",
                "success_any",
                "dmp_y0",
                "cmd_y0",
                "cmd_dy0",
                "n_substeps",
            ):
                np.testing.assert_array_equal(
                    step_info(s1[4], done, key), step_info(s2[4], done, key), err_msg=key
                )
                if key in s1[4]:  # (absent from sync's info when every env just reset)
                    np.testing.assert_array_equal(np.asarray(s1[4][key]), s2[4][key], err_msg=key)
            if done.any():
                for i in np.flatnonzero(done):
                    np.testing.assert_array_equal(s1[4]["final_obs"][i], s2[4]["final_obs"][i])
        assert ends >= 6
    finally:
        sync.close()
        work.close()
    work.close()  # idempotent


def test_worker_error_is_raised_with_its_traceback():
    work = _venv(main_steps=False)
    try:
        work.reset(seed=0)
        bad = np.zeros((3, 2, 2))
        bad[2] = np.nan  # env 2 lives in worker 1
        with pytest.raises(RuntimeError, match=r"env worker 1 \(step\).*finite"):
            work.step(bad)
    finally:
        work.close()
    local = _venv(main_steps=True)
    try:
        local.reset(seed=0)
        with pytest.raises(ValueError, match="finite"):  # slice 0: raised in this process
            local.step(np.full((3, 2, 2), np.nan))
    finally:
        local.close()


def test_dead_worker_is_reported():
    work = _venv()
    try:
        work.reset(seed=0)
        os.kill(work._procs[-1].pid, signal.SIGKILL)
        work._procs[-1].join(5)
        with pytest.raises(RuntimeError, match="env worker 1 died"):
            work.step(np.zeros((3, 2, 2)))
    finally:
        work.close()


def test_bad_arguments():
    with pytest.raises(ValueError, match="workers"):
        _venv(n=2, workers=3)
    work = _venv(n=2, workers=1)
    try:
        with pytest.raises(ValueError, match="actions"):
            work.step(np.zeros((2, 3, 2)))
        with pytest.raises(ValueError, match="seed"):
            work.reset(seed=[1])
    finally:
        work.close()
    assert 1 <= default_workers(8) <= 8


def test_sync_env_takes_a_reset_beside_a_step_in_any_env_order():
    """Env 0's episode ends (and it resets) while env 1 steps on: gymnasium's SyncVectorEnv
    sizes ``robot_pos`` from env 0's reset info ([D]) and cannot take env 1's step rows
    ([k+1, D]); ndp's sync env widens the array, the reset's rows repeated, as the worker env
    does (an early termination, e.g. the sparse reward's, hits this)."""
    from ndp.envs.vector import SyncChunkedVectorEnv

    k = 2
    make = resolve_task("point-mass").make
    fns = [functools.partial(_make_chunked, make, k, True, h) for h in (2, 7)]  # env 0 ends first
    mode = gym.vector.AutoresetMode.SAME_STEP
    plain = gym.vector.SyncVectorEnv(fns, autoreset_mode=mode)
    ours = SyncChunkedVectorEnv(fns, autoreset_mode=mode)
    spec = get_task_spec("point-mass")
    work = WorkerVectorEnv(fns, spec.obs_dim, k, spec.action_dim, spec.dmp_dofs, workers=1)
    try:
        for env in (plain, ours, work):
            env.reset(seed=[3, 4])
        act = np.full((2, k, 2), 0.3)
        with pytest.raises(ValueError, match="could not broadcast"):
            plain.step(act)
        s1, s2 = ours.step(act), work.step(act)
        assert s1[3].tolist() == [True, False]  # env 0 truncated at its horizon
        for x, y in zip(s1[:4], s2[:4], strict=True):
            np.testing.assert_array_equal(x, y)
        for key in ("robot_pos", "robot_vel", "dmp_y0", "sub_rewards", "n_substeps"):
            np.testing.assert_array_equal(s1[4][key], s2[4][key], err_msg=key)
            np.testing.assert_array_equal(
                s1[4]["final_info"][key], s2[4]["final_info"][key], err_msg=key
            )
        assert s1[4]["robot_pos"].shape == (2, k + 1, 2)
        np.testing.assert_array_equal(s1[4]["robot_pos"][0], np.tile(s1[4]["dmp_y0"][0], (3, 1)))
        _, info = ours.reset(seed=[3, 4])  # every env resets: the reset's own shapes, as before
        assert info["robot_pos"].shape == (2, 2)
    finally:
        for env in (plain, ours, work):
            env.close()
