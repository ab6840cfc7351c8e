"""Learning comparison NDP vs PPO vs PPO-multi: a thin caller of ``ndp sweep paper-five``.

The grid, its resumption, retries and the report are the sweep's (ndp.experiments.sweep,
docs/experiments.md); this script keeps the benchmark's old command line:

- ``--tasks`` / ``--algos`` choose tasks and arms of the ``paper-five`` study (default arms ndp,
  ppo, ppo-multi as before; vices, vices-pos, vices-low-freq, dyne when named and registered;
  the runs of earlier versions of this script are reused as they are; a plain
  ``ndp sweep paper-five`` runs vices and dyne too);
- ``--out STEM`` is the report (``STEM.md``, ``STEM.csv``, ``STEM-<task>.png``);
- ``--plot-only`` only reports the existing runs (``ndp report``, cells with missing seeds
  marked);
- every other option (``--seeds``, ``--steps``, ``--jobs``, ``--vector``, ``--backend``, ...)
  and the trainer options after ``--`` go to ``ndp sweep`` unchanged.

The issue's protocol (days of CPU on 2 cores; resumable)::

    python benchmarks/rl_learning.py --steps 300000 --seeds 0 1 2
    # = ndp sweep paper-five --steps 300000 --seeds 0 1 2 --runs-dir runs/rl_learning \
    #       --report docs/results/rl_learning/rl_learning
"""

from __future__ import annotations

import argparse
import sys

from ndp.cli import main as ndp


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    cut = argv.index("--") if "--" in argv else len(argv)
    own, extra = argv[:cut], argv[cut:]
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", nargs="+")
    p.add_argument("--algos", nargs="+", default=["ndp", "ppo", "ppo-multi"],
                   help="arms of paper-five (default: ndp ppo ppo-multi)")  # fmt: skip
    p.add_argument("--runs-dir", default="runs/rl_learning")
    p.add_argument("--out", default="docs/results/rl_learning/rl_learning")
    p.add_argument("--plot-only", action="store_true", help="only report the existing runs")
    p.add_argument("--seeds", nargs="+")
    p.add_argument("--eval-episodes", default="0", help="with --plot-only: ndp report's option")
    args, rest = p.parse_known_args(own)
    pick = [*(["--tasks", *args.tasks] if args.tasks else [])]
    if args.plot_only:
        methods = ["--methods", *args.algos]
        seeds = ["--seeds", *args.seeds] if args.seeds else []
        title = ["--title", "RL learning comparison (paper-five)"]
        ev = ["--eval-episodes", args.eval_episodes]
        return ndp(["report", args.runs_dir, "--out", args.out, "--allow-missing",
                    *pick, *methods, *seeds, *title, *ev])  # fmt: skip
    arms = ["--arms", *args.algos]
    seeds = ["--seeds", *args.seeds] if args.seeds else []
    return ndp(["sweep", "paper-five", "--runs-dir", args.runs_dir, "--report", args.out,
                *pick, *arms, *seeds, *rest, *extra])  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
