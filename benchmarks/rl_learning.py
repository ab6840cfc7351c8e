"""Learning comparison: NDP vs PPO vs PPO-multi vs Dyn-E vs VICES: success vs env steps.

Every (task, method, seed) run is an ordinary ``ndp rl train`` run in
``<runs-dir>/<task>-<method>-s<seed>`` (ndp.experiments.study): an interrupted run is resumed,
a finished one reused, so the command can be re-run to extend or re-plot. Every method gets the
same budget, seeds, PPO settings and evaluation; extra ``ndp rl train`` options after ``--`` go
to all arms alike (e.g. ``-- --init-log-std -0.7``; Dyn-E ignores the PPO and NDP ones). Dyn-E's
budget includes the random exploration data its embedding is trained on (docs/dyne.md). Success
is the training episodes' success at any step (stochastic policy, ``charts/success_any``).
Writes ``<out>.json``, ``<out>.md`` (the tables: success area = the success curve averaged over
the budget, and final success = the mean of the last 10% of updates, mean +- std over seeds,
with the command, commit and date) and ``<out>.png`` (curves).

VICES (``vices``, ``vices-pos``, ``vices-low-freq``) trains on the torque-actuated variant of
each task (``ndp.envs.TORQUE_TASKS``) with the same budget, seeds, PPO settings and success
measure (the same task's success).

The issue's protocol (days of CPU on 2 cores; resumable)::

    python benchmarks/rl_learning.py --steps 300000 --seeds 0 1 2 \
        --tasks push-v3 soccer-v3 faucet-open-v3 throw pick reach-v3

with the VICES rows (same runs directory: the finished NDP / PPO runs are reused)::

    python benchmarks/rl_learning.py --steps 300000 --seeds 0 1 2 --tasks push-v3 throw \
        --algos ndp ppo ppo-multi vices vices-pos vices-low-freq
"""

from __future__ import annotations

import argparse
import sys

from ndp.experiments.study import Arm, add_study_arguments, run_study

ARMS = (
    Arm("ndp", "ndp", (), "NDP (default head)"),
    Arm("ppo", "ppo", (), "PPO"),
    Arm("ppo-multi", "ppo-multi", (), "PPO-multi"),
    Arm("vices", "vices", (), "VICES (torque-actuated task; OSC on Meta-World, joint on Jaco)"),
    Arm("vices-pos", "vices-pos", (), "VICES in end-effector space (OSC) on every task"),
    Arm("vices-low-freq", "vices-low-freq", (), "VICES, one decision per 5 env steps"),
    Arm("dyne", "dyne", (), "Dyn-E (TD3 in a learned k-action embedding, exploration counted)"),
)

DEFAULT_ALGOS = ("ndp", "ppo", "ppo-multi")
"""Arms of a plain run: the VICES arms are named with ``--algos`` (a study re-run with more arms
reuses the finished runs of the others, so the VICES rows join the same table)."""


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument(
        "--tasks",
        nargs="+",
        default=["push-v3", "soccer-v3", "faucet-open-v3", "throw", "pick", "reach-v3"],
    )
    p.add_argument(
        "--algos",
        nargs="+",
        default=list(DEFAULT_ALGOS),
        choices=[a.label for a in ARMS],
        help=f"arms to run and tabulate (default: {' '.join(DEFAULT_ALGOS)})",
    )
    add_study_arguments(p, "runs/rl_learning", "docs/results/rl_learning", 300_000)
    args = p.parse_args(argv)
    arms = [Arm(a.label, a.algo, tuple(args.extra), a.note) for a in ARMS if a.label in args.algos]
    cmd = "python benchmarks/rl_learning.py " + " ".join(argv if argv is not None else sys.argv[1:])
    intro = [f"Options for every method: `{' '.join(args.extra) or '(defaults)'}`.", ""]
    run_study(args, args.tasks, arms, "RL learning comparison", intro, cmd)
    return 0


if __name__ == "__main__":
    sys.exit(main())
