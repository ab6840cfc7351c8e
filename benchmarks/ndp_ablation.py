"""NDP head ablation: each handicap fix switched off from the new default, with PPO and PPO-multi.

Arms (every one an ordinary ``ndp rl train`` run; ndp.experiments.study runs, resumes and
summarises them):

- ``ndp``: the default NDP head (unclipped means, amplitude forcing, goal bound 2x the k-step
  reach, gripper command emitted per decision, DMP from the commanded target at rest);
- ``ndp-meanclip``: the sub-action means clipped before the noise (``--mean-clip``);
- ``ndp-goalforcing``: the paper's forcing term proportional to (g - y0) (``--forcing goal``);
- ``ndp-gs1``: the goal bound equal to the k-step reach (``--goal-scale 1``);
- ``ndp-gripdmp``: the gripper DMP from the last sampled command (``--absolute-mode dmp``);
- ``ndp-measured``: the DMP from the measured hand (``--dmp-state measured``);
- ``ndp-velstate``: the DMP starts with the state's velocity (``--dmp-velocity state``);
- ``ndp-paramnoise``: parameter-space exploration (``--param-noise``), on from the default;
- ``ndp-v0``: every fix off at once (the first release's head, value clip off);
- ``ppo``, ``ppo-multi``: the baselines with the same PPO settings.

Extra ``ndp rl train`` options after ``--`` go to EVERY arm (e.g. ``-- --init-log-std -0.7``
applies a smaller initial std to all methods alike). Writes ``<out>.json/.md/.png`` with the
command, commit and date: success area and final success, mean +- std over seeds.

The issue's protocol (many CPU hours; resumable)::

    python benchmarks/ndp_ablation.py --tasks push-v3 point-mass --seeds 0 1 2 --steps 300000
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
from pathlib import Path

from ndp.experiments.provenance import git_commit
from ndp.experiments.study import Arm, markdown_table, plot, run_grid, summarise

ARMS = [
    Arm("ndp", "ndp", (), "default NDP head"),
    Arm("ppo", "ppo", (), "PPO, one action per step"),
    Arm("ppo-multi", "ppo-multi", (), "PPO-multi, k raw actions per decision"),
    Arm("ndp-meanclip", "ndp", ("--mean-clip",), "means clipped before the noise"),
    Arm("ndp-goalforcing", "ndp", ("--forcing", "goal"), "f proportional to (g - y0)"),
    Arm("ndp-gs1", "ndp", ("--goal-scale", "1"), "goal bound = k-step reach"),
    Arm("ndp-gripdmp", "ndp", ("--absolute-mode", "dmp"), "gripper DMP from the sampled command"),
    Arm("ndp-measured", "ndp", ("--dmp-state", "measured"), "DMP from the measured hand"),
    Arm("ndp-velstate", "ndp", ("--dmp-velocity", "state"), "DMP starts with the state velocity"),
    Arm("ndp-paramnoise", "ndp", ("--param-noise",), "parameter-space exploration"),
    Arm("ndp-v0", "ndp", ("--mean-clip", "--forcing", "goal", "--goal-scale", "1",
                          "--absolute-mode", "dmp", "--dmp-state", "measured",
                          "--dmp-velocity", "state"), "every fix off (first release's head)"),
]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", nargs="+", default=["push-v3", "point-mass"])
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--steps", type=int, default=300_000)
    p.add_argument("--arms", nargs="+", default=[a.label for a in ARMS],
                   choices=[a.label for a in ARMS])
    p.add_argument("--jobs", type=int, default=1, help="runs at once (at most one per core)")
    p.add_argument("--vector", default=None, choices=("auto", "sync"),
                   help="vector env of each run (default: auto for one job, sync for several)")
    p.add_argument("--runs-dir", type=Path, default=Path("runs/ndp_study"))
    p.add_argument("--out", type=Path, default=Path("docs/results/ndp_ablation"))
    p.add_argument("--plot-only", action="store_true")
    p.add_argument("extra", nargs="*", help="extra 'ndp rl train' options for every arm")
    args = p.parse_args(argv)
    arms = [Arm(a.label, a.algo, a.args + tuple(args.extra), a.note)
            for a in ARMS if a.label in args.arms]
    cmd = "python benchmarks/ndp_ablation.py " + " ".join(
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
    lines = [f"# NDP head ablation ({args.steps} env steps, seeds {args.seeds})", "",
             f"Command: `{cmd}`  ", f"Commit: {summary['commit']}, date: {summary['date']}; "
             f"runs in `{args.runs_dir}`.", "", "| arm | change |", "|---|---|",
             *[f"| {a.label} | {a.note} (`{' '.join(a.args) or 'defaults'}`) |" for a in arms],
             "", "Success area (success averaged over the budget; mean +- std over seeds):", "",
             *markdown_table(summary, arms, "area"), "",
             "Final success (last 10% of updates):", "", *markdown_table(summary, arms, "final"),
             "", f"![curves]({args.out.with_suffix('.png').name})", ""]
    args.out.with_suffix(".md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
