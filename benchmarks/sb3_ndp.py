"""SB3's PPO with ``ndp.sb3.NDPPolicy`` against SB3's PPO with its ``MlpPolicy``, on one task.

Both arms run Stable-Baselines3's PPO on the same chunked env (``ndp.make_env(task, k)``: one
SB3 step is one decision of k env steps, its reward the sum of the k sub-step rewards) with
the same hyperparameters, seeds and budget; they differ in the policy only:

- ``ndp``: ``NDPPolicy`` on ``ndp.sb3.with_robot_state(env)``: the actor gives DMP goal and
  weights, the DMP (from the robot state) and the inverse controller give the k sub-actions;
- ``mlp``: ``MlpPolicy``: the actor gives the k * A sub-actions directly (SB3's PPO-multi).

Settings: 4 envs (``DummyVecEnv``), ``VecNormalize`` of observations (the ``obs`` entry only
for NDP: the DMP's start stays in physical units) and returns, SB3's default networks
([64, 64] tanh) and PPO settings except ``n_steps`` 128 decisions per env (512 per update),
``gamma`` 0.99 ** k (0.99 per env step), one torch thread. After training, the deterministic
policy runs ``--episodes`` episodes (seeds 10,000 on) with the normaliser frozen; the success
is the fraction with success at any step.

Writes ``<out>.json`` and ``<out>.md`` (per seed and mean +- std, with the command, commit and
date)::

    python benchmarks/sb3_ndp.py --task point-mass --steps 50000 --seeds 0 1 2
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

ARMS = ("ndp", "mlp")


def _venv(task: str, k: int, arm: str, seed: int, num_envs: int) -> Any:
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    import ndp
    import ndp.sb3

    def make() -> Any:
        env = ndp.make_env(task, k=k)
        return ndp.sb3.with_robot_state(env, task) if arm == "ndp" else env

    venv = DummyVecEnv([make for _ in range(num_envs)])
    venv.seed(seed)
    keys = ["obs"] if arm == "ndp" else None
    return VecNormalize(venv, gamma=0.99**k, norm_obs_keys=keys), make


def run_arm(task: str, k: int, arm: str, seed: int, steps: int, episodes: int) -> dict[str, Any]:
    """Train one arm for ``steps`` env steps; its deterministic success over ``episodes``."""
    import torch
    from stable_baselines3 import PPO

    import ndp.sb3

    torch.set_num_threads(1)
    num_envs = 4
    venv, make = _venv(task, k, arm, seed, num_envs)
    policy = ndp.sb3.NDPPolicy if arm == "ndp" else "MlpPolicy"
    model = PPO(policy, venv, n_steps=128, gamma=0.99**k, seed=seed, device="cpu", verbose=0)
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps // k)  # SB3 counts decisions
    wall = time.perf_counter() - t0
    venv.training = False  # frozen statistics for the evaluation
    env = make()
    succ, rets = [], []
    for ep in range(episodes):
        obs, info = env.reset(seed=10_000 + ep)
        done, ret = False, 0.0
        while not done:
            act, _ = model.predict(venv.normalize_obs(obs), deterministic=True)
            obs, r, term, trunc, info = env.step(act)
            ret += float(r)
            done = term or trunc
        succ.append(float(info["success_any"]))
        rets.append(ret)
    env.close()
    venv.close()
    return {
        "arm": arm,
        "seed": seed,
        "env_steps": int(model.num_timesteps) * k,
        "success": float(np.mean(succ)),
        "return": float(np.mean(rets)),
        "wall_s": wall,
    }


def _markdown(rows: list[dict[str, Any]], cmd: str, meta: dict[str, Any]) -> str:
    lines = [
        f"# SB3 PPO: NDPPolicy vs MlpPolicy on {meta['task']} (k = {meta['k']})",
        "",
        f"Command: `{cmd}`  ",
        f"Commit: {meta['commit']}, {meta['date']}, torch {meta['torch']}, "
        f"stable-baselines3 {meta['sb3']}, 1 thread, nice 10 on a shared 2-core machine.",
        "",
        f"Deterministic success over {meta['episodes']} episodes after {meta['steps']} env "
        "steps (mean return of those episodes; training wall time).",
        "",
        "| arm | seed | env steps | success | return | wall s |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['arm']} | {r['seed']} | {r['env_steps']} | {r['success']:.2f} | "
            f"{r['return']:.1f} | {r['wall_s']:.0f} |"
        )
    lines += ["", "| arm | success (mean +- std over seeds) | return |", "|---|---|---|"]
    for arm in ARMS:
        s = np.array([r["success"] for r in rows if r["arm"] == arm])
        g = np.array([r["return"] for r in rows if r["arm"] == arm])
        if len(s):
            lines.append(
                f"| {arm} | {s.mean():.2f} +- {s.std():.2f} | {g.mean():.1f} +- {g.std():.1f} |"
            )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--task", default="point-mass")
    p.add_argument("--k", type=int, default=5)
    p.add_argument("--steps", type=int, default=50_000, help="env steps per run")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--episodes", type=int, default=20)
    p.add_argument("--out", default="docs/results/sb3_ndp")
    args = p.parse_args(argv)
    import stable_baselines3
    import torch

    from ndp.provenance import git_commit

    rows = []
    for seed in args.seeds:
        for arm in ARMS:
            row = run_arm(args.task, args.k, arm, seed, args.steps, args.episodes)
            print(json.dumps(row), flush=True)
            rows.append(row)
    meta = {
        "task": args.task,
        "k": args.k,
        "steps": args.steps,
        "episodes": args.episodes,
        "commit": git_commit(),
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%d"),
        "torch": torch.__version__,
        "sb3": stable_baselines3.__version__,
    }
    cmd = "python benchmarks/sb3_ndp.py " + " ".join(argv if argv is not None else sys.argv[1:])
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1) + "\n")
    out.with_suffix(".md").write_text(_markdown(rows, cmd, meta))
    return 0


if __name__ == "__main__":
    sys.exit(main())
