"""Cost of one rollout decision call (ms) per method: what the main process spends per decision
besides stepping the envs.

The call a rollout makes each decision (``ndp.rl.onpolicy.trainer.Trainer.decide``, which
``Trainer.collect`` calls): the policy's distribution (NDP: the DMP head decoding goal and
weights into k sub-actions through its fused action map), its exploration wrapper, a sample,
its log-prob, the value, the actions inside their bounds and their finite check, and the
head's diagnostics (kept per decision, averaged once per rollout of T decisions, as
``Trainer.collect`` does); batch = ``--num-envs`` (4), no gradient, one thread.
Measured on the networks of a run opened through the run driver (``ndp.rl.run.open_run``,
untrained weights; the cost does not depend on them). Per env step it is the call divided by k
(5 for NDP and PPO-multi, 1 for PPO).

Example (the numbers of docs/rl-results.md's throughput section)::

    python benchmarks/policy_call.py --methods ppo ppo-multi ndp --calls 2000
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import torch

from ndp.experiments.provenance import git_commit


def call_ms(method: str, task: str, num_envs: int, calls: int, repeats: int) -> dict[str, float]:
    """Median (over ``repeats``) ms per decision call of ``method``, and its k."""
    from ndp.rl.config import TrainConfig
    from ndp.rl.onpolicy.trainer import Trainer, mean_of_means
    from ndp.rl.run import open_run

    with tempfile.TemporaryDirectory() as tmp:
        cfg = TrainConfig(
            task=task,
            algo=method,
            steps=1,
            num_envs=num_envs,
            run_dir=str(Path(tmp) / "r"),
            progress=False,
            tensorboard=False,
            vector="sync",
            eval_every=0,
        )
        opened = open_run(cfg)
        try:
            tr = opened.learner
            if not isinstance(tr, Trainer):
                raise ValueError(f"methods: {method!r} is not an on-policy method")
            y0, dy0 = tr.decision_start()  # the envs reset: the state a decision starts from
            obs = torch.randn(num_envs, tr.obs_dim)

            kept: dict[str, list[torch.Tensor]] = {}

            def one() -> None:
                d = tr.decide(obs, y0, dy0)
                for key, v in d.aux.items():  # kept per decision, reduced once per rollout
                    rows = kept.setdefault(key, [])
                    rows.append(v)
                    if len(rows) == tr.T:
                        mean_of_means(rows)
                        rows.clear()

            for _ in range(calls // 10):
                one()
            times = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                for _ in range(calls):
                    one()
                times.append((time.perf_counter() - t0) / calls * 1e3)
            return {"ms_per_call": statistics.median(times), "k": float(tr.k)}
        finally:
            opened.close()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--task", default="push-v3")
    p.add_argument("--methods", nargs="+", default=["ppo", "ppo-multi", "ndp"])
    p.add_argument("--num-envs", type=int, default=4)
    p.add_argument("--calls", type=int, default=2000)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    res = {}
    for m in args.methods:
        r = call_ms(m, args.task, args.num_envs, args.calls, args.repeats)
        r["ms_per_env_step"] = r["ms_per_call"] / r["k"]
        res[m] = r
    out = {
        "task": args.task,
        "num_envs": args.num_envs,
        "commit": git_commit(),
        "command": "python benchmarks/policy_call.py "
        + " ".join(sys.argv[1:] if argv is None else argv),
        "results": res,
    }
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
