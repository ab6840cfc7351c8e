"""The rollout decision call of two versions of the package in one process, interleaved: the
ratio new / old of ms per call, which stays meaningful on a loaded machine (both versions see
the same load), and a check that both give bit-identical outputs.

Each version opens a push-v3 run through its own run driver (batch 4, one thread, untrained
weights, the new one given the old one's weights) and times ``Trainer.decide`` plus what that
version's ``collect`` does with the head's diagnostics each decision (before ``mean_of_means``
existed: a mean and ``float()`` of each per call; with it: kept and averaged once per rollout).
Blocks of ``--calls`` calls alternate between the versions; the medians and the median of the
per-block ratios are printed as JSON.

Example (the numbers in docs/rl-results.md, "The decision call")::

    git worktree add /tmp/ndp-base 57f077c
    python benchmarks/policy_call_ab.py --base-src /tmp/ndp-base/src --methods ndp ppo ppo-multi
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import torch

ROOT = Path(__file__).resolve().parents[1]


def _open(src: str, method: str) -> tuple[Any, ModuleType]:
    """A run of ``method`` opened with the package at ``src``, and that version's trainer
    module; the version's modules are then removed from ``sys.modules`` (the objects stay)."""
    sys.path.insert(0, src)
    try:
        import ndp.rl.onpolicy.trainer as trainer_module
        from ndp.rl.config import TrainConfig
        from ndp.rl.run import open_run

        assert trainer_module.__file__ is not None and trainer_module.__file__.startswith(src)
        cfg = TrainConfig(task="push-v3", algo=method, steps=1, num_envs=4,
                          run_dir=str(Path(tempfile.mkdtemp()) / "r"), progress=False,
                          tensorboard=False, vector="sync", eval_every=0)  # fmt: skip
        opened = open_run(cfg)
    finally:
        for name in [k for k in sys.modules if k == "ndp" or k.startswith("ndp.")]:
            del sys.modules[name]
        sys.path.remove(src)
    return opened, trainer_module


def _call(tr: Any, module: ModuleType, obs: torch.Tensor, y0: Any, dy0: Any) -> Callable[[], None]:
    """One decision as that version's rollout makes it (its diagnostics handling included)."""
    if not hasattr(module, "mean_of_means"):

        def old() -> None:
            d = tr.decide(obs, y0, dy0)
            for v in d.aux.values():
                float(v.mean())

        return old
    kept: dict[str, list[torch.Tensor]] = {}

    def new() -> None:
        d = tr.decide(obs, y0, dy0)
        for key, v in d.aux.items():
            rows = kept.setdefault(key, [])
            rows.append(v)
            if len(rows) == tr.T:
                module.mean_of_means(rows)
                rows.clear()

    return new


def compare(base_src: str, new_src: str, method: str, blocks: int, calls: int) -> dict[str, Any]:
    """Bit-identity over 100 varied calls, then interleaved timing of both versions."""
    old, old_mod = _open(base_src, method)
    new, new_mod = _open(new_src, method)
    try:
        t_old, t_new = old.learner, new.learner
        t_new.rollout_model.load_state_dict(t_old.rollout_model.state_dict())
        y0, dy0 = t_old.decision_start()
        outs = []
        for tr in (t_old, t_new):
            torch.manual_seed(0)
            res = []
            for i in range(100):
                o = torch.randn(4, tr.obs_dim) * (1 + i % 7)
                d = tr.decide(o, y0 + i * 0.01, dy0 - i * 0.02)
                res.append([d.z, d.logp, d.values, d.act, *(d.aux[k] for k in sorted(d.aux))])
            outs.append(res)
        same = all(
            torch.equal(a, b)
            for ra, rb in zip(*outs, strict=True)
            for a, b in zip(ra, rb, strict=True)
        )
        obs = torch.randn(4, t_old.obs_dim)
        fns = {"old": _call(t_old, old_mod, obs, y0, dy0),
               "new": _call(t_new, new_mod, obs, y0, dy0)}  # fmt: skip
        for f in fns.values():
            for _ in range(300):
                f()
        ms: dict[str, list[float]] = {"old": [], "new": []}
        for _ in range(blocks):
            for name, f in fns.items():
                t0 = time.perf_counter()
                for _ in range(calls):
                    f()
                ms[name].append((time.perf_counter() - t0) / calls * 1e3)
        ratios = [n / o for o, n in zip(ms["old"], ms["new"], strict=True)]
        return {"method": method, "bit_identical": same,
                "old_ms": round(statistics.median(ms["old"]), 4),
                "new_ms": round(statistics.median(ms["new"]), 4),
                "ratio_median": round(statistics.median(ratios), 3),
                "ratio_range": [round(min(ratios), 3), round(max(ratios), 3)]}  # fmt: skip
    finally:
        old.close()
        new.close()


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--base-src", required=True, help="the old version's src folder")
    p.add_argument("--new-src", default=str(ROOT / "src"), help="the new one's (this checkout)")
    p.add_argument("--methods", nargs="+", default=["ndp", "ppo", "ppo-multi"])
    p.add_argument("--blocks", type=int, default=9)
    p.add_argument("--calls", type=int, default=1000)
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    rows = [compare(args.base_src, args.new_src, m, args.blocks, args.calls) for m in args.methods]
    print(json.dumps(rows, indent=1))
    return rows


if __name__ == "__main__":
    main()
