"""Start-up time of the ``ndp`` command: help texts and argument errors (target: < 1 s each).

Each command runs ``--repeat`` times in a fresh process; prints JSON with the best and median
wall-clock seconds per command. Measure on a quiet machine::

    python benchmarks/cli_startup.py --repeat 5
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

COMMANDS = [
    ["--help"],
    ["rl", "train", "--help"],
    ["il", "train", "--help"],
    ["il", "eval", "--help"],
    ["rl", "eval", "--help"],
    ["rl", "train", "--lr", "abc"],
    ["il", "train", "--epochs", "x"],
]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--repeat", type=int, default=5, help="runs per command (default 5)")
    args = p.parse_args(argv)
    out = {}
    for cmd in COMMANDS:
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "ndp.cli", *cmd], capture_output=True)
            times.append(time.perf_counter() - t0)
        out["ndp " + " ".join(cmd)] = {"best_s": min(times), "median_s": statistics.median(times)}
    out["target_s"] = 1.0
    out["all_below_target"] = all(
        v["median_s"] < 1.0 for k, v in out.items() if k.startswith("ndp")
    )
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
