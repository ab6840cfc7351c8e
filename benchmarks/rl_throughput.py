"""Training throughput (env steps/s) of PPO, PPO-multi and NDP vs raw env stepping and SB3 PPO.

In one run, on one task, with the same number of envs (sync, one process) and the same PPO
hyperparameters (2048 env steps per update, 32 mini-batches, 10 epochs, [100, 100] tanh,
observation and return normalisation):

- ``raw``: the per-step env stepped with uniform random actions in a plain loop (num_envs envs
  round-robin, resets included): the ceiling for any trainer;
- ``ndp`` / ``ppo`` / ``ppo-multi``: ``ndp.rl.trainer.Trainer.train`` for ``--steps`` env steps
  (setup excluded);
- ``sb3-ppo``: stable-baselines3 PPO (``DummyVecEnv`` + ``VecNormalize``) with the same
  hyperparameters on the same per-step env, ``learn(--steps)``.

Each measurement reports wall-clock and process-CPU rates (and, for this package's trainer, the
rollout-only rate: env steps / time spent collecting, i.e. without the PPO epochs); the CPU rate
is less sensitive to other processes sharing the machine. The methods are measured in
interleaved rounds (``--repeats``) and the median is reported. Ratios are against ``raw`` and
``sb3-ppo``.

Example::

    python benchmarks/rl_throughput.py --task reach-v3 --steps 8192 --repeats 2 \
        --out docs/results/rl_throughput
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ndp.experiments.provenance import git_commit

METHODS = ("raw", "ppo", "ppo-multi", "ndp", "sb3-ppo")


def bench_raw(task: str, steps: int, num_envs: int, seed: int) -> tuple[float, float]:
    from ndp.rl.envs import resolve_task

    h = resolve_task(task)
    envs = [h.make() for _ in range(num_envs)]
    for i, e in enumerate(envs):
        e.reset(seed=seed + i)
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(h.spec.action_low), np.asarray(h.spec.action_high)
    w0, c0 = time.perf_counter(), time.process_time()
    for i in range(steps):
        e = envs[i % num_envs]
        _, _, term, trunc, _ = e.step(rng.uniform(lo, hi).astype(np.float32))
        if term or trunc:
            e.reset()
    w, c = time.perf_counter() - w0, time.process_time() - c0
    for e in envs:
        e.close()
    return steps / w, steps / c


ROLLOUT: dict[str, list[float]] = {}
"""Per method: rollout-only wall rates (env steps / time in rollouts), from the run's CSV."""


def bench_ours(task: str, algo: str, steps: int, num_envs: int, seed: int) -> tuple[float, float]:
    from ndp.rl.config import TrainConfig
    from ndp.rl.logger import read_csv
    from ndp.rl.trainer import Trainer

    with tempfile.TemporaryDirectory() as tmp:
        tr = Trainer(TrainConfig(task=task, algo=algo, steps=steps, seed=seed,
                                 num_envs=num_envs, run_dir=str(Path(tmp) / "r"),
                                 progress=False, tensorboard=False))
        try:
            w0, c0 = time.perf_counter(), time.process_time()
            tr.train()
            w, c = time.perf_counter() - w0, time.process_time() - c0
            done = tr.global_step
            rows = read_csv(Path(tmp) / "r" / "progress.csv")
            ROLLOUT.setdefault(algo, []).append(done / sum(r["time/rollout_s"] for r in rows))
        finally:
            tr.close()
    return done / w, done / c


def bench_sb3(task: str, steps: int, num_envs: int, seed: int) -> tuple[float, float]:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from ndp.rl.envs import resolve_task

    torch.set_num_threads(1)
    h = resolve_task(task)
    venv = VecNormalize(DummyVecEnv([h.make for _ in range(num_envs)]), gamma=0.99)
    n_steps = 2048 // num_envs
    model = PPO(
        "MlpPolicy", venv, learning_rate=3e-4, n_steps=n_steps, batch_size=2048 // 32,
        n_epochs=10, gamma=0.99, gae_lambda=0.95, clip_range=0.1, ent_coef=0.0, vf_coef=0.5,
        max_grad_norm=0.5, seed=seed, device="cpu", verbose=0,
        policy_kwargs={"net_arch": {"pi": [100, 100], "vf": [100, 100]},
                       "activation_fn": torch.nn.Tanh, "optimizer_kwargs": {"eps": 1e-5}},
    )
    w0, c0 = time.perf_counter(), time.process_time()
    model.learn(total_timesteps=steps)
    w, c = time.perf_counter() - w0, time.process_time() - c0
    done = model.num_timesteps
    venv.close()
    return done / w, done / c


def measure(method: str, task: str, steps: int, num_envs: int, seed: int) -> tuple[float, float]:
    """(wall steps/s, CPU steps/s) of one method."""
    import torch

    torch.set_num_threads(1)
    if method == "raw":
        return bench_raw(task, steps, num_envs, seed)
    if method == "sb3-ppo":
        return bench_sb3(task, steps, num_envs, seed)
    return bench_ours(task, method, steps, num_envs, seed)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--task", default="reach-v3")
    p.add_argument("--steps", type=int, default=8192, help="env steps per measurement")
    p.add_argument("--num-envs", type=int, default=4)
    p.add_argument("--repeats", type=int, default=1, help="interleaved rounds (median)")
    p.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None, help="write <out>.json and <out>.md")
    args = p.parse_args(argv)
    samples: dict[str, list[tuple[float, float]]] = {m: [] for m in args.methods}
    for r in range(args.repeats):
        for m in args.methods:
            wall, cpu = measure(m, args.task, args.steps, args.num_envs, args.seed)
            samples[m].append((wall, cpu))
            print(f"round {r} {m:10s} wall {wall:8.1f} steps/s  cpu {cpu:8.1f} steps/s",
                  flush=True)
    res = {m: {"wall": statistics.median(s[0] for s in v),
               "cpu": statistics.median(s[1] for s in v)} for m, v in samples.items()}
    for m, v in res.items():
        if m in ROLLOUT:
            v["rollout_only_wall"] = statistics.median(ROLLOUT[m])
        for base in ("raw", "sb3-ppo"):
            if base in res and m != base:
                v[f"vs_{base}_wall"] = v["wall"] / res[base]["wall"]
                v[f"vs_{base}_cpu"] = v["cpu"] / res[base]["cpu"]
    cmd = "python benchmarks/rl_throughput.py " + " ".join(
        argv if argv is not None else sys.argv[1:])
    out = {"task": args.task, "steps": args.steps, "num_envs": args.num_envs,
           "repeats": args.repeats, "commit": git_commit(), "date": dt.date.today().isoformat(),
           "command": cmd, "results": res, "samples": samples}
    print(json.dumps(out["results"], indent=1))
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.with_suffix(".json").write_text(json.dumps(out, indent=1) + "\n")
        lines = [f"# RL training throughput on {args.task}", "",
                 f"Command: `{cmd}`  ", f"Commit: {out['commit']}, date: {out['date']}; "
                 f"{args.num_envs} sync envs, {args.steps} env steps per measurement, median "
                 f"of {args.repeats} interleaved round(s).", "",
                 "| method | wall steps/s | CPU steps/s | vs raw (wall / CPU) | "
                 "vs SB3 (wall / CPU) | rollout-only wall steps/s |", "|---|---|---|---|---|---|"]
        for m, v in res.items():
            def ratio(base: str, v: dict = v) -> str:
                if f"vs_{base}_wall" not in v:
                    return "-"
                return f"{v[f'vs_{base}_wall']:.2f} / {v[f'vs_{base}_cpu']:.2f}"
            ro = f"{v['rollout_only_wall']:.0f}" if "rollout_only_wall" in v else "-"
            lines.append(f"| {m} | {v['wall']:.0f} | {v['cpu']:.0f} | {ratio('raw')} | "
                         f"{ratio('sb3-ppo')} | {ro} |")
        args.out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
