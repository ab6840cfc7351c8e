"""Learning benchmark: NDP vs PPO vs PPO-multi, success vs env steps, several tasks and seeds.

Every (task, method, seed) run is an ordinary ``ndp rl train`` run under ``--runs-dir``; a run
that was interrupted is resumed, a finished one is reused, so the script can be re-run to extend
or re-plot. Success is the training episodes' success (any step of the episode, stochastic
policy), as logged in ``charts/success_any``. At the end the script writes

- ``<out>.png``: success vs env steps (mean +- std over seeds, smoothed), one panel per task;
- ``<out>.json``: every curve and the table;
- ``<out>.md``: the table of success at the budget (mean +- std over seeds of the mean of the
  last 10% of each run's updates) with the command, the commit and the date.

Example (the issue's full protocol; days of CPU time)::

    python benchmarks/rl_learning.py --steps 500000 --seeds 0 1 2 \
        --tasks reach-v3 push-v3 soccer-v3 faucet-open-v3

A short run that fits in a development session::

    python benchmarks/rl_learning.py --steps 100000 --seeds 0 --tasks reach-v3 push-v3
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from ndp.experiments.provenance import git_commit

ALGOS = ("ndp", "ppo", "ppo-multi")


def run_one(task: str, algo: str, seed: int, steps: int, runs_dir: Path, num_envs: int,
            extra: list[str]) -> Path:
    """Train (or resume / reuse) one run in a subprocess; returns its directory."""
    from ndp.rl.checkpoint import CHECKPOINT_NAME, load_checkpoint
    from ndp.rl.config import TrainConfig

    run = runs_dir / f"{task}-{algo}-s{seed}"
    ckpt = run / CHECKPOINT_NAME
    if ckpt.is_file():
        state = load_checkpoint(ckpt)
        cfg = TrainConfig.from_dict(state["config"])
        if cfg.steps != steps:
            raise ValueError(f"{run} was trained with --steps {cfg.steps}, not {steps}; "
                             "use another --runs-dir")
        if state["update"] >= cfg.num_updates:
            return run
        cmd = [sys.executable, "-m", "ndp.cli", "rl", "train", "--resume", str(run),
               "--no-progress"]
    else:
        cmd = [sys.executable, "-m", "ndp.cli", "rl", "train", "--task", task, "--algo", algo,
               "--seed", str(seed), "--steps", str(steps), "--num-envs", str(num_envs),
               "--stale-world", "--run-dir", str(run), "--no-progress", *extra]
    t0 = time.time()
    subprocess.run(cmd, check=True)
    print(f"[{task} {algo} s{seed}] {time.time() - t0:.0f}s", flush=True)
    return run


def load_curve(run: Path, key: str = "charts/success_any") -> tuple[np.ndarray, np.ndarray]:
    """(global_step [U], metric [U]) of a run (updates without finished episodes dropped)."""
    from ndp.rl.logger import read_csv

    rows = read_csv(run / "progress.csv")
    x = np.array([r["global_step"] for r in rows])
    y = np.array([r[key] for r in rows])
    keep = ~np.isnan(y)
    return x[keep], y[keep]


def _return_key(run: Path) -> str:
    """The live-world return column if the run logged it, else the trained return."""
    with (run / "progress.csv").open() as f:
        header = f.readline()
    live = "charts/episode_return_live"
    return live if live in header.split(",") else "charts/episode_return"


def smooth(y: np.ndarray, window: int) -> np.ndarray:
    """Trailing moving average."""
    if len(y) == 0:
        return y
    c = np.cumsum(np.insert(y, 0, 0.0))
    out = np.empty_like(y)
    for i in range(len(y)):
        lo = max(0, i + 1 - window)
        out[i] = (c[i + 1] - c[lo]) / (i + 1 - lo)
    return out


def summarise(tasks, algos, seeds, steps, runs_dir: Path, out: Path, cmdline: str) -> dict:
    """Aggregate curves and the table, write PNG / JSON / Markdown."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grid = np.linspace(0, steps, 51)
    result: dict = {"steps": steps, "seeds": list(seeds), "tasks": {}, "commit": git_commit(),
                    "date": dt.date.today().isoformat(), "command": cmdline}
    used_keys: set[str] = set()
    fig, axes = plt.subplots(2, len(tasks), figsize=(4.2 * len(tasks), 6.4), squeeze=False)
    for col, task in enumerate(tasks):
        ax, ax_ret = axes[0][col], axes[1][col]
        result["tasks"][task] = {}
        for algo in algos:
            curves, rcurves, finals, rets, aucs = [], [], [], [], []
            for seed in seeds:
                run = runs_dir / f"{task}-{algo}-s{seed}"
                if not (run / "progress.csv").is_file():
                    continue
                x, y = load_curve(run)
                if len(x) == 0:
                    continue
                w = max(1, len(y) // 20)
                curves.append(np.interp(grid, x, smooth(y, w), left=np.nan))
                tail = y[int(len(y) * 0.9):] if len(y) >= 10 else y[-1:]
                finals.append(float(np.mean(tail)))
                # sample efficiency: success averaged over the budget (area under the curve)
                aucs.append(float(np.trapezoid(np.interp(grid, x, y, left=0.0), grid) / steps))
                xr, ret = load_curve(run, _return_key(run))
                used_keys.add(_return_key(run))
                rcurves.append(np.interp(grid, xr, smooth(ret, w), left=np.nan))
                rets.append(float(np.mean(ret[int(len(ret) * 0.9):] if len(ret) >= 10
                                          else ret[-1:])))
            if not curves:
                continue
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # grid points before 1st update
                mean, std = np.nanmean(curves, 0), np.nanstd(curves, 0)
                rmean, rstd = np.nanmean(rcurves, 0), np.nanstd(rcurves, 0)
            ax.plot(grid, mean, label=algo)
            ax.fill_between(grid, mean - std, mean + std, alpha=0.2)
            ax_ret.plot(grid, rmean, label=algo)
            ax_ret.fill_between(grid, rmean - rstd, rmean + rstd, alpha=0.2)
            result["tasks"][task][algo] = {
                "n_seeds": len(finals), "final_mean": float(np.mean(finals)),
                "final_std": float(np.std(finals)), "finals": finals,
                "return_mean": float(np.mean(rets)), "return_std": float(np.std(rets)),
                "auc_mean": float(np.mean(aucs)), "auc_std": float(np.std(aucs)),
                "curve_steps": grid.tolist(), "curve_mean": mean.tolist(),
                "curve_std": std.tolist(), "return_curve_mean": rmean.tolist(),
            }
        ax.set_title(task)
        ax.set_ylim(-0.02, 1.02)
        ax_ret.set_xlabel("env steps")
        for a in (ax, ax_ret):
            a.grid(alpha=0.3)
    axes[1][0].set_ylabel("episode return (training)")
    axes[0][0].set_ylabel("success (any step, training episodes)")
    axes[0][-1].legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out.with_suffix(".png"), dpi=60)
    out.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    lines = [
        f"# RL learning benchmark ({steps} env steps, seeds {list(seeds)})", "",
        f"Command: `{cmdline}`  ", f"Commit: {result['commit']}, date: {result['date']}.", "",
        "Success = mean `charts/success_any` over the last 10% of updates (training episodes, "
        "stochastic policy); mean +- std over seeds.", "",
        "| task | " + " | ".join(algos) + " |", "|---" * (len(algos) + 1) + "|",
    ]
    for task in tasks:
        cells = []
        for algo in algos:
            r = result["tasks"][task].get(algo)
            cells.append("-" if r is None else
                         f"{r['final_mean']:.2f} +- {r['final_std']:.2f} (n={r['n_seeds']})")
        lines.append(f"| {task} | " + " | ".join(cells) + " |")
    lines += ["", "Sample efficiency: success averaged over the whole budget (area under the raw "
              "success curve / budget), mean +- std over seeds:", "",
              "| task | " + " | ".join(algos) + " |", "|---" * (len(algos) + 1) + "|"]
    for task in tasks:
        cells = []
        for algo in algos:
            r = result["tasks"][task].get(algo)
            cells.append("-" if r is None else f"{r['auc_mean']:.2f} +- {r['auc_std']:.2f}")
        lines.append(f"| {task} | " + " | ".join(cells) + " |")
    note = ("live-world reward (`charts/episode_return_live`)"
            if used_keys == {"charts/episode_return_live"} else
            "the reward each method trains with (`charts/episode_return`: stale-world rule for "
            "NDP and PPO-multi, live for PPO; runs logged before the live column existed)"
            if used_keys == {"charts/episode_return"} else
            "live-world reward where logged, else the trained reward (mixed runs)")
    lines += ["", f"Episode return over the last 10% of updates, {note} (mean +- std over "
              "seeds):", "",
              "| task | " + " | ".join(algos) + " |", "|---" * (len(algos) + 1) + "|"]
    for task in tasks:
        cells = []
        for algo in algos:
            r = result["tasks"][task].get(algo)
            cells.append("-" if r is None else f"{r['return_mean']:.0f} +- {r['return_std']:.0f}")
        lines.append(f"| {task} | " + " | ".join(cells) + " |")
    lines += ["", f"![curves]({out.with_suffix('.png').name})", ""]
    out.with_suffix(".md").write_text("\n".join(lines))
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", nargs="+",
                   default=["reach-v3", "push-v3", "soccer-v3", "faucet-open-v3"])
    p.add_argument("--algos", nargs="+", default=list(ALGOS), choices=ALGOS)
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--steps", type=int, default=500_000, help="env-step budget per run")
    p.add_argument("--num-envs", type=int, default=4)
    p.add_argument("--runs-dir", type=Path, default=Path("runs/rl_learning"))
    p.add_argument("--out", type=Path, default=Path("docs/rl_learning"),
                   help="output stem: <out>.png, <out>.json, <out>.md")
    p.add_argument("--plot-only", action="store_true", help="only aggregate existing runs")
    p.add_argument("extra", nargs="*", help="extra 'ndp rl train' options after --")
    args = p.parse_args(argv)
    cmdline = "python benchmarks/rl_learning.py " + " ".join(
        argv if argv is not None else sys.argv[1:])
    if not args.plot_only:
        for task in args.tasks:
            for seed in args.seeds:
                for algo in args.algos:
                    run_one(task, algo, seed, args.steps, args.runs_dir, args.num_envs,
                            args.extra)
    res = summarise(args.tasks, args.algos, args.seeds, args.steps, args.runs_dir, args.out,
                    cmdline)
    for task, algos in res["tasks"].items():
        for algo, r in algos.items():
            if not math.isnan(r["final_mean"]):
                print(f"{task:16s} {algo:10s} {r['final_mean']:.2f} +- {r['final_std']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
