"""Our PPO (k = 1) against Stable-Baselines3's PPO: same tasks, seeds, budget, hyperparameters.

Both use the supplement's PPO settings (2048 env steps per update over 4 envs, 32 mini-batches,
10 epochs, clip 0.1, Adam 3e-4 / eps 1e-5, gamma 0.99, GAE 0.95, [100, 100] tanh, observation
and return normalisation) on the same per-step env; success is counted per env and per episode
in both (see ndp.sb3.runs). Extra ``ndp rl train`` options for our PPO go after
``--`` with a ``--label`` of their own (for example ``--label ppo-vclip -- --clip-value-loss`` to
measure the release's value clip). Runs are resumable (ndp.experiments.study); re-running the
command continues or re-plots.

Writes ``<out>.json`` / ``<out>.md`` / ``<out>.png``: success area and final success per task,
mean +- std over seeds, side by side, with the command, commit and date.

The issue's protocol (hours of CPU)::

    python benchmarks/ppo_vs_sb3.py --steps 150000 --seeds 0 1 2 \
        --tasks reach-v3 push-v3 window-close-v3 drawer-open-v3 button-press-v3
"""

from __future__ import annotations

import argparse
import sys

from ndp.experiments.studies import get_study
from ndp.experiments.study import Arm
from ndp.experiments.sweep.grid import add_study_arguments, run_study

TASKS = list(get_study("ppo-vs-sb3").task_list())  # the named study ppo-vs-sb3


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", nargs="+", default=TASKS)
    p.add_argument("--label", default="ppo", help="label of our PPO arm (with extra options)")
    add_study_arguments(p, "runs/ppo_vs_sb3", "docs/results/ppo_vs_sb3/ppo_vs_sb3", 150_000)
    args = p.parse_args(argv)
    ours, sb3 = (a.arm() for a in get_study("ppo-vs-sb3").arm_specs())
    arms = [Arm(args.label, ours.algo, tuple(args.extra), ours.note), sb3]
    cmd = "python benchmarks/ppo_vs_sb3.py " + " ".join(argv if argv is not None else sys.argv[1:])
    intro = [f"Our PPO options: `{' '.join(args.extra) or '(defaults)'}`.", ""]
    run_study(args, args.tasks, arms, "Our PPO vs SB3 PPO", intro, cmd)
    return 0


if __name__ == "__main__":
    sys.exit(main())
