"""Does a refactor change any number? Short seeded runs of each learner trained with two versions
of the package (subprocesses with each version's ``src`` on ``PYTHONPATH``), then every
``metrics.csv`` cell (wall-clock columns aside) and every checkpoint entry (the config aside)
compared for equality. Prints JSON: per run, identical or the first differences.

The runs (point-mass, seed 3, a few thousand env steps each): PPO, PPO-multi, NDP (on-policy),
SAC, chunked SAC, NDP-SAC, TD3 (off-policy, periodic evaluation on), Dyn-E, and a Dyn-E run
trained to 1,400 steps and resumed to 2,400. The refactors of 2026-12-07 (Dyn-E on the shared
off-policy loop; the decision call without autograd) were checked this way: every run identical.

Example::

    git worktree add /tmp/ndp-base 57f077c
    python benchmarks/refactor_equivalence.py --base-src /tmp/ndp-base/src --out /tmp/eq
    python benchmarks/refactor_equivalence.py --base-src /tmp/ndp-base/src --runs td3 dyne
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
WALL_CLOCK = {"charts/env_steps_per_s", "time/rollout_s", "time/update_s", "time/eval_s",
              "time/wall_s"}  # fmt: skip
COMMON = ["--task", "point-mass", "--vector", "sync", "--no-progress", "--no-tensorboard",
          "--seed", "3"]  # fmt: skip
OFF = ["--steps", "3000", "--steps-per-update", "500", "--eval-every", "1000"]
DYNE = ["--algo", "dyne", "--steps-per-update", "200", "--embed-updates", "100",
        "--decoder-updates", "100"]  # fmt: skip
# fmt: off
RUNS: dict[str, list[list[str]]] = {
    "ppo": [["--algo", "ppo", "--steps", "2048", "--steps-per-update", "512"]],
    "ppo-multi": [["--algo", "ppo-multi", "--steps", "2560", "--steps-per-update", "640"]],
    "ndp": [["--algo", "ndp", "--steps", "2560", "--steps-per-update", "640"]],
    "sac": [["--algo", "sac", *OFF, "--sac-random-steps", "500", "--sac-batch-size", "64"]],
    "sac-chunk": [["--algo", "sac-chunk", *OFF, "--sac-random-steps", "500",
                   "--sac-batch-size", "64"]],
    "ndp-sac": [["--algo", "ndp-sac", *OFF, "--sac-random-steps", "500",
                 "--sac-batch-size", "64"]],
    "td3": [["--algo", "td3", *OFF, "--td3-random-steps", "500", "--td3-batch-size", "64"]],
    "dyne": [[*DYNE, "--steps", "3000", "--explore-steps", "400", "--updates-per-step", "0.5",
              "--eval-every", "1000"]],
    "dyne-resume": [[*DYNE, "--steps", "1400", "--explore-steps", "400",
                     "--updates-per-step", "0.5"], ["--resume", "{run}", "--steps", "2400"]],
}
# fmt: on
"""Per run: the ``ndp rl train`` option lists, one per command (a second one resumes)."""


def train(src: str, out: Path, name: str) -> None:
    """Train run ``name`` with the package at ``src`` into ``out/name``."""
    run = out / name
    env = {**os.environ, "PYTHONPATH": src, "OMP_NUM_THREADS": "1", "MUJOCO_GL": "egl"}
    for i, opts in enumerate(RUNS[name]):
        args = [o.replace("{run}", str(run)) for o in opts]
        cmd = [sys.executable, "-m", "ndp.cli", "rl", "train", *args]
        if i == 0:
            cmd += [*COMMON, "--run-dir", str(run)]
        else:
            cmd += ["--no-progress"]
        subprocess.run(cmd, env=env, check=True, capture_output=True, text=True)


def _rows(run: Path) -> tuple[list[dict[str, str]], list[str]]:
    with (run / "metrics.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    columns = list(rows[0]) if rows else []
    return [{k: v for k, v in r.items() if k not in WALL_CLOCK} for r in rows], columns


def differences(a: Any, b: Any, path: str = "") -> list[str]:
    """The key paths where two checkpoint values differ (tensors and arrays exactly)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{path}: keys {sorted(map(str, set(a) ^ set(b)))}"]
        return [d for k in a for d in differences(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            return [f"{path}: length {len(a)} != {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True))
                for d in differences(x, y, f"{path}[{i}]")]  # fmt: skip
    if isinstance(a, torch.Tensor) and isinstance(b, torch.Tensor):
        return [] if a.dtype == b.dtype and torch.equal(a, b) else [path]
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
        return [] if a.dtype == b.dtype and np.array_equal(a, b) else [path]
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return []
    return [] if type(a) is type(b) and a == b else [f"{path}: {a!r} != {b!r}"]


def compare(a: Path, b: Path) -> dict[str, Any]:
    """One run of each version: identical, or what differs."""
    ra, ca = _rows(a)
    rb, cb = _rows(b)
    found: list[str] = []
    if ca != cb:
        found.append("metrics columns differ")
    if ra != rb:
        n = sum(x != y for x, y in zip(ra, rb, strict=False))
        found.append(f"metrics differ in {n} of {len(ra)} rows (lengths {len(ra)}, {len(rb)})")
    ka = torch.load(a / "checkpoint.pt", map_location="cpu", weights_only=False)
    kb = torch.load(b / "checkpoint.pt", map_location="cpu", weights_only=False)
    ka.pop("config", None)
    kb.pop("config", None)
    diff = differences(ka, kb)
    if diff:
        found.append(f"checkpoint differs at {len(diff)} entries, first {diff[:5]}")
    return {"rows": len(ra), "identical": not found, "differences": found}


def main(argv: list[str] | None = None) -> dict[str, Any]:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--base-src", required=True, help="the old version's src folder")
    p.add_argument("--new-src", default=str(ROOT / "src"), help="the new one's (this checkout)")
    p.add_argument("--runs", nargs="+", default=list(RUNS), choices=list(RUNS))
    p.add_argument("--out", default=None, help="where the runs go (default: a temporary folder)")
    args = p.parse_args(argv)
    import tempfile

    out = Path(args.out or tempfile.mkdtemp(prefix="ndp-equivalence-"))
    result: dict[str, Any] = {}
    for name in args.runs:
        for tag, src in (("base", args.base_src), ("new", args.new_src)):
            train(src, out / tag, name)
        result[name] = compare(out / "base" / name, out / "new" / name)
    result["all_identical"] = all(r["identical"] for r in result.values())
    print(json.dumps(result, indent=1))
    return result


if __name__ == "__main__":
    main()
