"""Our PPO (k = 1) against Stable-Baselines3's PPO: same tasks, seeds, budget, hyperparameters.

Both use the supplement's PPO settings (2048 env steps per update over 4 envs, 32 mini-batches,
10 epochs, clip 0.1, Adam 3e-4 / eps 1e-5, gamma 0.99, GAE 0.95, [100, 100] tanh, observation
and return normalisation) on the same per-step env; success is counted per env and per episode
in both (see ndp.experiments.sb3_ppo). Extra ``ndp rl train`` options for our PPO go after
``--`` (for example ``-- --clip-value-loss`` to measure the release's value clip). Runs are
resumable (ndp.experiments.study); re-running the command continues or re-plots.

Writes ``<out>.json`` / ``<out>.md`` / ``<out>.png``: success area and final success per task,
mean +- std over seeds, side by side, with the command, commit and date.

The issue's protocol (hours of CPU)::

    python benchmarks/ppo_vs_sb3.py --steps 150000 --seeds 0 1 2 --jobs 2 \
        --tasks reach-v3 push-v3 window-close-v3 drawer-open-v3 button-press-v3
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
from pathlib import Path

from ndp.experiments.provenance import git_commit
from ndp.experiments.study import Arm, markdown_table, plot, run_grid, summarise

TASKS = ["reach-v3", "push-v3", "window-close-v3", "drawer-open-v3", "button-press-v3"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", nargs="+", default=TASKS)
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--steps", type=int, default=150_000)
    p.add_argument("--jobs", type=int, default=1, help="runs at once (at most one per core)")
    p.add_argument("--vector", default=None, choices=("auto", "sync"),
                   help="vector env of each run (default: auto for one job, sync for several)")
    p.add_argument("--runs-dir", type=Path, default=Path("runs/ppo_vs_sb3"))
    p.add_argument("--label", default="ppo", help="label of our PPO arm (with extra options)")
    p.add_argument("--out", type=Path, default=Path("docs/results/ppo_vs_sb3"))
    p.add_argument("--plot-only", action="store_true")
    p.add_argument("extra", nargs="*", help="extra 'ndp rl train' options for our PPO, after --")
    args = p.parse_args(argv)
    arms = [Arm(args.label, "ppo", tuple(args.extra), "this package's PPO (k = 1)"),
            Arm("sb3-ppo", "sb3-ppo", (), "Stable-Baselines3 2.x PPO")]
    cmd = "python benchmarks/ppo_vs_sb3.py " + " ".join(argv if argv is not None else sys.argv[1:])
    if not args.plot_only:
        run_grid(args.tasks, arms, args.seeds, args.steps, args.runs_dir, args.jobs,
                 vector=args.vector)
    summary = summarise(args.tasks, arms, args.seeds, args.steps, args.runs_dir)
    summary.update(command=cmd, commit=git_commit(), date=dt.date.today().isoformat(),
                   runs_dir=str(args.runs_dir))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(summary, indent=1) + "\n")
    plot(summary, arms, args.out.with_suffix(".png"))
    lines = [f"# Our PPO vs SB3 PPO ({args.steps} env steps, seeds {args.seeds})", "",
             f"Command: `{cmd}`  ", f"Commit: {summary['commit']}, date: {summary['date']}; "
             f"runs in `{args.runs_dir}`. Our PPO options: "
             f"`{' '.join(args.extra) or '(defaults)'}`.",
             "", "Success area (success averaged over the budget; mean +- std over seeds):", "",
             *markdown_table(summary, arms, "area"), "",
             "Final success (last 10% of updates):", "", *markdown_table(summary, arms, "final"),
             "", f"![curves]({args.out.with_suffix('.png').name})", ""]
    args.out.with_suffix(".md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
