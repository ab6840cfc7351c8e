"""Cost of one PPO update (10 epochs x 32 mini-batches over 2048 env steps) per method; prints JSON.

For each method it collects one rollout on ``--task`` (sync env) and times ``Trainer.learn`` on
it (median of ``--repeats`` after one warm-up update), and reports beside it:

- ``compile_mlps``: the same update with the actor and critic MLPs wrapped in
  ``torch.compile`` (compile time of the first update reported apart): on this CPU it is slower;
- ``floor``: the bare networks' share, forward + backward + one fused Adam step of two
  [100, 100] tanh MLPs on 64 observations, 320 times: what no loss or head fusion can go below.

Example::

    python benchmarks/rl_update_speed.py --task reach-v3 --repeats 3
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

from ndp.provenance import git_commit


def _trainer(task: str, algo: str, tmp: str):
    """The run of ``algo`` on ``task``, opened by the run driver (``.learner``: the Trainer)."""
    from ndp.rl.config import TrainConfig
    from ndp.rl.run import open_run

    return open_run(
        TrainConfig(
            task=task,
            algo=algo,
            steps=10**6,
            run_dir=str(Path(tmp) / algo),
            progress=False,
            tensorboard=False,
            vector="sync",
        )
    )


def time_update(task: str, algo: str, repeats: int, compile_mlps: bool) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp:
        opened = _trainer(task, algo, tmp)
        tr = opened.learner
        try:
            if compile_mlps:
                tr.model.actor = torch.compile(tr.model.actor, dynamic=True)
                tr.model.critic = torch.compile(tr.model.critic, dynamic=True)
            batch = tr.collect()
            t0 = time.perf_counter()
            tr.learn(batch)
            first = time.perf_counter() - t0
            times = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                tr.learn(batch)
                times.append(time.perf_counter() - t0)
        finally:
            opened.close()
    return {"update_s": statistics.median(times), "first_update_s": first}


def floor(obs_dim: int, repeats: int) -> float:
    """Seconds for 320 forward + backward + fused Adam steps of two bare MLPs on batch 64."""
    from torch import nn

    def mlp(out: int) -> nn.Module:
        return nn.Sequential(
            nn.Linear(obs_dim, 100), nn.Tanh(), nn.Linear(100, 100), nn.Tanh(), nn.Linear(100, out)
        )

    actor, critic = mlp(4), mlp(1)
    params = [*actor.parameters(), *critic.parameters()]
    opt = torch.optim.Adam(params, lr=3e-4, eps=1e-5, fused=True)
    x, t = torch.randn(64, obs_dim), torch.randn(64, 4)

    def step() -> None:
        loss = ((actor(x) - t) ** 2).mean() + (critic(x) ** 2).mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    for _ in range(50):
        step()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(320):
            step()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--task", default="reach-v3")
    p.add_argument("--methods", nargs="+", default=["ppo", "ppo-multi", "ndp"])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--no-compile", action="store_true", help="skip the torch.compile rows")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    res: dict[str, dict[str, float]] = {}
    for m in args.methods:
        res[m] = time_update(args.task, m, args.repeats, False)
        if not args.no_compile:
            c = time_update(args.task, m, args.repeats, True)
            res[m]["compile_mlps_update_s"] = c["update_s"]
            res[m]["compile_mlps_first_update_s"] = c["first_update_s"]
    from ndp.envs import get_task_spec

    out = {
        "task": args.task,
        "commit": git_commit(),
        "results": res,
        "floor_s": floor(get_task_spec(args.task).obs_dim, args.repeats),
        "command": "python benchmarks/rl_update_speed.py "
        + " ".join(argv if argv is not None else sys.argv[1:]),
    }
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
