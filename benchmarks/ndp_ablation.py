"""NDP head ablation: each handicap fix switched off, with PPO and PPO-multi.

Arms (every one an ordinary ``ndp rl train`` run; ndp.experiments.study runs, resumes and
summarises them). The fixes are switched off one at a time from the commanded frame at rest
(``ndp-commanded``), the head these runs were designed against; every arm names its frame
explicitly, so a label means the same head whatever the task's default frame is:

- ``ndp``: the default NDP head of the task (unclipped means, amplitude forcing, goal bound 2x
  the k-step reach, gripper command emitted per decision, the task preset's DMP frame: the
  measured hand with its velocity on Meta-World, the commanded joint targets at rest on Jaco);
- ``ndp-commanded``: the commanded frame at rest (``--dmp-state commanded --dmp-velocity zero``;
  the default on every task before the per-task frame, and still Jaco's and the toy's);
- ``ndp-meanclip``: ndp-commanded with the means clipped before the noise (``--mean-clip``);
- ``ndp-goalforcing``: ndp-commanded with the paper's forcing f proportional to (g - y0);
- ``ndp-gs1``: ndp-commanded with the goal bound equal to the k-step reach (``--goal-scale 1``);
- ``ndp-gripdmp``: ndp-commanded with the gripper DMP from the last sampled command;
- ``ndp-paramnoise``: ndp-commanded with parameter-space exploration (``--param-noise``);
- ``ndp-velstate``: the commanded frame starting with its velocity;
- ``ndp-measured``: the measured frame with its velocity (``--dmp-state measured --dmp-velocity
  state``): the ``ndp`` arm itself on Meta-World, so only run when named (``--arms``), for the
  Jaco tasks;
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
import sys

from ndp.experiments.studies import get_study
from ndp.experiments.study import Arm
from ndp.experiments.sweep.grid import add_study_arguments, run_study

ARMS = [a.arm() for a in get_study("ndp-head-ablation").arm_specs() if a.in_default]
"""The default arms (in this order): the named study ``ndp-head-ablation``'s."""
EXTRA_ARMS = [a.arm() for a in get_study("ndp-head-ablation").arm_specs() if not a.in_default]
"""Arms run only when named with --arms."""


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", nargs="+", default=["push-v3", "point-mass"])
    p.add_argument(
        "--arms",
        nargs="+",
        default=[a.label for a in ARMS],
        choices=[a.label for a in (*ARMS, *EXTRA_ARMS)],
    )
    add_study_arguments(
        p, "runs/ndp_study", "docs/results/ndp_ablation_push/ndp_ablation_push", 300_000
    )
    args = p.parse_args(argv)
    arms = [
        Arm(a.label, a.algo, a.args + tuple(args.extra), a.note)
        for a in (*ARMS, *EXTRA_ARMS)
        if a.label in args.arms
    ]
    cmd = "python benchmarks/ndp_ablation.py " + " ".join(
        argv if argv is not None else sys.argv[1:]
    )
    intro = [
        "| arm | change |",
        "|---|---|",
        *[f"| {a.label} | {a.note} (`{' '.join(a.args) or 'defaults'}`) |" for a in arms],
        "",
    ]
    run_study(args, args.tasks, arms, "NDP head ablation", intro, cmd)
    return 0


if __name__ == "__main__":
    sys.exit(main())
