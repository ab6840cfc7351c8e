"""ONNX exports of trained policies: export time, file size, agreement and latency per decision.

For each policy: ``Policy.export(..., format="onnx")`` (timed, its verification included), then
20 decisions of an episode (seed 0) in its env, acting with ``Policy.act``; at each the ONNX
graph (``OnnxPolicy``, onnxruntime's CPU provider) gets the same observation and info. Prints
a markdown table: the largest absolute action difference over those decisions and the best of
3 mean latencies of one decision (E = 1) over 300 calls, both with one thread::

    python benchmarks/onnx_export.py zoo/push-v3-ndp zoo/push-v3-ppo-multi zoo/throw-ndp
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np


def _latency_us(fn: Any, cases: list[tuple[Any, Any]], calls: int = 300) -> float:
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        for i in range(calls):
            fn(*cases[i % len(cases)])
        best = min(best, (time.perf_counter() - t0) / calls)
    return best * 1e6


def measure(path: str) -> dict[str, Any]:
    """Export ``path`` (a run or an export directory) to ONNX and compare (see the module)."""
    import onnxruntime as ort

    import ndp
    from ndp.rl.onnx_export import ONNX_FILE, OnnxPolicy

    policy = ndp.load_policy(path)
    out = Path(tempfile.mkdtemp()) / "onnx"
    t0 = time.perf_counter()
    policy.export(out, format="onnx")
    export_s = time.perf_counter() - t0
    onnx_policy = OnnxPolicy(out)
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = opts.inter_op_num_threads = 1
    onnx_policy.session = ort.InferenceSession(
        str(out / ONNX_FILE), opts, providers=["CPUExecutionProvider"]
    )
    env = policy.make_env()
    obs, info = env.reset(seed=0)
    cases, diff = [], 0.0
    for _ in range(20):
        cases.append((obs, info))
        act = policy.act(obs, info)
        diff = max(diff, float(np.abs(act - onnx_policy.act(obs, info)).max()))
        obs, _, term, trunc, info = env.step(act)
        if term or trunc:
            break
    env.close()
    return {
        "policy": path,
        "export_s": export_s,
        "kb": (out / ONNX_FILE).stat().st_size / 1e3,
        "max_diff": diff,
        "eager_us": _latency_us(policy.act, cases),
        "onnx_us": _latency_us(onnx_policy.act, cases),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("policies", nargs="+", help="run or export directories")
    args = p.parse_args(argv)
    import torch

    torch.set_num_threads(1)
    print("| policy | export s | file kB | max abs diff | Policy.act us | ONNX us |")
    print("|---|---|---|---|---|---|")
    for path in args.policies:
        r = measure(path)
        print(
            f"| {r['policy']} | {r['export_s']:.1f} | {r['kb']:.0f} | {r['max_diff']:.1e} | "
            f"{r['eager_us']:.0f} | {r['onnx_us']:.0f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
