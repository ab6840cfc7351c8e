"""Success vs K2: trained runs evaluated at a higher control rate (``ndp rl eval --exec-k``).

Each run is evaluated (deterministic, the same episode seeds for every K2) at its trained k and
at the finest rate its task allows, K2 = k * m_max (Meta-World m_max 5, Jaco 10; see
``ndp.rl.exec_k``), at every K2 it allows (``--every``) or at the K2 given with ``--exec-k``.
Success compares across K2; the return does not (m times as many env-step rewards are summed),
so the table reports it only for reference. The runs are only read.

    python benchmarks/exec_k.py /work/runs/ndp_study/push-v3-ndp-s0 \\
        /work/runs/ndp_study/push-v3-ppo-multi-s0 --episodes 20 --out docs/results/exec_k/exec_k

Writes ``<out>.md`` and ``<out>.csv`` (one row per run and K2), each with the command, the commit
and the date.
"""

from __future__ import annotations

import argparse
import csv
import shlex
import sys
import time
from pathlib import Path
from typing import Any


def write_table(rows: list[dict[str, Any]], out: Path, prov: dict[str, str]) -> list[str]:
    """Write ``out.csv`` and ``out.md`` from :func:`ndp.rl.evaluate.exec_k_table` rows; returns
    the Markdown lines."""
    from ndp.io import atomic_write_text

    out.parent.mkdir(parents=True, exist_ok=True)
    cols = [*rows[0], "command", "commit", "date"] if rows else ["command", "commit", "date"]
    with out.with_suffix(".csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({**r, **prov})
    eps = sorted({int(r["episodes"]) for r in rows})
    md = [
        "# Success vs K2: inference at a higher control rate (`ndp rl eval --exec-k`)",
        "",
        f"Command: `{prov['command']}`  ",
        f"Commit: {prov['commit']}, date: {prov['date']}.",
        "",
        f"Deterministic policy, {', '.join(map(str, eps))} episodes per row (seeds 10000 ..., the "
        "same for every K2). K2 = k * m sub-steps per decision of the same duration, each env "
        "step m times shorter (docs/rl.md, 'Inference at a higher rate'). Success (any step / "
        "final step) is the metric; the return sums m times as many env-step rewards and does "
        "not compare across m. Episode seconds: the same for every m. Execution: `trained` "
        "(m = 1, plain eval), `dmp` (NDP: the same DMP reported at K2 + 1 points), `hold` (each "
        "trained sub-action held for m env steps: PPO, PPO-multi, Dyn-E; for NDP the diagnostic "
        "`--ndp-hold`).",
        "",
        "| run | task | algo | k | K2 | m | execution | success any | success final | return "
        "(not comparable across m) | episode s | eval wall s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        md.append(
            f"| {Path(r['run']).name} | {r['task']} | {r['algo']} | {r['k']} | {r['exec_k']} | "
            f"{r['m']} | {r['execution']} | {r['success_any']:.2f} | {r['success_final']:.2f} | "
            f"{r['episode_return']:.1f} | {r['episode_seconds']:.3f} | {r['seconds']:.0f} |"
        )
    atomic_write_text(out.with_suffix(".md"), "\n".join(md) + "\n")
    return md


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("runs", nargs="+", metavar="RUN_DIR", help="trained runs (read only)")
    p.add_argument(
        "--exec-k",
        type=int,
        nargs="+",
        default=None,
        metavar="K2",
        help="K2 for every run (default: per run, its k and k * m_max)",
    )
    p.add_argument(
        "--every", action="store_true", help="without --exec-k: every K2 each run allows"
    )
    p.add_argument(
        "--ndp-hold",
        action="store_true",
        help="NDP runs: also a row with the trained k sub-actions held for m env steps",
    )
    p.add_argument("--episodes", type=int, default=20)
    p.add_argument("--seed", type=int, default=10_000)
    p.add_argument("--out", default="docs/results/exec_k/exec_k")
    args = p.parse_args(argv)

    import torch

    torch.set_num_threads(1)
    from ndp.provenance import git_commit
    from ndp.rl.evaluate import exec_k_table

    rows = exec_k_table(
        args.runs, args.exec_k, args.episodes, args.seed, every=args.every, ndp_hold=args.ndp_hold
    )
    given = argv if argv is not None else sys.argv[1:]
    prov = {
        "command": "python benchmarks/exec_k.py " + shlex.join(given),
        "commit": git_commit(),
        "date": time.strftime("%Y-%m-%d %H:%M"),
    }
    print("\n".join(write_table(rows, Path(args.out), prov)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
