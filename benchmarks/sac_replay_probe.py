"""What a SAC-family run's actor chose, read from the replay buffer saved in its checkpoint.

For windows of env steps (the replay keeps one row per decision, in the order they were taken,
``num_envs`` rows per decision step; the rows of the first 1M env steps are all kept): the
fraction of the decision's bounded parameters near the box's edge (|tanh u| above 0.99 and
0.999), the largest such fraction of any one parameter, the mean |u|, the mean chunk return of a
decision and the bootstrap weights stored (``gamma^n (1 - terminal)``: a value other than
``gamma^k`` marks decisions cut by an episode's end or a true termination). Printed as JSON.

Used for docs/offpolicy.md ("Critic health"): did NDP-SAC's actor push its parameters into the
corners of the box while its critic ran away on push-v3 seed 0? ::

    python benchmarks/sac_replay_probe.py runs/off_policy/push-v3-ndp-sac-k5-s0
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import numpy as np

WINDOWS = (0, 5_000, 20_000, 60_000, 120_000, 200_000, None)
"""Window edges in env steps (None: to the end of the replay)."""


def probe(run_dir: str | Path, windows: tuple[int | None, ...] = WINDOWS) -> dict[str, object]:
    """The statistics of the module doc for one run directory with a SAC-family checkpoint."""
    from ndp.runs import load_checkpoint

    try:
        ck = load_checkpoint(run_dir, kind="rl")
    except (FileNotFoundError, ValueError) as exc:  # no checkpoint, or another trainer's
        raise SystemExit(f"run_dir: {exc}") from None
    if "sac" not in ck:
        raise SystemExit(
            f"run_dir: {run_dir} is not a SAC-family run (its checkpoint has no 'sac')"
        )
    data = ck["sac"]["replay"]["data"]
    u, ret, disc = data["u"], data["ret"][:, 0], data["discount"][:, 0]
    steps_per_row = ck["global_step"] / max(len(u), 1)  # env steps per stored decision
    out: list[dict[str, float | int | None]] = []
    for lo, hi in itertools.pairwise(windows):
        a = int(lo / steps_per_row)
        b = len(u) if hi is None else min(int(hi / steps_per_row), len(u))
        if a >= b:
            continue
        t = np.abs(np.tanh(u[a:b]))
        out.append({
            "env_steps_from": lo, "env_steps_to": hi if hi is not None else int(ck["global_step"]),
            "decisions": b - a,
            "edge_0.99": float(np.mean(t > 0.99)), "edge_0.999": float(np.mean(t > 0.999)),
            "edge_0.99_worst_parameter": float(np.max(np.mean(t > 0.99, 0))),
            "mean_abs_u": float(np.mean(np.abs(u[a:b]))),
            "mean_chunk_return": float(np.mean(ret[a:b])),
        })  # fmt: skip
    weights, counts = np.unique(np.round(disc, 6), return_counts=True)
    return {
        "run": Path(run_dir).name,
        "global_step": int(ck["global_step"]),
        "parameters": int(u.shape[1]),
        "windows": out,
        "bootstrap_weights": {f"{w:g}": int(c) for w, c in zip(weights, counts, strict=True)},
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run_dirs", nargs="+", help="SAC-family run directories with a checkpoint")
    args = p.parse_args(argv)
    print(json.dumps([probe(r) for r in args.run_dirs], indent=1))


if __name__ == "__main__":
    main()
