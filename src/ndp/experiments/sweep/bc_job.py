"""One behaviour-cloning run of a study (run kind ``"bc"``): demonstrations, cloning, evaluation.

``python -m ndp.experiments.sweep.bc_job --task TASK [--demos-episodes N] [--eval-episodes E] --
BC-OPTIONS`` (the sweep builds this command; ``BC-OPTIONS`` are those of ``ndp il bc``:
``--model``, ``--episodes``, ``--seed``, ``--epochs``, ``--run-dir``, the policy's options):

1. demonstrations: the scripted expert's successful episodes of the task, collected once per
   sweep folder to ``<runs>/<task>-demos.npz`` (reset seeds from 0; a file lock lets one job
   collect while the others of the task wait), so every model, demonstration count and seed of
   a study clones the first n episodes of the same recording;
2. cloning (:func:`ndp.bc.train.train_bc`); a cloning run does not resume, so an unfinished run
   left by a killed job (its ``run.json`` says so) is cloned again from scratch;
3. closed-loop evaluation (:func:`ndp.experiments.smoothness.run_smoothness`: one decision per
   k env steps, stale-world rule, deterministic) over ``--eval-episodes`` episodes whose reset
   seeds start 1,000 past the last demonstration's, to ``eval.json``: success (any step), mean
   squared jerk and SPARC of the executed arm path, and the cloning's last validation loss.

The run counts as finished once ``eval.json`` exists (``RunKind.needs_eval``); ``ndp report``
puts it in the behaviour-cloning table.
"""

from __future__ import annotations

import argparse
import dataclasses
import fcntl
import json
import math
import sys
from pathlib import Path
from typing import Any

from ndp.bc.demos import Demos, collect, load_demos, save_demos
from ndp.checks import check_int
from ndp.experiments.run_kinds import BC_DEMOS_EPISODES as DEMOS_EPISODES
from ndp.io import atomic_write_text
from ndp.runs import read_metrics
from ndp.runs.session import read_manifest

EVAL_EPISODES = 50
"""Closed-loop evaluation episodes per run."""
EVAL_SEED_OFFSET = 1000
"""The first evaluation seed is the last demonstration's reset seed plus this."""
EVAL_FILE = "eval.json"
"""What the evaluation writes in the run directory."""


def demos_file(runs_dir: str | Path, task: str) -> Path:
    """Where the demonstrations of ``task`` live for the runs of ``runs_dir``."""
    return Path(runs_dir) / f"{task}-demos.npz"


def ensure_demos(path: Path, task: str, episodes: int = DEMOS_EPISODES) -> Demos:
    """Record ``episodes`` successful expert episodes of ``task`` to ``path`` unless it holds
    them already (one process records while the others wait on ``<path>.lock``); returns the
    file's demonstrations.

    Raises:
        ValueError: ``path`` holds another task's demonstrations, or fewer episodes.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_name(path.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.is_file():
            save_demos(collect(task, episodes, seed=0), path)
    demos = load_demos(path)
    from ndp.envs import get_task_spec

    if get_task_spec(demos.task).name != get_task_spec(task).name:
        raise ValueError(f"demos: {path} holds demonstrations of {demos.task}, not {task}")
    if demos.n_episodes < episodes:
        raise ValueError(
            f"demos: {path} holds {demos.n_episodes} episodes, the study needs {episodes}"
        )
    return demos


def last_val_loss(run: Path) -> float:
    """The cloning's fit: validation loss (MSE of the actions) of its last epoch; NaN when not
    logged (no validation split)."""
    try:
        rows = read_metrics(run / "bc_metrics.csv")
    except (OSError, ValueError):
        return math.nan
    return float(rows[-1].get("val/loss", math.nan)) if rows else math.nan


def run_job(task: str, bc_argv: list[str], demos_episodes: int, eval_episodes: int) -> Path:
    """Demonstrations, cloning and evaluation of one run (each step skipped when done)."""
    from ndp.bc.train import BCConfig, train_bc
    from ndp.runs.cli import parse_config

    cfg = parse_config(BCConfig, bc_argv, prog="ndp il bc")
    run = Path(cfg.run_dir)
    path = demos_file(run.parent, task)
    demos = ensure_demos(path, task, demos_episodes)
    cfg = dataclasses.replace(cfg, demos=str(path))
    manifest = read_manifest(run)
    if manifest is None or not manifest.finished:
        # a cloning run does not resume: an unfinished one (this job's, killed) starts again
        train_bc(cfg, overwrite=manifest is not None)
    out = run / EVAL_FILE
    if not out.is_file():
        from ndp.experiments.smoothness import run_smoothness

        seed = int(demos.seeds.max()) + EVAL_SEED_OFFSET
        ev = run_smoothness(run, eval_episodes, seed)
        rec: dict[str, Any] = {
            "success": ev["success"],
            "jerk": ev["jerk"],
            "sparc": ev["sparc"],
            "val_loss": last_val_loss(run),
            "episodes": eval_episodes,
            "first_seed": seed,
            "demos": str(path),
        }
        atomic_write_text(out, json.dumps(rec, indent=1) + "\n")
    return run


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--" not in argv:
        raise SystemExit("bc_job: expected 'JOB-OPTIONS -- NDP-IL-BC-OPTIONS'")
    cut = argv.index("--")
    p = argparse.ArgumentParser(prog="python -m ndp.experiments.sweep.bc_job", description=__doc__)
    p.add_argument("--task", required=True)
    p.add_argument("--demos-episodes", type=int, default=DEMOS_EPISODES)
    p.add_argument("--eval-episodes", type=int, default=EVAL_EPISODES)
    args = p.parse_args(argv[:cut])
    for name in ("demos_episodes", "eval_episodes"):
        try:
            check_int(f"--{name.replace('_', '-')}", getattr(args, name), 1)
        except ValueError as exc:
            p.error(str(exc))
    import torch

    torch.set_num_threads(1)
    try:
        run = run_job(args.task, argv[cut + 1 :], args.demos_episodes, args.eval_episodes)
    except (ValueError, FileNotFoundError) as exc:
        print(f"ndp: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(json.loads((run / EVAL_FILE).read_text())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
