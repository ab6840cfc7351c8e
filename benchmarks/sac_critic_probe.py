"""What a SAC-family run's critic believes, read from its checkpoint (critics, their targets,
the actor and the replay buffer saved under ``sac``). Printed as JSON, one object per run.

On a sample of replay rows (``--rows``, drawn with ``--seed``), with the checkpoint's temperature
alpha:

- ``q_replay``: the mean min-Q of the stored decisions, Q(s, c);
- ``q_policy``: the same states with a fresh decision of the actor;
- ``q_uniform``: the same states with decisions uniform in the bounded parameter space: a
  critic whose estimate ran away everywhere (not only at the actor's choices) values these
  like the others;
- ``target`` and ``td_mean`` / ``td_abs``: the soft k-step target
  y = R + gamma^n (1 - terminal) (min Q'(s', c') - alpha log pi(c' | s')) with the target
  critics, and the mean of y - Q(s, c) (positive: the targets pull the estimate up) and of
  |y - Q|;
- ``soft_term``: the mean of -alpha log pi(c' | s') in the targets;
- ``feature_norm``, ``feature_cos``, ``feature_dot``: the first critic's last hidden features
  phi at (s, c) and at (s', c'): their mean norm, the mean cosine between the two and the mean
  dot product phi(s, c) . phi(s', c') (large, aligned features of consecutive decisions are the
  "co-adaptation" that Kumar et al. 2021, DR3, tie to TD divergence).

Printed with the command, the commit and the date (``{"command", "commit", "date", "runs"}``).

Used for docs/offpolicy.md ("Critic health"): did NDP-SAC's critic run away at the actor's
choices, or everywhere? ::

    python benchmarks/sac_critic_probe.py runs/sac_critic/push-v3-ndp-sac-k5-s0 \\
        runs/sac_critic/push-v3-ndp-sac-ln-k5-s0
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
import torch


def _hidden(mlp: Any, x: torch.Tensor) -> torch.Tensor:
    """The last hidden features [B, H] of an :class:`ndp.nets.mlp.MLP` (all but its output
    layer)."""
    for layer in list(mlp.net)[:-1]:
        x = layer(x)
    return x


def probe(run_dir: str | Path, rows: int = 4096, seed: int = 0) -> dict[str, Any]:
    """The statistics of the module doc for one run directory with a SAC-family checkpoint."""
    from ndp.rl.config import load_config
    from ndp.rl.policy import load_policy
    from ndp.rl.sac.learner import TwinQ, critic_input, scores_params
    from ndp.rl.sac.losses import critic_target
    from ndp.runs import load_checkpoint

    run_dir = Path(run_dir)
    try:
        ck = load_checkpoint(run_dir, kind="rl")
        cfg = load_config(run_dir / "config.json")
    except (FileNotFoundError, ValueError) as exc:
        raise SystemExit(f"run_dir: {exc}") from None
    if "sac" not in ck:
        raise SystemExit(
            f"run_dir: {run_dir} is not a SAC-family run (its checkpoint has no 'sac')"
        )
    torch.manual_seed(seed)
    pol = load_policy(run_dir)
    model, s = pol.model, ck["sac"]
    data = s["replay"]["data"]
    n = len(data["u"])
    if n == 0:
        raise SystemExit(f"run_dir: {run_dir}'s replay buffer is empty")
    pick = np.random.default_rng(seed).choice(n, min(rows, n), replace=False)
    hidden, activation = cfg.policy.hidden, cfg.policy.activation
    assert hidden is not None and activation is not None  # a run's config is resolved
    c_dim = data["critic_in"].shape[1]

    def critic(key: str) -> TwinQ:
        net = TwinQ(int(ck["obs_dim"]), c_dim, tuple(hidden), activation,
                    cfg.sac.critic_layer_norm)  # fmt: skip
        net.load_state_dict(s[key])
        return net.eval()

    q_net, q_targ = critic("critic"), critic("critic_target")
    alpha = float(s["log_alpha"].exp())
    low = torch.as_tensor(pol.spec.action_low, dtype=torch.float32)
    high = torch.as_tensor(pol.spec.action_high, dtype=torch.float32)
    params = scores_params(model.head, cfg.sac.critic_input)

    def c_of(u: torch.Tensor, dist: Any) -> torch.Tensor:  # the learner's critic input
        return critic_input(u, dist, params, low, high)

    def col(key: str) -> torch.Tensor:
        return torch.as_tensor(data[key][pick], dtype=torch.float32)

    obs, nobs = col("obs"), col("next_obs")
    with torch.no_grad():
        dist, _ = model.distribution(obs, col("y0"), col("dy0"))
        dist_n, _ = model.distribution(nobs, col("next_y0"), col("next_dy0"))
        c = col("critic_in")
        q = torch.minimum(*q_net(obs, c))
        q_pol = torch.minimum(*q_net(obs, c_of(dist.sample(), dist)))
        uni = torch.atanh(torch.empty_like(col("u")).uniform_(-0.999999, 0.999999))
        q_uni = torch.minimum(*q_net(obs, c_of(uni, dist)))
        u_n = dist_n.sample()
        c_n = c_of(u_n, dist_n)
        logp_n = dist_n.log_prob(u_n)[:, 0]
        soft = -alpha * logp_n
        y = critic_target(col("ret")[:, 0], col("discount")[:, 0], *q_targ(nobs, c_n), logp_n,
                          alpha)  # fmt: skip
        f = _hidden(q_net.q1, torch.cat([obs, c], -1))
        f_n = _hidden(q_net.q1, torch.cat([nobs, c_n], -1))
    td = y - q
    return {
        "run": run_dir.name,
        "global_step": int(ck["global_step"]),
        "rows": len(pick),
        "alpha": alpha,
        "critic_layer_norm": bool(cfg.sac.critic_layer_norm),
        "q_replay": float(q.mean()),
        "q_policy": float(q_pol.mean()),
        "q_uniform": float(q_uni.mean()),
        "target": float(y.mean()),
        "td_mean": float(td.mean()),
        "td_abs": float(td.abs().mean()),
        "soft_term": float(soft.mean()),
        "mean_chunk_return": float(col("ret")[:, 0].mean()),
        "feature_norm": float(f.norm(dim=-1).mean()),
        "feature_cos": float(torch.nn.functional.cosine_similarity(f, f_n, dim=-1).mean()),
        "feature_dot": float((f * f_n).sum(-1).mean()),
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run_dirs", nargs="+", help="SAC-family run directories with a checkpoint")
    p.add_argument("--rows", type=int, default=4096, help="replay rows sampled per run")
    p.add_argument("--seed", type=int, default=0, help="seed of the sample and fresh decisions")
    args = p.parse_args(argv)
    if args.rows < 1:
        raise SystemExit(f"--rows: expected an integer >= 1, got {args.rows}")
    import datetime as dt
    import shlex
    import sys

    from ndp.provenance import git_commit

    out = {
        "command": shlex.join(["python", "benchmarks/sac_critic_probe.py", *sys.argv[1:]]),
        "commit": git_commit(),
        "date": dt.datetime.now().isoformat(timespec="minutes"),
        "runs": [probe(r, args.rows, args.seed) for r in args.run_dirs],
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
