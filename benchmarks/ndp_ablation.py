"""NDP head ablation: each handicap fix switched off from the new default, with PPO and PPO-multi.

Arms (every one an ordinary ``ndp rl train`` run; ndp.experiments.study runs, resumes and
summarises them):

- ``ndp``: the default NDP head (unclipped means, amplitude forcing, goal bound 2x the k-step
  reach, gripper command emitted per decision, DMP from the commanded target at rest);
- ``ndp-meanclip``: the sub-action means clipped before the noise (``--mean-clip``);
- ``ndp-goalforcing``: the paper's forcing term proportional to (g - y0) (``--forcing goal``);
- ``ndp-gs1``: the goal bound equal to the k-step reach (``--goal-scale 1``);
- ``ndp-gripdmp``: the gripper DMP from the last sampled command (``--absolute-mode dmp``);
- ``ndp-measured``: the DMP from the measured hand with its velocity (``--dmp-state measured
  --dmp-velocity state``; with a start at rest the frame alone changes nothing for delta DoF:
  the trajectory relative to y0 does not depend on y0);
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
import sys

from ndp.experiments.study import Arm, add_study_arguments, run_study

ARMS = [
    Arm("ndp", "ndp", (), "default NDP head"),
    Arm("ppo", "ppo", (), "PPO, one action per step"),
    Arm("ppo-multi", "ppo-multi", (), "PPO-multi, k raw actions per decision"),
    Arm("ndp-meanclip", "ndp", ("--mean-clip",), "means clipped before the noise"),
    Arm("ndp-goalforcing", "ndp", ("--forcing", "goal"), "f proportional to (g - y0)"),
    Arm("ndp-gs1", "ndp", ("--goal-scale", "1"), "goal bound = k-step reach"),
    Arm("ndp-gripdmp", "ndp", ("--absolute-mode", "dmp"), "gripper DMP from the sampled command"),
    Arm(
        "ndp-measured",
        "ndp",
        ("--dmp-state", "measured", "--dmp-velocity", "state"),
        "DMP from the measured hand and its velocity",
    ),
    Arm("ndp-velstate", "ndp", ("--dmp-velocity", "state"), "DMP starts with the state velocity"),
    Arm("ndp-paramnoise", "ndp", ("--param-noise",), "parameter-space exploration"),
    Arm(
        "ndp-v0",
        "ndp",
        (
            "--mean-clip",
            "--forcing",
            "goal",
            "--goal-scale",
            "1",
            "--absolute-mode",
            "dmp",
            "--dmp-state",
            "measured",
            "--dmp-velocity",
            "state",
        ),
        "every fix off (first release's head)",
    ),
]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", nargs="+", default=["push-v3", "point-mass"])
    p.add_argument(
        "--arms", nargs="+", default=[a.label for a in ARMS], choices=[a.label for a in ARMS]
    )
    add_study_arguments(p, "runs/ndp_study", "docs/results/ndp_ablation", 300_000)
    args = p.parse_args(argv)
    arms = [
        Arm(a.label, a.algo, a.args + tuple(args.extra), a.note)
        for a in ARMS
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
