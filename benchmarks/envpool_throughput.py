"""Env steps per second of the metaworld and EnvPool backends on push-v3 (random actions).

Prints one JSON object: for 1 and 4 envs, steps/s of

- ``raw``: the simulators themselves: metaworld's env class (N envs stepped in turn in this
  process) against ``envpool.make_gymnasium(num_envs=N)`` (one batched call per step;
  ``num_threads`` EnvPool's default);
- ``adapter``: the package's per-step envs, ``MetaWorldEnv`` and ``EnvPoolMetaWorldEnv``, N
  stepped in turn (what the trainer's sync vector env and each env worker run; built directly:
  ``--backend envpool`` itself refuses push-v3, which its equivalence check lists as differing);

and the envpool / metaworld ratio of each. Each measurement runs for ``--seconds`` of wall
time after a warm-up, with resets at the 150-step horizon counted in. Ratios are what to read:
the absolute numbers depend on the machine and on what else runs on it (``load_average``).

    python benchmarks/envpool_throughput.py [--seconds 4] [--out FILE]
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import time
from collections.abc import Callable
from importlib.metadata import version
from typing import Any

import numpy as np

TASK = "push-v3"
HORIZON = 150


def _timed(step: Callable[[], None], seconds: float, per_call: int) -> float:
    """Steps per second of ``step`` (``per_call`` env steps per call) over ``seconds``."""
    for _ in range(20):
        step()
    n, t0 = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - t0) < seconds:
        step()
        n += 1
    return n * per_call / elapsed


def raw_metaworld(n: int, seconds: float) -> float:
    """metaworld's own env class, ``n`` envs stepped in turn."""
    from metaworld.env_dict import ALL_V3_ENVIRONMENTS

    envs = []
    for i in range(n):
        env = ALL_V3_ENVIRONMENTS[TASK]()
        env._set_task_called = True
        env._freeze_rand_vec = False
        env.seeded_rand_vec = True
        env._partially_observable = False
        env.max_path_length = HORIZON
        env.reset(seed=i)
        envs.append(env)
    rng = np.random.default_rng(0)
    t = [0]

    def step() -> None:
        a = rng.uniform(-1, 1, (n, 4)).astype(np.float32)
        t[0] += 1
        for i, env in enumerate(envs):
            if t[0] % HORIZON == 0:
                env.reset()
            env.step(a[i])

    return _timed(step, seconds, n)


def raw_envpool(n: int, seconds: float) -> float:
    """``envpool.make_gymnasium(num_envs=n)``, one batched step call (auto-reset inside)."""
    import envpool

    env = envpool.make_gymnasium("MetaWorld/Push-v3", num_envs=n, seed=0,
                                 partially_observable=False, max_episode_steps=HORIZON)  # fmt: skip
    env.reset()
    rng = np.random.default_rng(0)

    def step() -> None:
        env.step(rng.uniform(-1, 1, (n, 4)).astype(np.float32))

    return _timed(step, seconds, n)


def adapter(backend: str, n: int, seconds: float) -> float:
    """The package's per-step env of ``backend``, ``n`` envs stepped in turn."""
    from ndp.envs.envpool_backend import EnvPoolMetaWorldEnv
    from ndp.envs.metaworld_env import MetaWorldEnv

    cls = EnvPoolMetaWorldEnv if backend == "envpool" else MetaWorldEnv
    envs = [cls(TASK, horizon=HORIZON) for _ in range(n)]
    for i, env in enumerate(envs):
        env.reset(seed=i)
    rng = np.random.default_rng(0)
    t = [0]

    def step() -> None:
        a = rng.uniform(-1, 1, (n, 4)).astype(np.float32)
        t[0] += 1
        for i, env in enumerate(envs):
            if t[0] % HORIZON == 0:
                env.reset()
            env.step(a[i])

    return _timed(step, seconds, n)


def machine() -> dict[str, Any]:
    """What the numbers were measured on."""
    cpu = "unknown"
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if "model name" in line)
    except (OSError, StopIteration):
        pass
    return {
        "cpu": cpu,
        "cores_usable": len(os.sched_getaffinity(0)),
        "load_average": os.getloadavg(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS"),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=4.0)
    p.add_argument("--note", default="")
    p.add_argument("--out", default=None, help="also write the JSON here")
    args = p.parse_args()
    rows: dict[str, Any] = {}
    for n in (1, 4):
        r = {
            "raw_metaworld": raw_metaworld(n, args.seconds),
            "raw_envpool": raw_envpool(n, args.seconds),
            "adapter_metaworld": adapter("metaworld", n, args.seconds),
            "adapter_envpool": adapter("envpool", n, args.seconds),
        }
        r["ratio_raw"] = r["raw_envpool"] / r["raw_metaworld"]
        r["ratio_adapter"] = r["adapter_envpool"] / r["adapter_metaworld"]
        rows[f"{n}_envs"] = {k: round(v, 3) for k, v in r.items()}
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True).stdout
    out = {
        "task": TASK,
        "unit": "env steps per second (ratio: envpool / metaworld)",
        "results": rows,
        "command": "python benchmarks/envpool_throughput.py "
        + " ".join(f"--{k} {v}" for k, v in vars(args).items() if v not in (None, "")),
        "commit": commit.strip(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "versions": {m: version(m) for m in ("envpool", "metaworld", "mujoco", "numpy")},
        "machine": machine(),
        "note": args.note,
    }
    text = json.dumps(out, indent=1)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
