"""DMP layer speed and memory: fast linear-map path vs reference Euler loop vs a matmul floor.

Prints one JSON document. For each shape it times forward + backward (gradients of positions,
velocities and accelerations w.r.t. every input) of

- ``fast``:    the :class:`ndp.dmp.DMPLayer` as users call it (fast path, finite check on),
- ``fast_unchecked``: the functional fast path without the finite check,
- ``loop``:    the reference Euler loop (:func:`ndp.dmp.dmp_rollout_reference`),
- ``matmul``:  one dense [B*D, N+3] @ [N+3, 3*n_out] product with the same operand sizes
  (forward + backward), the practical floor of the fast path.

``check_cost`` is the cost of the layer's default finite check: the median, over ``--pairs``
back-to-back calls in alternating order, of time(``fast``) / time(``fast_unchecked``) (target
<= 1.2; the shape ``check_cost`` is a policy-sized batch, B 256, D 7, N 10, 100 steps).

Memory is the bytes autograd saves for backward plus the outputs (exact, from saved-tensor
hooks), and on CUDA also the peak allocated memory.

Usage: python benchmarks/dmp_speed.py [--device cpu|cuda] [--threads 1] [--rounds 3]

One thread by default: on a shared 2-core machine a second intra-op thread is often descheduled
and makes every small kernel several times slower; pass --threads 2 on a quiet machine.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import shlex
import sys

import torch
import torch.utils.benchmark as tb

from ndp.dmp import DMPConfig, DMPLayer, dmp_rollout, dmp_rollout_reference
from ndp.experiments.provenance import git_commit
from ndp.io import atomic_write_text

SHAPES = {
    # name: (B, D, N, steps, subsample)
    "imitation": (100, 2, 30, 300, 1),
    "rl": (2048, 4, 6, 40, 8),
    "rl_all_steps": (2048, 4, 6, 40, 1),
    # the finite check's cost at a policy-sized batch (fast / fast unchecked)
    "check_cost": (256, 7, 10, 100, 1),
}


FAST_OVER_MATMUL = {"imitation": 1.5, "rl": 1.5}
"""The fast path's targets as a multiple of the matmul floor (issue "speed, part 3"); 3 for the
other shapes."""


def _inputs(b, d, n, device, dtype):
    gen = torch.Generator().manual_seed(0)
    ts = [
        torch.randn(b, d, generator=gen),
        torch.randn(b, d, n, generator=gen) * 5,
        torch.randn(b, d, generator=gen),
        torch.randn(b, d, generator=gen),
    ]
    return [t.to(device=device, dtype=dtype).requires_grad_(True) for t in ts]


def _fwd_bwd(fn, inputs):
    out = fn(*inputs)
    loss = out[0].sum() + out[1].sum() + out[2].sum()
    loss.backward()
    for t in inputs:
        t.grad = None


def _saved_bytes(fn, inputs) -> int:
    total = 0

    def pack(t):
        nonlocal total
        total += t.numel() * t.element_size()
        return t

    with torch.autograd.graph.saved_tensors_hooks(pack, lambda t: t):
        out = fn(*inputs)
    outs = sum(o.numel() * o.element_size() for o in (out if isinstance(out, tuple) else [out]))
    # views of one buffer (the fast path) count once
    if (
        hasattr(out, "pos")
        and out.pos.untyped_storage().data_ptr() == out.acc.untyped_storage().data_ptr()
    ):
        outs = out.pos.untyped_storage().nbytes()
    return total + outs


def _time(fn, inputs, device, min_time) -> float:
    stmt = "f(inputs)"
    if device == "cuda":
        stmt += "; torch.cuda.synchronize()"
    timer = tb.Timer(
        stmt=stmt,
        globals={"f": lambda x: _fwd_bwd(fn, x), "inputs": inputs, "torch": torch},
        num_threads=torch.get_num_threads(),
    )
    return timer.blocked_autorange(min_run_time=min_time).median


def bench_shape(name, shape, device, dtype, min_time, rounds, pairs=1000):
    b, d, n, steps, sub = shape
    cfg = DMPConfig(n_basis=n, a_z=25.0, steps=steps, subsample=sub)
    layer = DMPLayer(cfg)
    inputs = _inputs(b, d, n, device, dtype)
    m = torch.randn(n + 3, 3 * cfg.n_out, device=device, dtype=dtype)
    a = torch.randn(b * d, n + 3, device=device, dtype=dtype, requires_grad=True)

    def matmul(a_):
        out = a_ @ m
        return (out, out[:, :0], out[:, :0])

    candidates = {
        "fast": lambda *x: layer(*x),
        "fast_unchecked": lambda *x: dmp_rollout(*x, cfg=cfg, method="fast"),
        "loop": lambda *x: dmp_rollout_reference(*x, cfg=cfg),
    }
    res = {"B": b, "D": d, "N": n, "steps": steps, "subsample": sub, "n_out": cfg.n_out}
    for key, fn in candidates.items():
        _fwd_bwd(fn, inputs)  # warm-up (builds the cached map)
        res[f"{key}_saved_bytes"] = _saved_bytes(fn, inputs)
        if device == "cuda":
            torch.cuda.reset_peak_memory_stats()
            base = torch.cuda.memory_allocated()
            _fwd_bwd(fn, inputs)
            res[f"{key}_cuda_peak_bytes"] = torch.cuda.max_memory_allocated() - base
    # Interleaved rounds; the best median of each candidate resists a noisy, shared machine.
    best: dict[str, float] = {}
    for _ in range(rounds):
        for key, fn in candidates.items():
            t = _time(fn, inputs, device, min_time)
            best[key] = min(best.get(key, float("inf")), t)
        best["matmul"] = min(best.get("matmul", float("inf")), _time(matmul, [a], device, min_time))
    for key, t in best.items():
        res[f"{key}_ms"] = round(t * 1e3, 4)
    res["loop_over_fast"] = round(res["loop_ms"] / res["fast_ms"], 1)
    res["fast_over_matmul"] = round(res["fast_ms"] / res["matmul_ms"], 2)
    res["fast_unchecked_over_matmul"] = round(res["fast_unchecked_ms"] / res["matmul_ms"], 2)
    res["check_cost"] = paired_ratio(
        candidates["fast"], candidates["fast_unchecked"], inputs, pairs
    )
    return res


def paired_ratio(fn_a, fn_b, inputs, pairs: int) -> float:
    """Median over ``pairs`` back-to-back calls of time(a) / time(b), the order alternating:
    on a loaded machine both calls of a pair see the same load, so the ratio stays meaningful
    when the separate medians drift (a slow phase hits one candidate's timing block only)."""
    import statistics
    import time

    ratios = []
    for i in range(pairs):
        ts = {}
        for key, fn in (("a", fn_a), ("b", fn_b)) if i % 2 else (("b", fn_b), ("a", fn_a)):
            t0 = time.perf_counter()
            _fwd_bwd(fn, inputs)
            ts[key] = time.perf_counter() - t0
        ratios.append(ts["a"] / ts["b"])
    return round(statistics.median(ratios), 3)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default="cpu", choices=["cpu", "cuda"])
    p.add_argument("--dtype", default="float32", choices=["float32", "float64"])
    p.add_argument("--threads", type=int, default=1, help="torch intra-op threads")
    p.add_argument("--min-time", type=float, default=0.5, help="seconds per candidate and round")
    p.add_argument("--rounds", type=int, default=3, help="interleaved timing rounds (best kept)")
    p.add_argument("--shapes", nargs="+", default=list(SHAPES), choices=list(SHAPES))
    p.add_argument(
        "--pairs", type=int, default=1000, help="back-to-back call pairs of the check-cost ratio"
    )
    p.add_argument("--md-out", default=None, help="also write a markdown table to this file")
    args = p.parse_args(argv)
    if args.device == "cuda" and not torch.cuda.is_available():
        print("--device: expected an available CUDA device, found none", file=sys.stderr)
        return 2
    torch.set_num_threads(args.threads)
    dtype = getattr(torch, args.dtype)
    results = {
        "benchmark": "dmp_speed",
        "device": args.device,
        "device_name": torch.cuda.get_device_name()
        if args.device == "cuda"
        else platform.processor() or platform.machine(),
        "dtype": args.dtype,
        "torch": torch.__version__,
        "commit": git_commit(),
        "command": shlex.join(
            ["python", "benchmarks/dmp_speed.py", *(sys.argv[1:] if argv is None else argv)]
        ),
        "date": datetime.date.today().isoformat(),
        "threads": torch.get_num_threads(),
        "targets": {
            "loop_over_fast_imitation": ">= 30",
            "fast_over_matmul_imitation": "<= 1.5 (issue 'speed, part 3')",
            "fast_over_matmul_rl": "<= 1.5 (issue 'speed, part 3')",
            "fast_over_matmul (other shapes)": "<= 3",
            "check_cost": "<= 1.2",
        },
        "shapes": {},
    }
    for name in args.shapes:
        results["shapes"][name] = bench_shape(
            name, SHAPES[name], args.device, dtype, args.min_time, args.rounds, args.pairs
        )
    s = results["shapes"]
    results["targets_met"] = {
        "loop_over_fast_imitation": s.get("imitation", {}).get("loop_over_fast", 0) >= 30,
        **{
            f"fast_over_matmul_{k}": v["fast_over_matmul"] <= FAST_OVER_MATMUL.get(k, 3.0)
            for k, v in s.items()
        },
    }
    if "check_cost" in s:
        results["targets_met"]["check_cost"] = s["check_cost"]["check_cost"] <= 1.2
    print(json.dumps(results, indent=2))
    if args.md_out:
        atomic_write_text(args.md_out, markdown_table(results))
    return 0


def markdown_table(results: dict) -> str:
    """The speed table of docs/dmp.md, generated from one benchmark run."""
    lines = [
        f"Command: `{results.get('command', 'python benchmarks/dmp_speed.py')}`  ",
        f"Commit: {results['commit']}, date: {results.get('date', 'unknown')}.  ",
        f"Device: {results['device']} ({results['device_name']}), {results['dtype']}, "
        f"torch {results['torch']}, {results['threads']} thread(s). "
        "Forward + backward, best median of interleaved rounds.",
        "",
        "| shape | B | D | N | steps / stride | fast (layer) ms | fast unchecked ms | loop ms "
        "| matmul floor ms | loop / fast | fast / floor | check cost (fast / unchecked, paired) "
        "| saved for backward (fast / loop) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in results["shapes"].items():
        lines.append(
            f"| {name} | {r['B']} | {r['D']} | {r['N']} | {r['steps']} / {r['subsample']} "
            f"| {r['fast_ms']:.3f} | {r['fast_unchecked_ms']:.3f} | {r['loop_ms']:.2f} "
            f"| {r['matmul_ms']:.3f} | {r['loop_over_fast']:.1f}x | {r['fast_over_matmul']:.2f}x "
            f"| {r['check_cost']:.2f}x "
            f"| {r['fast_saved_bytes'] / 1e6:.2f} MB / {r['loop_saved_bytes'] / 1e6:.2f} MB |"
        )
    lines += ["", f"Targets met: {json.dumps(results['targets_met'])}", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
