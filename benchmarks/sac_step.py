"""Cost (ms) of the parts of one SAC gradient step, with the optimiser and target update the
learner uses (``ndp.rl.sac.learner``) against the PyTorch defaults, in one process.

A SAC step on a CPU core is its linear layers and their backward; this measures what the
learner can change around them: the critics' Adam step (fused against the default per-tensor
loop) and the soft target update (one ``foreach`` lerp against a per-parameter loop). The
networks are the learner's twin critics (256-256 ReLU) on push-v3's sizes (observation 39,
action 4), batch 256, one thread; rounds interleave the variants and the minimum is kept.

Example (the numbers of docs/offpolicy.md's speed section)::

    python benchmarks/sac_step.py --steps 300 --rounds 3
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from collections.abc import Callable

import torch

from ndp.experiments.provenance import git_commit
from ndp.rl.optim import soft_update
from ndp.rl.sac.learner import TwinQ


def main(argv: list[str] | None = None) -> dict[str, object]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300, help="timed steps per variant and round")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds (minimum kept)")
    ap.add_argument("--batch", type=int, default=256)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    torch.manual_seed(0)
    obs_dim, act_dim = 39, 4
    critic = TwinQ(obs_dim, act_dim, (256, 256), "relu")
    target = copy.deepcopy(critic).requires_grad_(False)
    obs, act = torch.randn(args.batch, obs_dim), torch.randn(args.batch, act_dim)
    y = torch.randn(args.batch)

    def critic_step(opt: torch.optim.Optimizer) -> None:
        q1, q2 = critic(obs, act)
        loss = 0.5 * (((q1 - y) ** 2).mean() + ((q2 - y) ** 2).mean())
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    def soft_loop() -> None:
        with torch.no_grad():
            for t, s in zip(target.parameters(), critic.parameters(), strict=True):
                t.lerp_(s, 0.005)

    default = torch.optim.Adam(critic.parameters(), lr=3e-4)
    fused = torch.optim.Adam(critic.parameters(), lr=3e-4, fused=True)
    variants: dict[str, Callable[[], None]] = {
        "critic_step_adam_default": lambda: critic_step(default),
        "critic_step_adam_fused": lambda: critic_step(fused),
        "soft_update_loop": soft_loop,
        "soft_update_foreach": lambda: soft_update(target, critic, 0.005),
    }
    best: dict[str, float] = {}
    for _ in range(args.rounds):
        for name, fn in variants.items():
            for _ in range(10):
                fn()
            t0 = time.perf_counter()
            for _ in range(args.steps):
                fn()
            ms = (time.perf_counter() - t0) / args.steps * 1e3
            best[name] = min(best.get(name, ms), ms)
    out: dict[str, object] = {
        "commit": git_commit(),
        "batch": args.batch,
        "ms": {k: round(v, 4) for k, v in best.items()},
        "fused_vs_default": round(
            best["critic_step_adam_fused"] / best["critic_step_adam_default"], 3
        ),
        "foreach_vs_loop": round(best["soft_update_foreach"] / best["soft_update_loop"], 3),
    }
    print(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
