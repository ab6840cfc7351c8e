"""Env speed: steps/s of the raw env and of ChunkedEnv (k = 5, stale rule on); prints JSON.

Usage: ``MUJOCO_GL=egl python benchmarks/env_speed.py [--steps 1500] [--tasks reach-v3 ...]``

Steps are env steps (sub-steps) per second, with uniform random actions from a fixed seed;
episodes are reset when they end (resets are included in the time). Raw and chunked timings are
interleaved and the best of ``--repeats`` is kept, because timings on a shared machine are noisy.
``overhead`` is ``raw_steps_per_s / chunked_steps_per_s - 1`` (target <= 0.10).

Torque-actuated variants (the VICES baseline, ``ndp.envs.torque``; ``--no-torque`` skips them):
for every task with one, its rows (Meta-World ``<task>-osc``; Jaco ``<task>-joint`` and
``<task>-osc``) are timed raw beside the position-controlled env, interleaved, best of N;
``step_time_ratio`` is their step time over the position env's (target <= 1.5: the impedance
controller runs at every simulator step, with the Jacobian and mass matrix from MuJoCo).
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np
import torch

from ndp.envs import ChunkedEnv, make_env


def _time_raw(name: str, steps: int, seed: int) -> float:
    env = make_env(name)
    rng = np.random.default_rng(seed)
    acts = rng.uniform(-1, 1, size=(steps, env.action_space.shape[0]))
    env.reset(seed=seed)
    t0 = time.perf_counter()
    for a in acts:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return steps / (time.perf_counter() - t0)


def _time_chunked(name: str, steps: int, seed: int, k: int) -> float:
    env = ChunkedEnv(make_env(name), k=k, stale_world=True)
    rng = np.random.default_rng(seed)
    acts = rng.uniform(-1, 1, size=(steps // k, k, env.action_space.shape[1]))
    env.reset(seed=seed)
    done_steps = 0
    t0 = time.perf_counter()
    for a in acts:
        _, _, term, trunc, info = env.step(a)
        done_steps += info["n_substeps"]
        if term or trunc:
            env.reset()
    return done_steps / (time.perf_counter() - t0)


def torque_rows(name: str) -> list[str]:
    """The torque-actuated rows timed beside ``name`` (none for tasks without them)."""
    from ndp.envs import get_task_spec, torque_variant

    spec = get_task_spec(name)
    if spec.family == "metaworld":
        return [torque_variant(spec, space="osc").name]
    if spec.family == "jaco":
        return [torque_variant(spec, space=s).name for s in ("joint", "osc")]
    return []


def main() -> None:
    """Run the benchmark and print one JSON object."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--steps", type=int, default=1500)
    p.add_argument("--k", type=int, default=5)
    p.add_argument("--repeats", type=int, default=5, help="best of N timings per mode")
    p.add_argument("--tasks", nargs="+", default=["reach-v3", "push-v3", "throw", "pick"])
    p.add_argument("--no-torque", action="store_true", help="skip the torque-actuated rows")
    args = p.parse_args()
    torch.set_num_threads(1)
    results = {}
    for name in args.tasks:
        raw = chunked = 0.0
        rows = [] if args.no_torque else torque_rows(name)
        torque = dict.fromkeys(rows, 0.0)
        for _ in range(args.repeats):  # interleaved, best of N: the machine is shared
            raw = max(raw, _time_raw(name, args.steps, 0))
            chunked = max(chunked, _time_chunked(name, args.steps, 0, args.k))
            for row in rows:
                torque[row] = max(torque[row], _time_raw(row, args.steps, 0))
        results[name] = {
            "raw_steps_per_s": round(raw, 1),
            "chunked_steps_per_s": round(chunked, 1),
            "overhead": round(raw / chunked - 1.0, 4),
        }
        if torque:
            results[name]["torque"] = {
                row: {"steps_per_s": round(v, 1), "step_time_ratio": round(raw / v, 3)}
                for row, v in torque.items()
            }
    print(
        json.dumps(
            {
                "benchmark": "env_speed",
                "k": args.k,
                "stale_world": True,
                "steps": args.steps,
                "repeats": args.repeats,
                "machine": platform.processor() or platform.machine(),
                "results": results,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
