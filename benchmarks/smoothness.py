"""Smoothness of trained policies: mean squared jerk and SPARC of the executed paths.

For every finished RL run in RUNS (filtered by ``--tasks`` / ``--methods`` / ``--seeds``) the
trained policy is rolled out deterministically for ``--episodes`` fresh episodes (seeds from
10,000, disjoint from training's) in its own chunked env, and the executed robot path (every
env step: hand xyz on Meta-World, the 6 arm joints on Jaco; no gripper or fingers) is scored
with ``ndp.experiments.smoothness``: mean squared jerk (lower is smoother; compare only within a
task) and SPARC (closer to 0 is smoother; dimensionless). Per-run results are cached in the run
directory (``smoothness-e<episodes>-s<seed>.json``), so the study resumes.

    python benchmarks/smoothness.py /work/runs/ndp_study --tasks push-v3 throw \\
        --methods ndp ppo ppo-multi --seeds 0 1 2 --episodes 20 \\
        --out docs/results/smoothness/smoothness

Writes ``<out>.md``, ``<out>.csv`` and ``<out>.png`` (jerk and SPARC per task and method,
mean +- std over seeds), each with the command, commit and date.
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import time
from pathlib import Path
from typing import Any


def _plot(summary: list[dict[str, Any]], out: Path, foot: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    tasks = sorted({r["task"] for r in summary})
    methods = sorted({r["method"] for r in summary})
    fig, axes = plt.subplots(2, len(tasks), figsize=(3.2 * len(tasks) + 1, 6), squeeze=False)
    colors = plt.get_cmap("tab10")
    for j, task in enumerate(tasks):
        for i, (key, label) in enumerate(
            (("jerk", "mean squared jerk (log)"), ("sparc", "SPARC (closer to 0: smoother)"))
        ):
            ax = axes[i][j]
            for m_i, m in enumerate(methods):
                r = next((x for x in summary if x["task"] == task and x["method"] == m), None)
                if r is None:
                    continue
                mean, std = r[f"{key}_mean"], r[f"{key}_std"]
                if key == "jerk":  # points on a log axis (bars would start at an arbitrary floor)
                    lo = min(std, 0.9 * mean)
                    ax.errorbar(
                        m_i, mean, yerr=[[lo], [std]], fmt="o", color=colors(m_i), capsize=3
                    )
                else:
                    ax.bar(m_i, mean, yerr=std, color=colors(m_i), capsize=3)
            ax.set_xticks(np.arange(len(methods)), methods, rotation=30, ha="right", fontsize=8)
            if key == "jerk":
                ax.set_yscale("log")
                ax.set_xlim(-0.5, len(methods) - 0.5)
                ax.set_title(task)
            if j == 0:
                ax.set_ylabel(label)
    fig.text(0.01, 0.005, foot, fontsize=6)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    png = out.with_suffix(".png")
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("runs", nargs="+", help="run directories, or folders holding them")
    p.add_argument("--tasks", nargs="+")
    p.add_argument("--methods", nargs="+", help="run labels (ndp, ppo, ppo-multi, ...)")
    p.add_argument("--seeds", nargs="+", type=int)
    p.add_argument("--episodes", type=int, default=20)
    p.add_argument("--eval-seed", type=int, default=10_000, help="first evaluation episode seed")
    p.add_argument("--out", default="docs/results/smoothness/smoothness")
    args = p.parse_args(argv)

    import torch

    torch.set_num_threads(1)
    from ndp.experiments.smoothness import smoothness_of_runs, summarise
    from ndp.io import atomic_write_text
    from ndp.provenance import git_commit

    rows = smoothness_of_runs(
        args.runs, args.episodes, args.eval_seed, args.tasks, args.methods, args.seeds,
        log=lambda s: print(s, flush=True),
    )  # fmt: skip
    if not rows:
        print("smoothness: no finished RL run matched", file=sys.stderr)
        return 1
    summary = summarise(rows)
    cmd = "python benchmarks/smoothness.py " + " ".join(argv)
    commit, date = git_commit(), time.strftime("%Y-%m-%d")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    png = _plot(summary, out, f"{cmd}  |  commit {commit}  |  {date}")
    buf = io.StringIO()
    cols = ["task", "method", "n_seeds", "seeds", "success_mean", "success_std", "jerk_mean",
            "jerk_std", "sparc_mean", "sparc_std"]  # fmt: skip
    w = csv.DictWriter(buf, fieldnames=[*cols, "command", "commit", "date"])
    w.writeheader()
    for r in summary:
        w.writerow({**{c: r[c] for c in cols}, "command": cmd, "commit": commit, "date": date})
    atomic_write_text(out.with_suffix(".csv"), buf.getvalue())
    lines = [
        "# Smoothness of the executed paths of trained policies",
        "",
        f"Command: `{cmd}`  ",
        f"Commit: {commit}, date: {date}; runs in {', '.join(f'`{r}`' for r in args.runs)}.",
        "",
        f"Deterministic policy, {args.episodes} evaluation episodes per run (seeds from "
        f"{args.eval_seed}); mean +- std over seeds. Path = the executed robot coordinates at "
        "every env step (hand xyz on Meta-World, the 6 arm joints on Jaco). Jerk: mean squared "
        "third derivative (units^2/s^6; lower is smoother, comparable within a task only). "
        "SPARC: spectral arc length of the speed profile (closer to 0 is smoother). Success "
        "(any step) of the same episodes, for context: a policy that fails may still be smooth.",
        "",
        "| task | method | seeds | success | jerk | SPARC |",
        "|---|---|---|---|---|---|",
    ]
    for r in summary:
        lines.append(
            f"| {r['task']} | {r['method']} | {r['seeds']} | "
            f"{r['success_mean']:.2f} +- {r['success_std']:.2f} | "
            f"{r['jerk_mean']:.3g} +- {r['jerk_std']:.2g} | "
            f"{r['sparc_mean']:.2f} +- {r['sparc_std']:.2f} |"
        )
    lines += ["", f"![smoothness]({png.name})"]
    atomic_write_text(out.with_suffix(".md"), "\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
