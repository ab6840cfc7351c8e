"""Learning comparison: NDP vs PPO vs PPO-multi, success vs env steps, several tasks and seeds.

Every (task, method, seed) run is an ordinary ``ndp rl train`` run in
``<runs-dir>/<task>-<method>-s<seed>`` (ndp.experiments.study): an interrupted run is resumed,
a finished one reused, so the command can be re-run to extend or re-plot. Every method gets the
same budget, seeds, PPO settings and evaluation; extra ``ndp rl train`` options after ``--`` go
to all three alike (e.g. ``-- --init-log-std -0.7``). Success is the training episodes' success
at any step (stochastic policy, ``charts/success_any``). Writes ``<out>.json``, ``<out>.md`` (the
tables: success area = the success curve averaged over the budget, and final success = the mean
of the last 10% of updates, mean +- std over seeds, with the command, commit and date) and
``<out>.png`` (curves).

The issue's protocol (days of CPU on 2 cores; resumable)::

    python benchmarks/rl_learning.py --steps 300000 --seeds 0 1 2 \
        --tasks push-v3 soccer-v3 faucet-open-v3 throw pick reach-v3
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
from pathlib import Path

from ndp.experiments.provenance import git_commit
from ndp.experiments.study import Arm, markdown_table, plot, run_grid, summarise

ARMS = (Arm("ndp", "ndp", (), "NDP (default head)"), Arm("ppo", "ppo", (), "PPO"),
        Arm("ppo-multi", "ppo-multi", (), "PPO-multi"))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", nargs="+",
                   default=["push-v3", "soccer-v3", "faucet-open-v3", "throw", "pick",
                            "reach-v3"])
    p.add_argument("--algos", nargs="+", default=[a.label for a in ARMS],
                   choices=[a.label for a in ARMS])
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--steps", type=int, default=300_000, help="env-step budget per run")
    p.add_argument("--jobs", type=int, default=1, help="runs at once (at most one per core)")
    p.add_argument("--vector", default=None, choices=("auto", "sync"),
                   help="vector env of each run (default: auto for one job, sync for several)")
    p.add_argument("--runs-dir", type=Path, default=Path("runs/rl_learning"))
    p.add_argument("--out", type=Path, default=Path("docs/results/rl_learning"))
    p.add_argument("--plot-only", action="store_true", help="only aggregate existing runs")
    p.add_argument("extra", nargs="*", help="extra 'ndp rl train' options for every method")
    args = p.parse_args(argv)
    arms = [Arm(a.label, a.algo, tuple(args.extra), a.note) for a in ARMS
            if a.label in args.algos]
    cmd = "python benchmarks/rl_learning.py " + " ".join(
        argv if argv is not None else sys.argv[1:])
    if not args.plot_only:
        run_grid(args.tasks, arms, args.seeds, args.steps, args.runs_dir, args.jobs,
                 vector=args.vector)
    summary = summarise(args.tasks, arms, args.seeds, args.steps, args.runs_dir)
    summary.update(command=cmd, commit=git_commit(), date=dt.date.today().isoformat(),
                   runs_dir=str(args.runs_dir))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(summary, indent=1) + "\n")
    plot(summary, arms, args.out.with_suffix(".png"))
    lines = [f"# RL learning comparison ({args.steps} env steps, seeds {args.seeds})", "",
             f"Command: `{cmd}`  ", f"Commit: {summary['commit']}, date: {summary['date']}; "
             f"runs in `{args.runs_dir}`; options for every method: "
             f"`{' '.join(args.extra) or '(defaults)'}`.", "",
             "Success area (success averaged over the budget; mean +- std over seeds):", "",
             *markdown_table(summary, arms, "area"), "",
             "Final success (last 10% of updates):", "", *markdown_table(summary, arms, "final"),
             "", f"![curves]({args.out.with_suffix('.png').name})", ""]
    args.out.with_suffix(".md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
