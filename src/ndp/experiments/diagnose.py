"""Diagnostic of the NDP head's handicaps on a real rollout (docs/rl.md, "Diagnostic").

For a policy (fresh at initialisation, or a trained run) it runs ``decisions`` decisions of the
stochastic policy in one chunked env and reports, per sub-step j of a decision:

- ``intended_disp[j]``: mean |a_mean| of the delta DoF times the action scale (m or rad per
  sub-step): what the policy's mean asks for;
- ``executed_disp[j]``: mean |clip(a_sample)| times the action scale: what reaches the
  simulator after the noise and the bound (E[clip(m + n)] is biased toward 0 near the bounds);
- ``moved_disp[j]``: mean |change of the commanded target| (Meta-World mocap, Jaco joint
  targets) per sub-step, measured in the env;
- ``grip_mean_std[j]``: std over decisions of the absolute DoF's (gripper) sub-step mean, and
  ``grip_noise_corr[j]``: its correlation with the previous decision's executed command (1.0:
  the previous decision's noise steers the command; near 0: it does not).

A regression of any handicap shows here: ``executed / intended`` far below 1 at saturated
sub-steps (mean clip, goal bound), ``grip_noise_corr`` near 1 (gripper start), ``moved`` far
below ``executed`` (targets at their bounds).

Usage::

    python -m ndp.experiments.diagnose --task push-v3 --algo ndp            # at initialisation
    python -m ndp.experiments.diagnose --run runs/push-v3-ndp-s0            # a trained run
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from ndp.chunk_info import dmp_start
from ndp.policies import build_actor_critic
from ndp.rl.normalize import ObsNormalizer

if TYPE_CHECKING:
    from ndp.policies.actor_critic import ActorCritic
    from ndp.rl.config import TrainConfig
    from ndp.rl.normalize import ObsNormalizer


def _policy(
    task: str | None, algo: str, run: str | None, overrides: dict[str, Any]
) -> tuple[TrainConfig, Any, ActorCritic, ObsNormalizer]:
    """(config, spec, model, obs normaliser) of a fresh policy or a trained run (the spec: a
    ``TaskSpec``, or a trained run's ``PolicySpec`` as ``Policy.spec``)."""
    import dataclasses

    from ndp.rl.config import TrainConfig, resolve_config
    from ndp.rl.envs import resolve_task

    if run is not None:
        from ndp.rl.evaluate import load_policy

        pol = load_policy(run)
        return pol.cfg, pol.spec, pol.model, pol.obs_norm
    if task is None:
        raise ValueError("task: give --task (fresh policy) or --run (trained)")
    spec = resolve_task(task).spec
    base = TrainConfig(task=task, algo=algo)
    cfg = resolve_config(dataclasses.replace(base, policy=base.policy.updated(**overrides)), spec)
    torch.manual_seed(cfg.seed)
    model = build_actor_critic(spec.obs_dim, spec, cfg.policy)
    # a fresh normaliser still learns the observation statistics during the diagnostic rollout
    return cfg, spec, model, ObsNormalizer(spec.obs_dim, cfg.ppo.clip_obs, cfg.ppo.norm_obs)


def diagnose(
    task: str | None = None,
    algo: str = "ndp",
    run: str | None = None,
    decisions: int = 300,
    seed: int = 0,
    **overrides: Any,
) -> dict[str, Any]:
    """Run the diagnostic; returns a JSON-ready dict (see the module docstring)."""
    from ndp.envs.chunked import ChunkedEnv
    from ndp.rl.envs import resolve_task

    cfg, spec, model, obs_norm = _policy(task, algo, run, overrides)
    torch.set_num_threads(1)
    k = cfg.k
    env = ChunkedEnv(
        resolve_task(cfg.task, **cfg.env_options()).make(horizon=cfg.horizon),
        k,
        **cfg.chunk_options(),
    )
    key = "cmd" if cfg.policy.dmp_state == "commanded" else "dmp"
    scale = np.array([s if s > 0 else 1.0 for s in spec.action_scale])[: spec.action_dim]
    delta = ~np.array(spec.action_absolute)[: spec.action_dim]
    absolute = np.flatnonzero(~delta)
    low, high = np.array(spec.action_low), np.array(spec.action_high)
    gen = torch.Generator().manual_seed(seed)
    obs, info = env.reset(seed=seed)
    intended, executed, moved, grip_mean, prev_cmd = [], [], [], [], []
    last_cmd = info[f"{key}_y0"][absolute] if absolute.size else None
    for _ in range(decisions):
        o = torch.from_numpy(obs_norm(np.asarray(obs, dtype=np.float64)[None], update=True))
        y0 = torch.as_tensor(info[f"{key}_y0"], dtype=torch.float32)[None]
        dy0 = torch.as_tensor(info[f"{key}_dy0"], dtype=torch.float32)[None]
        with torch.no_grad():
            dist, _ = model.distribution(o, y0, dy0)
            z = dist.sample(gen)
            act = dist.actions(z)[0].numpy()
            mean = dist.actions(dist.mode())[0].numpy()
        ex = np.clip(act, low, high)
        intended.append(np.abs(mean[:, delta]) * scale[delta])
        executed.append(np.abs(ex[:, delta]) * scale[delta])
        before = info[f"{key}_y0"]
        if absolute.size:
            assert last_cmd is not None  # set whenever there are absolute DoF
            grip_mean.append(mean[:, absolute[0]])
            prev_cmd.append(float(last_cmd[0]))
        obs, _, term, trunc, info = env.step(act)
        # commanded-target motion per sub-step of this decision (measured in the env)
        cmd_now = dmp_start(info, "commanded")[0]
        moved.append(
            np.abs(cmd_now[: len(delta)][delta] - np.asarray(before)[: len(delta)][delta]) / k
        )
        last_cmd = ex[-1, absolute] if absolute.size else None
        if term or trunc:
            obs, info = env.reset()
            last_cmd = info[f"{key}_y0"][absolute] if absolute.size else None
    env.close()
    out: dict[str, Any] = {
        "task": cfg.task,
        "algo": cfg.algo,
        "run": run,
        "decisions": decisions,
        "k": k,
        "policy": {
            **{
                f: getattr(cfg.policy.ndp, f)
                for f in ("mean_clip", "forcing", "absolute_mode", "goal_scale", "param_noise")
            },
            **{f: getattr(cfg.policy, f) for f in ("dmp_state", "dmp_velocity", "init_log_std")},
        },
        "intended_disp": np.mean(intended, axis=(0, 2)).tolist(),
        "executed_disp": np.mean(executed, axis=(0, 2)).tolist(),
        "moved_disp_per_substep": float(np.mean(moved)),
        "action_scale": float(scale[delta].mean()),
    }
    if grip_mean:
        g = np.array(grip_mean)  # [decisions, k]
        p = np.array(prev_cmd)
        out["grip_mean_std"] = g.std(0).tolist()
        out["grip_noise_corr"] = [
            float(np.corrcoef(g[:, j], p)[0, 1]) if g[:, j].std() > 1e-9 and p.std() > 1e-9 else 0.0
            for j in range(k)
        ]
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--task", default=None)
    p.add_argument("--algo", default="ndp")
    p.add_argument("--run", default=None, help="a trained run directory (else a fresh policy)")
    p.add_argument("--decisions", type=int, default=300)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="FIELD=VALUE",
        help="PolicyConfig overrides of a fresh policy, e.g. mean_clip=true",
    )
    args = p.parse_args(argv)
    overrides: dict[str, Any] = {}
    for item in args.set:
        name, _, val = item.partition("=")
        try:
            overrides[name] = json.loads(val)
        except json.JSONDecodeError:
            overrides[name] = val  # a plain string such as forcing=goal
    res = diagnose(args.task, args.algo, args.run, args.decisions, args.seed, **overrides)
    print(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
