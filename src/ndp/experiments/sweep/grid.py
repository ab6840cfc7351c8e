"""Private grids of runs, for the benchmark scripts that predate named studies
(``benchmarks/ndp_ablation.py``, ``benchmarks/ppo_vs_sb3.py``): run every (task, arm, seed) on
the sweep's local backend, then summarise them into ``<out>.json``, ``.md`` and ``.png``.

This module sits above both :mod:`ndp.experiments.study` (arms, run records, the finished
rule, curves) and :mod:`ndp.experiments.sweep` (the runner), so neither imports the other.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ndp.experiments.provenance import git_commit
from ndp.experiments.study import Arm, default_vector, markdown_table, plot, summarise
from ndp.experiments.sweep import make_jobs, run_sweep


def run_grid(
    tasks: Sequence[str],
    arms: Sequence[Arm],
    seeds: Sequence[int],
    steps: int,
    runs_dir: Path,
    jobs: int = 1,
    num_envs: int = 4,
    vector: str | None = None,
) -> list[Path]:
    """Every (task, arm, seed), seed-major (all arms of seed 0 first), ``jobs`` at a time, on
    the sweep's local backend (:func:`ndp.experiments.sweep.run_sweep`: a failed run is retried
    once; Ctrl-C stops every run at its last checkpoint).

    ``vector`` (None: :func:`default_vector`). Pass ``sync`` when other studies share the
    machine.

    Raises:
        RuntimeError: some runs failed twice (after the others finished).
        KeyboardInterrupt: the sweep was interrupted (everything stays resumable).
    """
    if vector is None:
        vector = default_vector(jobs)
    grid = make_jobs(tasks, arms, seeds, steps, runs_dir, num_envs=num_envs, vector=vector)
    result = run_sweep(grid, workers=max(1, jobs))
    if result.interrupted:
        raise KeyboardInterrupt
    if result.failed:
        raise RuntimeError(
            "runs failed: " + "; ".join(f"{o.job.name}: {o.error}" for o in result.failed)
        )
    return [j.run_dir for j in grid]


def add_study_arguments(
    parser: argparse.ArgumentParser, runs_dir: str, out: str, steps: int
) -> None:
    """The options every study command shares (seeds, budget, jobs, directories, extras)."""
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--steps", type=int, default=steps, help="env-step budget per run")
    parser.add_argument("--jobs", type=int, default=1, help="runs at once (at most one per core)")
    parser.add_argument(
        "--vector",
        default=None,
        choices=("auto", "sync"),
        help="vector env of each run (default: auto for one job, sync for more)",
    )
    parser.add_argument("--runs-dir", type=Path, default=Path(runs_dir))
    parser.add_argument(
        "--out", type=Path, default=Path(out), help="output stem: <out>.json, <out>.md, <out>.png"
    )
    parser.add_argument("--plot-only", action="store_true", help="only aggregate existing runs")
    parser.add_argument("extra", nargs="*", help="extra 'ndp rl train' options, after --")


def run_study(
    args: argparse.Namespace,
    tasks: Sequence[str],
    arms: Sequence[Arm],
    title: str,
    intro: Sequence[str],
    command: str,
) -> dict[str, Any]:
    """Run (unless ``args.plot_only``) and report a study: ``<out>.json`` (every number, with
    the command, commit, date and runs directory), ``<out>.png`` and ``<out>.md`` (``intro``
    lines, then success area and final success tables)."""
    import datetime as dt

    if not args.plot_only:
        run_grid(tasks, arms, args.seeds, args.steps, args.runs_dir, args.jobs, vector=args.vector)
    summary = summarise(tasks, arms, args.seeds, args.steps, args.runs_dir)
    summary.update(
        command=command,
        commit=git_commit(),
        date=dt.date.today().isoformat(),
        runs_dir=str(args.runs_dir),
    )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(summary, indent=1) + "\n")
    plot(summary, arms, out.with_suffix(".png"))
    lines = [
        f"# {title} ({args.steps} env steps, seeds {list(args.seeds)})",
        "",
        f"Command: `{command}`  ",
        f"Commit: {summary['commit']}, date: {summary['date']}; runs in `{args.runs_dir}`.",
        "",
        *(
            [
                "Aggregated with `--plot-only`: the runs were made by this command without it "
                "(resumable; each run's `arm.json` holds its options and `config.json` its "
                "resolved config; docs/rl.md names the commits they ran at).",
                "",
            ]
            if args.plot_only
            else []
        ),
        *intro,
        "Success area (success averaged over the budget; mean +- std over seeds):",
        "",
        *markdown_table(summary, arms, "area"),
        "",
        "Final success (last 10% of updates):",
        "",
        *markdown_table(summary, arms, "final"),
        "",
        f"![curves]({out.with_suffix('.png').name})",
        "",
    ]
    out.with_suffix(".md").write_text("\n".join(lines))
    print("\n".join(lines))
    return summary
