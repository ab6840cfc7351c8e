"""Diagnostics of the NDP head on real rollouts: its handicaps, and the conditioning of its map
(``ndp rl diagnose``; docs/rl.md, "Diagnostic" and "The conditioning of the action map").

**Handicaps** (:func:`diagnose`). For a policy (fresh at initialisation, or a trained run) it runs
``decisions`` decisions of the stochastic policy in one chunked env and reports, per sub-step j
of a decision:

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

**Conditioning** (:func:`jacobian_diagnostic`, ``--jacobian``). The Jacobian J [k A, P] of the
k sub-action means w.r.t. the head's P raw outputs (:meth:`ndp.policies.heads.NDPHead.
raw_jacobians`), and from it (:mod:`ndp.policies.conditioning`): the singular values, the
condition number over the reachable directions, the share of ``|J|_F^2`` in the goal and the
weight columns, and the fraction of raw outputs whose tanh slope is below 0.07 (saturated),

- ``raw0``: at raw = 0, y0 = dy0 = 0 (the nominal start; with 'amplitude' forcing J does not
  depend on the start);
- ``init``: at the fresh network's outputs (the run's config and seed) along ``episodes``
  deterministic episodes (its observation normaliser learning as in the first rollout);
- ``trained``: for a run or export, at its deterministic policy's outputs along ``episodes``
  episodes: every decision, the median and range.

Usage::

    ndp rl diagnose --task push-v3                      # handicaps, fresh policy
    ndp rl diagnose runs/push-v3-ndp-s0                 # handicaps, a trained run
    ndp rl diagnose --jacobian zoo:push-v3-ndp zoo:throw-ndp --png spectra.png
    ndp rl diagnose --jacobian --task push-v3 --set param_map=whitened

(``python -m ndp.experiments.diagnose`` takes the same options.)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from ndp.checks import check_int
from ndp.chunk_info import dmp_start
from ndp.envs.chunked import ChunkedEnv
from ndp.io import atomic_savefig, check_output_path
from ndp.policies import build_actor_critic
from ndp.policies.conditioning import (
    SATURATION_SLOPE,
    conditioning,
    saturated_fraction,
)
from ndp.rl.config import TrainConfig, resolve_config
from ndp.rl.envs import resolve_task
from ndp.rl.normalize import ObsNormalizer
from ndp.rl.policy import Policy, load_policy

if TYPE_CHECKING:
    from ndp.policies.actor_critic import ActorCritic
    from ndp.policies.heads import NDPHead
    from ndp.schema import TaskSchema

JACOBIAN_EPISODES = 3
"""Deterministic episodes per policy of the conditioning diagnostic (every decision is read)."""
RANK_RULE = (
    "reachable directions r = numerical rank of J_map (J with every tanh slope replaced by 1, W "
    "left out; = J at raw 0), singular values above max(M, P) * eps(float64) * s_max; "
    "condition = s_1 / s_r of J's singular values"
)
"""The rule of the condition number, stated in every report (ndp.policies.conditioning)."""


def _fresh(task: str, algo: str, overrides: Mapping[str, object]) -> Policy:
    """A fresh policy of ``task`` (its config resolved with ``overrides`` of the policy
    config, the network initialised from the config's seed, a fresh observation normaliser)."""
    spec = resolve_task(task).spec
    base = TrainConfig(task=task, algo=algo)
    cfg = resolve_config(dataclasses.replace(base, policy=base.policy.updated(**overrides)), spec)
    return _fresh_of(cfg, spec)


def _fresh_of(cfg: TrainConfig, spec: TaskSchema) -> Policy:
    """The network a run of ``cfg`` starts from (seeded with its seed), with a fresh normaliser
    (which learns the observation statistics during a diagnostic rollout, as in training)."""
    torch.manual_seed(cfg.seed)
    model = build_actor_critic(spec.obs_dim, spec, cfg.policy)
    return Policy(cfg, spec, model, ObsNormalizer(spec.obs_dim, cfg.clip_obs, cfg.norm_obs))


def _policy(
    task: str | None, algo: str, run: str | None, overrides: Mapping[str, object]
) -> tuple[TrainConfig, TaskSchema, ActorCritic, ObsNormalizer]:
    """(config, spec, model, obs normaliser) of a fresh policy or a trained run (the spec: a
    ``TaskSpec``, or a trained run's ``PolicySpec`` as ``Policy.spec``)."""
    if run is not None:
        pol = load_policy(run)
    elif task is None:
        raise ValueError("task: give --task (fresh policy) or a run (trained)")
    else:
        pol = _fresh(task, algo, overrides)
    return pol.cfg, pol.spec, pol.model, pol.obs_norm


def diagnose(
    task: str | None = None,
    algo: str = "ndp",
    run: str | None = None,
    decisions: int = 300,
    seed: int = 0,
    **overrides: object,
) -> dict[str, object]:
    """Run the handicap diagnostic; returns a JSON-ready dict (see the module docstring)."""
    cfg, spec, model, obs_norm = _policy(task, algo, run, overrides)
    torch.set_num_threads(1)
    k = cfg.k
    env = ChunkedEnv(
        resolve_task(cfg.task, **cfg.env_options()).make(horizon=cfg.horizon),
        k,
        **cfg.chunk_options(),
    )
    key = "cmd" if cfg.policy.dmp_state == "commanded" else "dmp"
    rec = _handicap_rollout(env, model, obs_norm, spec, key, decisions, seed)
    env.close()
    out: dict[str, object] = {
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
        "intended_disp": np.mean(rec.intended, axis=(0, 2)).tolist(),
        "executed_disp": np.mean(rec.executed, axis=(0, 2)).tolist(),
        "moved_disp_per_substep": float(np.mean(rec.moved)),
        "action_scale": rec.action_scale,
    }
    if rec.grip_mean:
        g = np.array(rec.grip_mean)  # [decisions, k]
        p = np.array(rec.prev_cmd)
        out["grip_mean_std"] = g.std(0).tolist()
        out["grip_noise_corr"] = [
            float(np.corrcoef(g[:, j], p)[0, 1]) if g[:, j].std() > 1e-9 and p.std() > 1e-9 else 0.0
            for j in range(k)
        ]
    return out


@dataclasses.dataclass
class _Handicaps:
    """What :func:`_handicap_rollout` records, a row per decision (the module docstring)."""

    action_scale: float
    """The mean action scale of the delta DoF (m or rad per sub-step)."""
    intended: list[np.ndarray] = dataclasses.field(default_factory=list)
    """|mean| of the delta DoF times their scale, [k, delta DoF]."""
    executed: list[np.ndarray] = dataclasses.field(default_factory=list)
    """|clip(sample)| of the delta DoF times their scale, [k, delta DoF]."""
    moved: list[np.ndarray] = dataclasses.field(default_factory=list)
    """The commanded target's motion per sub-step, [delta DoF]."""
    grip_mean: list[np.ndarray] = dataclasses.field(default_factory=list)
    """The first absolute DoF's sub-step means, [k] (none without absolute DoF)."""
    prev_cmd: list[float] = dataclasses.field(default_factory=list)
    """That DoF's command executed last before the decision."""


def _handicap_rollout(
    env: ChunkedEnv,
    model: ActorCritic,
    obs_norm: ObsNormalizer,
    spec: TaskSchema,
    key: str,
    decisions: int,
    seed: int,
) -> _Handicaps:
    """Run ``decisions`` decisions of the stochastic policy in ``env`` (the normaliser
    learning, episodes reset as they end) and record the handicaps of each; ``key``: the
    DMP frame's info prefix (``cmd`` or ``dmp``)."""
    k = env.k
    scale = np.array([s if s > 0 else 1.0 for s in spec.action_scale])[: spec.action_dim]
    delta = ~np.array(spec.action_absolute)[: spec.action_dim]
    absolute = np.flatnonzero(~delta)
    low, high = np.array(spec.action_low), np.array(spec.action_high)
    rec = _Handicaps(action_scale=float(scale[delta].mean()))
    gen = torch.Generator().manual_seed(seed)
    obs, info = env.reset(seed=seed)
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
        rec.intended.append(np.abs(mean[:, delta]) * scale[delta])
        rec.executed.append(np.abs(ex[:, delta]) * scale[delta])
        before = info[f"{key}_y0"]
        if absolute.size:
            assert last_cmd is not None  # set whenever there are absolute DoF
            rec.grip_mean.append(mean[:, absolute[0]])
            rec.prev_cmd.append(float(last_cmd[0]))
        obs, _, term, trunc, info = env.step(act)
        # commanded-target motion per sub-step of this decision (measured in the env)
        cmd_now = dmp_start(info, "commanded")[0]
        rec.moved.append(
            np.abs(cmd_now[: len(delta)][delta] - np.asarray(before)[: len(delta)][delta]) / k
        )
        last_cmd = ex[-1, absolute] if absolute.size else None
        if term or trunc:
            obs, info = env.reset()
            last_cmd = info[f"{key}_y0"][absolute] if absolute.size else None
    return rec


def _decisions(
    policy: Policy, episodes: int, seed: int, learn_norm: bool
) -> dict[str, torch.Tensor]:
    """Every decision of ``episodes`` deterministic episodes (seeds ``seed``, ``seed + 1``,
    ...): the raw outputs [B, P] and the robot state y0, dy0 [B, D] the head read."""
    env = policy.make_env()
    ky, kdy = policy.state_keys
    raws, y0s, dy0s = [], [], []
    low, high = np.asarray(policy.spec.action_low), np.asarray(policy.spec.action_high)
    try:
        for ep in range(episodes):
            obs, info = env.reset(seed=seed + ep)
            done = False
            while not done:
                o = torch.from_numpy(
                    policy.obs_norm(np.asarray(obs, dtype=np.float64)[None], update=learn_norm)
                )
                y0 = torch.as_tensor(np.asarray(info[ky]), dtype=torch.float32)[None]
                dy0 = torch.as_tensor(np.asarray(info[kdy]), dtype=torch.float32)[None]
                with torch.no_grad():
                    raw = policy.model.actor(o)
                    dist, _ = policy.model.head.distribution(raw, y0, dy0)
                    act = dist.actions(dist.mode())[0].numpy()
                raws.append(raw[0])
                y0s.append(y0[0])
                dy0s.append(dy0[0])
                obs, _, term, trunc, info = env.step(np.clip(act, low, high))
                done = bool(term or trunc)
    finally:
        env.close()
    return {"raw": torch.stack(raws), "y0": torch.stack(y0s), "dy0": torch.stack(dy0s)}


def _sig(x: float) -> float:
    """``x`` to 6 significant digits (the reports are read by people; inf stays inf)."""
    return float(f"{float(x):.6g}")


def _spread(x: torch.Tensor) -> dict[str, float] | float:
    """Per-decision values [B]: their median, 10th and 90th percentile, min and max (the value
    itself when B = 1)."""
    v = x.double()
    if v.numel() == 1:
        return _sig(v.item())
    q = torch.quantile(v, torch.tensor([0.1, 0.5, 0.9], dtype=torch.float64)).tolist()
    return {
        "median": _sig(q[1]),
        "p10": _sig(q[0]),
        "p90": _sig(q[2]),
        "min": _sig(v.min().item()),
        "max": _sig(v.max().item()),
    }


def _spectrum(s: torch.Tensor) -> list[float]:
    """Per index, the median over decisions of singular values [B, r]."""
    return [_sig(v) for v in s.median(0).values.tolist()]


def conditioning_report(
    head: NDPHead, raw: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor
) -> dict[str, object]:
    """The conditioning of an NDP head's map at B decisions (raw [B, P], y0 / dy0 [B, D]).

    Returns:
        JSON-ready (6 significant digits): ``decisions``; ``rank`` (reachable directions r),
        ``condition`` and ``map_condition`` (J's and ``J_map``'s ``s_1 / s_r``),
        ``singular_values`` and ``map_singular_values`` (the r_min largest; per index, the
        median over decisions), ``goal_share`` / ``weight_share`` of ``|J|_F^2``, and
        ``saturated`` (fractions of the goal, weight and all tanh'd raw outputs whose slope is
        below :data:`ndp.policies.conditioning.SATURATION_SLOPE`; None without tanh). With B >
        1 each per-decision value is a spread (median, p10, p90, min, max) and
        ``singular_values_p10_p90`` gives the band of each index; with B = 1 the values
        themselves, and ``per_dof`` singular values (when A = D: the rows of DoF d, the columns
        of its goal and weights; the whole spectrum when J is block diagonal per DoF).
    """
    d, n = int(head.dmp_dofs), int(head.n_mapped)
    jac, map_jac = head.raw_jacobians(raw, y0, dy0)
    c = conditioning(jac, map_jac, slice(0, d), slice(d, n))
    r_min = int(c.rank.min())
    b = int(raw.shape[0])
    out: dict[str, object] = {
        "decisions": b,
        "rank": r_min
        if b == 1
        else {
            "median": _sig(c.rank.double().median().item()),
            "min": r_min,
            "max": int(c.rank.max()),
        },
        "condition": _spread(c.condition),
        "map_condition": _spread(c.map_condition),
        "singular_values": _spectrum(c.singular_values[:, :r_min]),
        "map_singular_values": _spectrum(c.map_singular_values[:, :r_min]),
        "goal_share": _spread(c.goal_share),
        "weight_share": _spread(c.weight_share) if n > d else None,
        "saturated": None,
    }
    if b > 1:
        out["singular_values_p10_p90"] = [
            [_sig(v) for v in torch.quantile(c.singular_values[:, :r_min], q, dim=0).tolist()]
            for q in (0.1, 0.9)
        ]
    if head.param_map == "tanh":
        pre = raw.detach().double()
        out["saturated"] = {
            "all": _spread(saturated_fraction(pre[:, :n])),
            "goal": _spread(saturated_fraction(pre[:, :d])),
            "weights": _spread(saturated_fraction(pre[:, d:n])) if n > d else None,
        }
    if b == 1 and head.action_dim == d:
        k, nb = int(head.k), int(head.n_basis) if n > d else 0
        per_dof = []
        for dof in range(d):
            rows = [j * d + dof for j in range(k)]
            cols = [dof] + [d + dof * nb + i for i in range(nb)]
            per_dof.append([_sig(v) for v in torch.linalg.svdvals(jac[0][rows][:, cols]).tolist()])
        out["per_dof"] = per_dof
    return out


def jacobian_diagnostic(
    task: str | None = None,
    algo: str = "ndp",
    run: str | None = None,
    episodes: int = JACOBIAN_EPISODES,
    seed: int = 0,
    **overrides: object,
) -> dict[str, object]:
    """The conditioning of an NDP policy's action map (see the module docstring).

    Args:
        task: a task (a fresh policy: ``raw0`` and ``init``), or None with ``run``.
        algo: the method of a fresh policy (one with the NDP head).
        run: a run directory, export or ``"zoo:NAME"`` (adds ``trained``; ``init`` is the
            network a run of its config starts from).
        episodes: deterministic episodes of each rollout (every decision is read).
        seed: the first episode seed.
        overrides: policy-config fields of a fresh policy (``param_map="whitened"``).

    Returns:
        JSON-ready dict: the source, task, k, ``param_map``, P, M = k A, the rank rule, and a
        :func:`conditioning_report` for ``raw0``, ``init`` and (a run) ``trained``.
    """
    check_int("episodes", episodes, 1)
    trained: Policy | None = None
    if run is not None:
        if overrides:
            raise ValueError(f"overrides: a trained run's config is its own, got {overrides}")
        trained = load_policy(run)
        fresh = _fresh_of(trained.cfg, trained.spec)
    elif task is None:
        raise ValueError("task: give a task (fresh policy) or a run (trained)")
    else:
        fresh = _fresh(task, algo, overrides)
    head = fresh.model.head
    if not hasattr(head, "raw_jacobians"):
        raise ValueError(
            f"algo: the conditioning diagnostic reads the NDP head, got {fresh.cfg.algo!r} "
            f"({type(head).__name__})"
        )
    torch.set_num_threads(1)
    d = int(head.dmp_dofs)
    zero = torch.zeros(1, int(head.n_params))
    out: dict[str, object] = {
        "source": str(run) if run is not None else f"{task} (fresh)",
        "task": fresh.cfg.task,
        "algo": fresh.cfg.algo,
        "k": int(head.k),
        "param_map": head.param_map,
        "P": int(head.n_params),
        "M": int(head.k) * int(head.action_dim),
        "goal_columns": d,
        "weight_columns": int(head.n_mapped) - d,
        "rank_rule": RANK_RULE,
        "saturation_slope": SATURATION_SLOPE,
        "episodes": episodes,
        "seed": seed,
        "raw0": conditioning_report(head, zero, torch.zeros(1, d), torch.zeros(1, d)),
    }
    at_init = _decisions(fresh, episodes, seed, learn_norm=True)
    out["init"] = conditioning_report(head, at_init["raw"], at_init["y0"], at_init["dy0"])
    if trained is not None:
        got = _decisions(trained, episodes, seed, learn_norm=False)
        out["trained"] = conditioning_report(trained.model.head, got["raw"], got["y0"], got["dy0"])
    return out


def plot_spectra(reports: Sequence[Mapping[str, Any]], path: str | Path) -> Path:
    """A figure of the singular-value spectra of :func:`jacobian_diagnostic` reports, one panel
    per report (policy): at raw = 0, at the fresh network's outputs and at the trained
    policy's (per index, the median over decisions and the 10-90 % band), on a log scale;
    the legend gives each one's median condition number. Written as PNG to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    out = Path(path)
    check_output_path(out, "png")
    fig, axes = plt.subplots(1, len(reports), figsize=(4.2 * len(reports), 3.6), squeeze=False)
    for ax, rep in zip(axes[0], reports, strict=True):
        title = [f"{rep['source']}", f"param_map {rep['param_map']}, k={rep['k']}, P={rep['P']}"]
        for key, style in (("raw0", "o-"), ("init", "s--"), ("trained", "^-")):
            if key not in rep:
                continue
            sv = rep[key]["singular_values"]
            cond = rep[key]["condition"]
            cond = cond["median"] if isinstance(cond, dict) else cond
            label = {"raw0": "raw = 0", "init": "at init", "trained": "trained"}[key]
            x = np.arange(1, len(sv) + 1)
            line = ax.semilogy(x, sv, style, ms=4, label=f"{label}: cond {cond:.3g}")
            if "singular_values_p10_p90" in rep[key]:
                lo, hi = rep[key]["singular_values_p10_p90"]
                ax.fill_between(x, lo, hi, color=line[0].get_color(), alpha=0.2)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("index (reachable directions)")
        ax.set_ylabel("singular value of d means / d raw")
        ax.set_title("\n".join(title), fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    atomic_savefig(fig, out, dpi=110)
    plt.close(fig)
    return out
