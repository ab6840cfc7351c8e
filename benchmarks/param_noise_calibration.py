"""Calibrate NDP's parameter-space noise against the white-noise arm at initialisation.

The white-noise arm explores with a Gaussian of std exp(init_log_std) = 1 around each sub-action;
the executed action is that sample clipped to the action bounds. Parameter noise (``--param-noise``)
draws the DMP's raw parameters (goal, forcing weights) once per decision instead, and the k
sub-actions follow from the DMP. This script measures, for a freshly initialised policy (the
network as ``build_actor_critic`` makes it, the observation normaliser fitted to reset
observations), the std of the **executed** (clipped) sub-actions over noise draws, averaged over
observations, sub-steps and action dimensions, for the white arm and for parameter noise at a
grid of ``init_log_std``; it prints one JSON document with the grid and, per task and k, the
``init_log_std`` whose executed-action std is closest to the white arm's (interpolated on the
grid in log space). It does the same for the noise of a decision's summed displacement, where
white noise adds up as sqrt(k) and parameter noise, correlated over the decision, as up to k.

Usage: python benchmarks/param_noise_calibration.py [--tasks push-v3 throw] [--ks 5 10 20]
       [--out docs/results/param_noise_calibration/param_noise_calibration.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from ndp.experiments.provenance import git_commit
from ndp.io import atomic_write_text
from ndp.policies import build_actor_critic
from ndp.policies.config import PolicyConfig
from ndp.rl.config import TrainConfig, resolve_config
from ndp.rl.envs import decision_start as _robot_state
from ndp.rl.envs import resolve_task
from ndp.rl.normalize import ObsNormalizer

GRID = tuple(np.round(np.arange(-3.0, 0.51, 0.25), 2))
"""init_log_std values tried for the parameter noise."""


def _states(task: str, k: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, object]:
    """Observations [n, O], y0, dy0 [n, D] of ``n`` reset states, and the resolved config."""
    from ndp.envs import ChunkedEnv

    cfg = resolve_config(TrainConfig(task=task, algo="ndp", policy=PolicyConfig(k=k)))
    handle = resolve_task(cfg.task, **cfg.env_options())
    env = ChunkedEnv(handle.make(), k, **cfg.chunk_options())
    obs, ys, dys = [], [], []
    frame = cfg.policy.dmp_state or "measured"
    for seed in range(n):
        o, info = env.reset(seed=seed)
        y, dy = _robot_state({key: np.asarray(v)[None] for key, v in info.items()
                              if isinstance(v, np.ndarray)}, 1, frame)  # fmt: skip
        obs.append(o)
        ys.append(y[0])
        dys.append(dy[0])
    env.close()
    return np.array(obs), np.array(ys), np.array(dys), cfg


def executed_std(
    task: str, k: int, init_log_std: float | None, n: int, draws: int
) -> tuple[float, float]:
    """(per sub-action, per decision): the std of the executed (clipped) sub-actions over
    ``draws`` noise draws per observation, averaged over ``n`` reset observations, sub-steps and
    action dimensions; and the std of their sum over the decision (the displacement a decision's
    noise makes), averaged over observations and action dimensions. ``init_log_std`` None: the
    white arm (std 1 around each sub-action)."""
    obs, y0, dy0, cfg = _states(task, k, n)
    pol = cfg.policy  # type: ignore[attr-defined]
    if init_log_std is not None:
        pol = pol.updated(param_noise=True, init_log_std=float(init_log_std))
    spec = resolve_task(cfg.task).spec  # type: ignore[attr-defined]
    torch.manual_seed(0)
    model = build_actor_critic(obs.shape[1], spec, pol)
    norm = ObsNormalizer(obs.shape[1], 10.0, True)
    norm(obs, update=True)
    o = torch.from_numpy(norm(obs))
    low = torch.as_tensor(spec.action_low, dtype=torch.float32)
    high = torch.as_tensor(spec.action_high, dtype=torch.float32)
    gen = torch.Generator().manual_seed(1)
    with torch.no_grad():
        dist, _ = model.distribution(
            o.repeat(draws, 1),
            torch.as_tensor(y0, dtype=torch.float32).repeat(draws, 1),
            torch.as_tensor(dy0, dtype=torch.float32).repeat(draws, 1),
        )
        act = torch.maximum(torch.minimum(dist.actions(dist.sample(gen)), high), low)
    a = act.reshape(draws, n, *act.shape[1:]).numpy()  # [draws, n, k, A]
    return float(a.std(axis=0).mean()), float(a.sum(axis=2).std(axis=0).mean())


def _closest(grid: list[float], stds: list[float], target: float) -> float:
    """The init_log_std at which the measured std crosses ``target`` (linear interpolation on
    the grid; the grid's end where it never does)."""
    s = np.array(stds)
    for i in range(len(s) - 1):
        if (s[i] - target) * (s[i + 1] - target) <= 0 and s[i] != s[i + 1]:
            t = (target - s[i]) / (s[i + 1] - s[i])
            return float(grid[i] + t * (grid[i + 1] - grid[i]))
    return float(grid[int(np.argmin(np.abs(s - target)))])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tasks", nargs="+", default=["push-v3", "throw"])
    p.add_argument("--ks", nargs="+", type=int, default=[5, 10, 20])
    p.add_argument("--obs", type=int, default=32, help="reset observations per task")
    p.add_argument("--draws", type=int, default=256, help="noise draws per observation")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    t0 = time.time()
    out: dict[str, object] = {
        "benchmark": "param_noise_calibration",
        "command": "python benchmarks/param_noise_calibration.py " + " ".join(sys.argv[1:]),
        "commit": git_commit(),
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "grid": list(GRID),
        "results": [],
    }
    for task in args.tasks:
        for k in args.ks:
            white, white_d = executed_std(task, k, None, args.obs, args.draws)
            both = [executed_std(task, k, s, args.obs, args.draws) for s in GRID]
            stds, disp = [b[0] for b in both], [b[1] for b in both]
            out["results"].append(  # type: ignore[attr-defined]
                {
                    "task": task,
                    "k": k,
                    "white_executed_std": white,
                    "param_executed_std": stds,
                    "matching_init_log_std": _closest(list(GRID), stds, white),
                    "white_decision_displacement_std": white_d,
                    "param_decision_displacement_std": disp,
                    "matching_init_log_std_displacement": _closest(list(GRID), disp, white_d),
                }
            )
    out["seconds"] = round(time.time() - t0, 1)
    text = json.dumps(out, indent=1)
    if args.out is not None:
        atomic_write_text(args.out, text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
