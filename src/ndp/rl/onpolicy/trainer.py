"""One on-policy trainer (PPO with GAE over sub-steps) for PPO, PPO-multi and NDP.

Data flow of one update (shapes: E envs, T decisions per env, k sub-steps, A action size,
D DMP DoF, O observation size)::

    obs [E, O] --normalise--> actor-critic --> distribution over [E, k, A], values [E, k]
    sample z --> sub-actions [E, k, A] --clip to the task's bounds--> ChunkedEnv x E
    --> sub-step rewards [E, k], masks [E, k], ends [E], robot state y0, dy0 [E, D] (physical)
    x T decisions --> GAE over the sub-step sequence --> PPO epochs over mini-batches of decisions

Truncation (time limit, unstable simulator) is bootstrapped with the value of the final
observation; termination is not. Every action reaching the simulator is clipped to the spec's
bounds. A non-finite loss, gradient or parameter stops training with
:class:`TrainingDivergedError`; the last good checkpoint is kept untouched.
"""

from __future__ import annotations

import copy
import itertools
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch

from ndp.envs.base import CTRL_INFO
from ndp.envs.vector import OverlapVectorEnv, concat_steps
from ndp.policies import build_actor_critic
from ndp.policies.distributions import (
    AR1SubActionGaussian,
    PolicyDistribution,
    SubActionGaussian,
    correlate,
)
from ndp.rl.config import TrainConfig
from ndp.rl.envs import (
    EpisodeTracker,
    decision_rewards,
    decision_start,
    env_seeds,
    resolve_task,
    run_envs,
    step_info,
)
from ndp.rl.logger import METRICS
from ndp.rl.normalize import ObsNormalizer, ReturnNormalizer
from ndp.rl.onpolicy.gae import bootstrap_truncated, gae_substeps
from ndp.rl.onpolicy.losses import (
    entropy_mean,
    gaussian_policy_loss,
    normalize_advantages,
    policy_loss,
    release_first_held,
    value_loss,
)
from ndp.rl.optim import FlatAdam
from ndp.rl.periodic_eval import PeriodicEvaluator
from ndp.rl.progress import episode_charts
from ndp.runs.checkpoint import (
    OptimizerState,
    Spec,
    check_state,
    policy_schema,
    running_stats,
)
from ndp.runs.session import (
    CountsUpdates,
    RunSession,
    TrainingDivergedError,
    nonfinite_parameter,
)

__all__ = ["Trainer", "TrainingDivergedError", "ppo_state"]


class Decision(NamedTuple):
    """One rollout decision of :meth:`Trainer.decide` for E envs."""

    dist: PolicyDistribution
    """The exploration distribution (a :mod:`ndp.policies.distributions` one)."""
    aux: dict[str, torch.Tensor]
    """The head's diagnostics (NDP: ``goal_norm``, ``weight_norm`` [E])."""
    z: torch.Tensor
    """The sample the update scores (sub-actions [E, k, A] or DMP parameters [E, P])."""
    logp: torch.Tensor
    """Its log-probability [E, 1] (per decision) or [E, k] (per sub-action)."""
    values: torch.Tensor
    """The critic's values [E, k]."""
    act: torch.Tensor
    """The k actions [E, k, A], inside the action bounds."""


class Trainer(CountsUpdates):
    """PPO over chunked decisions; the method is only the actor-critic's action head.

    A :class:`ndp.rl.run.RLLearner`: the run driver (:mod:`ndp.runs.driver`, through
    :class:`ndp.rl.run.RLRecipe`) opens the run, seeds, builds it, restores its state, drives
    :meth:`iterate` and writes the checkpoints.

    Args:
        cfg: the run's config, resolved (:func:`ndp.rl.config.resolve_config`).
        session: the run's session (paths, the divergence message).
    """

    def __init__(self, cfg: TrainConfig, session: RunSession) -> None:
        # the row the method runs (VICES: the torque variant) with the run's task options
        task = resolve_task(cfg.task, **cfg.env_options())
        self.cfg = cfg
        self.spec = task.spec
        self.run_dir = Path(cfg.run_dir or ".")
        self.session = session
        self.run = session.run
        self.ckpt_path = self.run.checkpoint

        self.k = cfg.k
        self.num_envs = cfg.num_envs
        self.T = cfg.decisions_per_env
        self.envs, obs_dim = run_envs(cfg, task)
        self.obs_dim = obs_dim
        self.device = torch.device(cfg.device)
        model = build_actor_critic(obs_dim, self.spec, cfg.policy)
        # The rollout acts on the CPU (one small batch per decision, beside the simulators);
        # the update runs on ``device``. Off the CPU the rollout uses a CPU copy, refreshed after
        # every update.
        self.rollout_model = model if self.device.type == "cpu" else copy.deepcopy(model)
        self.model = model.to(self.device)
        p = cfg.ppo
        # one flat buffer: one clip and one fused Adam step per mini-batch (ndp.rl.optim)
        self.opt = FlatAdam(self.model, lr=p.lr, eps=p.adam_eps)
        self.obs_norm = ObsNormalizer(obs_dim, cfg.clip_obs, cfg.norm_obs)
        self.ret_norm = ReturnNormalizer(cfg.num_envs, cfg.gamma, p.clip_reward, p.norm_return)
        self.low = torch.as_tensor(self.spec.action_low, dtype=torch.float32)
        self.high = torch.as_tensor(self.spec.action_high, dtype=torch.float32)
        # low <= high: one clamp is the minimum-then-maximum clip, bit for bit (decide)
        self._one_clamp = bool((self.low <= self.high).all())
        self.update = 0
        self.global_step = 0
        self.evaluator = PeriodicEvaluator(cfg, self.spec)
        # Episode bookkeeping.
        self._episodes = EpisodeTracker(cfg.num_envs)
        frame = cfg.policy.dmp_state
        assert frame is not None  # resolve_config fills it from the task's preset
        self._dmp_frame: str = frame
        # AR(1) exploration: each env's last unit noise, the next decision's carry (None: white)
        self._rho = float(cfg.policy.noise_corr) if cfg.policy.noise == "ar1" else None
        self._carry: torch.Tensor | None = None
        self._started = False  # the envs are reset at the first update, after any restore
        # two env groups in alternation (vector='overlap'; any other vector env: both at once)
        self._overlap = isinstance(self.envs, OverlapVectorEnv)
        self._release_ratio = cfg.first_held_ratio == "release"
        if self._release_ratio:
            self._check_release_ratio(obs_dim)

    def _start(self) -> None:
        """Reset the envs (one seed per env, from the update the run continues at) and draw
        the AR(1) carry: at the first update, so that a restored run starts where it stopped."""
        cfg = self.cfg
        # gymnasium types VectorEnv.reset's seed as one int; its vector envs and
        # ndp.envs.vector take a list
        seeds = env_seeds(cfg.seed, cfg.num_envs, epoch=self.update)
        obs, info = self.envs.reset(seed=seeds)  # type: ignore[arg-type]
        self._obs = np.asarray(obs, dtype=np.float64).reshape(cfg.num_envs, self.obs_dim)
        self._y0, self._dy0 = decision_start(info, cfg.num_envs, self._dmp_frame)
        if self._rho is not None:
            self._carry = torch.randn(cfg.num_envs, self.spec.action_dim)
        self._started = True

    def _check_release_ratio(self, obs_dim: int) -> None:
        """Refuse ``first_held_ratio='release'`` for a distribution with one log-prob per
        decision (parameter noise, the hold head): it has no sub-step distributions to pair."""
        D = self.spec.dmp_dofs
        with torch.no_grad():
            dist, _ = self.rollout_model.distribution(
                torch.zeros(1, obs_dim), torch.zeros(1, D), torch.zeros(1, D)
            )
        if dist.per_decision:
            raise ValueError(
                "first_held_ratio: 'release' pairs sub-step distributions and needs one "
                "log-prob per sub-action; this policy draws one per decision (parameter noise "
                "or the hold head): use first_held_ratio='own'"
            )

    def _explore(self, dist: PolicyDistribution, carry: torch.Tensor | None) -> PolicyDistribution:
        """The exploration distribution the run samples from: ``dist`` itself (white noise) or
        with AR(1) noise continued from ``carry`` [B, A] (``--noise ar1``)."""
        if self._rho is None:
            return dist
        assert carry is not None
        return correlate(dist, carry, self._rho)

    def decide(
        self,
        obs_n: torch.Tensor,
        y0: torch.Tensor,
        dy0: torch.Tensor,
        noise: Callable[[torch.Tensor], torch.Tensor] | None = None,
    ) -> Decision:
        """One rollout decision for E envs (no gradient): the exploration distribution
        (continuing the AR(1) carry, if any), a sample ``z``, its log-prob, the values [E, k] and
        the k actions [E, k, A] inside the action bounds. ``obs_n`` [E, O] is the normalised
        observation, ``y0`` / ``dy0`` [E, D] the robot state the decision starts from;
        ``noise``: given the distribution's mode, the standard normal draw to sample with
        (None: the distribution draws it).

        Raises:
            TrainingDivergedError: a non-finite DMP input or action.
        """
        with torch.no_grad():
            try:
                dist, aux = self.rollout_model.distribution(obs_n, y0, dy0)
            except FloatingPointError as exc:
                msg = f"non-finite DMP input during the rollout ({exc})"
                raise self._diverged(msg) from None
            dist = self._explore(dist, self._carry)
            z = dist.sample() if noise is None else dist.sample(noise=noise(dist.mode()))
            logp = dist.log_prob(z)
            values = self.rollout_model.value(obs_n)
            act = dist.actions(z)
            if self._one_clamp:
                act = torch.clamp(act, self.low, self.high)
            else:
                act = torch.maximum(torch.minimum(act, self.high), self.low)
        # a finite sum: every action is finite (one reduction; the exact test only otherwise)
        if not math.isfinite(float(act.sum())) and not bool(torch.isfinite(act).all()):
            raise self._diverged("non-finite actions (check the observations)")
        if self._release_ratio:  # store the executed a_0 at every sub-step (the release's)
            z, logp = release_first_held(z, logp)
        return Decision(dist, aux, z, logp, values, act)

    def decision_start(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The robot state [E, D] (positions, velocities) the next decision starts from
        (resetting the envs first if the run has not started)."""
        if not self._started:
            self._start()
        as_t = torch.as_tensor
        return as_t(self._y0, dtype=torch.float32), as_t(self._dy0, dtype=torch.float32)

    # ----------------------------------------------------------------------- state
    def state_dict(self) -> dict[str, Any]:
        """Everything needed to continue: model, optimiser, normalisers, counters (the session
        adds the global RNG state and the config)."""
        return ppo_state(
            self.model,
            self.opt,
            self.obs_norm,
            self.ret_norm,
            self.update,
            self.global_step,
            self.obs_dim,
        )

    def checkpoint_schema(self) -> dict[str, Spec]:
        """What a checkpoint must hold (:func:`ppo_state`'s keys), shaped like the model now;
        the optimiser's moments may be per parameter (older checkpoints, :class:`FlatAdam`)."""
        return {
            **policy_schema(self.model.state_dict(), self.obs_dim),
            "optimizer": OptimizerState(),
            "ret_norm": running_stats(()),
        }

    def load_state_dict(self, ckpt: dict[str, Any]) -> None:
        """Continue from a checkpoint (the session restores the global RNG state).

        Raises:
            ValueError: the checkpoint does not match :meth:`checkpoint_schema` (one line
                naming the file and the key).
        """
        check_state(ckpt, self.checkpoint_schema(), self.ckpt_path)
        self.model.load_state_dict(ckpt["model"])
        self._sync_rollout_model()
        self.opt.load_state_dict(ckpt["optimizer"])
        self.obs_norm.load_state_dict(ckpt["obs_norm"])
        self.ret_norm.load_state_dict(ckpt["ret_norm"])
        self.update = int(ckpt["update"])
        self.global_step = int(ckpt["global_step"])

    def _sync_rollout_model(self) -> None:
        if self.rollout_model is not self.model:
            self.rollout_model.load_state_dict(self.model.state_dict())

    @property
    def columns(self) -> tuple[str, ...]:
        """``metrics.csv``'s columns (docs/metrics.md)."""
        return METRICS

    def nonfinite(self) -> str | None:
        """The first parameter holding NaN / Inf, else None (the driver checks it before every
        checkpoint)."""
        return nonfinite_parameter(self.model.named_parameters())

    def _diverged(self, what: str) -> TrainingDivergedError:
        return self.session.diverged(what, self.update)

    def _check_params(self, when: str) -> None:
        name = self.nonfinite()
        if name is not None:
            raise self._diverged(f"parameter {name} holds NaN/Inf {when}")

    # ----------------------------------------------------------------------- rollout
    def collect(self) -> dict[str, Any]:
        """Run T decisions in every env; returns the rollout (tensors / arrays) and stats.

        With ``vector='overlap'`` the decisions of the two env groups alternate with their
        steps (:meth:`_collect_overlap`)."""
        if not self._started:
            self._start()
        buf = _Rollout(self.T, self.num_envs, self.k, self.obs_dim, self._y0.shape[1])
        if self._overlap:
            self._collect_overlap(buf)
        else:
            for t in range(self.T):
                obs_n = torch.from_numpy(self.obs_norm(self._obs, update=True))
                y0 = torch.as_tensor(self._y0, dtype=torch.float32)
                dy0 = torch.as_tensor(self._dy0, dtype=torch.float32)
                carry = self._carry
                d = self.decide(obs_n, y0, dy0)
                buf.record(t, slice(None), obs_n, y0, dy0, carry, d)
                step = self.envs.step(d.act.numpy())
                buf.add_step(t, *self._after_step(step, buf, self.obs_norm, d.dist, d.z))
        return self._finish(buf)

    def _collect_overlap(self, buf: _Rollout) -> None:
        """T decisions in every env, the two env groups of the ``OverlapVectorEnv`` in
        alternation: group B's decision t is computed while group A steps t, group A's decision
        t + 1 while group B steps t.

        Same rollout as the serial loop of :meth:`collect` except through the observation
        normaliser: each decision's noise is the serial draw for all E envs (drawn at group A's
        decision, group B's rows kept); each group's call is on E rows (its own, and the other
        group's current ones as filler, discarded), so that its rows are the serial call's bit
        for bit (a float32 matrix product of E/2 rows rounds differently); the step's
        bookkeeping runs over all E envs in the serial order, its truncation bootstrap with the
        statistics after decision t. The normaliser is updated with each group's observations
        at that group's decision: group A's decision t + 1 is normalised before group B's
        observations of t + 1 are merged, and every merge is of E/2 rows (equal to one E-row
        merge up to rounding). With ``norm_obs=False`` the rollout is the serial one."""
        envs = self.envs
        assert isinstance(envs, OverlapVectorEnv)  # run_envs with vector='overlap'
        E, T, O = self.num_envs, self.T, self.obs_dim
        (ga, gb), h = envs.groups, envs.bounds[0][1]
        eps: list[torch.Tensor] = []  # the decision's noise for all E envs

        def draw_all(mode: torch.Tensor) -> torch.Tensor:  # the serial loop's draw
            eps[:] = [torch.randn(mode.shape, dtype=mode.dtype, device=mode.device)]
            return eps[0]

        def draw_kept(mode: torch.Tensor) -> torch.Tensor:
            return eps[0]

        def decide(
            t: int, rows: slice, other: slice, obs: np.ndarray, y0_np: np.ndarray,
            dy0_np: np.ndarray, draw: Callable[[torch.Tensor], torch.Tensor],
        ) -> np.ndarray:  # fmt: skip
            obs_n = np.empty((E, O), dtype=np.float32)
            obs_n[rows] = self.obs_norm(obs, update=True)
            obs_n[other] = self.obs_norm(self._obs[other])
            y0_full, dy0_full = self._y0.copy(), self._dy0.copy()
            y0_full[rows], dy0_full[rows] = y0_np, dy0_np
            obs_t = torch.from_numpy(obs_n)
            y0 = torch.as_tensor(y0_full, dtype=torch.float32)
            dy0 = torch.as_tensor(dy0_full, dtype=torch.float32)
            d = self.decide(obs_t, y0, dy0, noise=draw)
            buf.record(t, rows, obs_t, y0, dy0, None, d)
            return d.act[rows].numpy()

        a_rows, b_rows = slice(0, h), slice(h, E)
        act = decide(0, a_rows, b_rows, self._obs[a_rows], self._y0[a_rows], self._dy0[a_rows],
                     draw_all)  # fmt: skip
        ga.step_async(act)
        for t in range(T):
            act = decide(t, b_rows, a_rows, self._obs[b_rows], self._y0[b_rows],
                         self._dy0[b_rows], draw_kept)  # fmt: skip
            gb.step_async(act)
            step_a = ga.step_wait()
            norm_t = self._norm_snapshot()  # the statistics after decision t (all E envs)
            if t + 1 < T:
                y0_a, dy0_a = decision_start(step_a[4], h, self._dmp_frame)
                obs_a = np.asarray(step_a[0], dtype=np.float64).reshape(h, O)
                act = decide(t + 1, a_rows, b_rows, obs_a, y0_a, dy0_a, draw_all)
                ga.step_async(act)
            step = concat_steps([step_a, gb.step_wait()])
            buf.add_step(t, *self._after_step(step, buf, norm_t, None, None))

    def _norm_snapshot(self) -> ObsNormalizer:
        """The observation normaliser as it is now (later updates leave it unchanged: they
        rebind the statistics' arrays)."""
        snap = copy.copy(self.obs_norm)
        snap.rms = copy.copy(self.obs_norm.rms)
        return snap

    def _finish(self, buf: _Rollout) -> dict[str, Any]:
        """The rollout's batch: GAE over the T decisions (bootstrapped from the last
        observations' values) and the flattened buffers."""
        E, T, k, D = self.num_envs, self.T, self.k, buf.y0.shape[2]
        with torch.no_grad():
            last_obs = torch.from_numpy(self.obs_norm(self._obs))
            last_v = self.rollout_model.value(last_obs)[:, 0].numpy()
        adv, ret = gae_substeps(
            buf.rew, buf.val, buf.mask, buf.end, last_v, self.cfg.gamma, self.cfg.ppo.gae_lambda
        )
        z_b, logp_b, carry_b = buf.z, buf.logp, buf.carry
        assert z_b is not None and logp_b is not None
        n = T * E
        return {
            "obs": buf.obs.reshape(n, self.obs_dim),
            "y0": buf.y0.reshape(n, D),
            "dy0": buf.dy0.reshape(n, D),
            "z": z_b.reshape(n, *z_b.shape[2:]),
            "logp": logp_b.reshape(n, -1),
            "values": torch.as_tensor(buf.val.reshape(n, k), dtype=torch.float32),
            "adv": torch.as_tensor(adv.reshape(n, k), dtype=torch.float32),
            "returns": torch.as_tensor(ret.reshape(n, k), dtype=torch.float32),
            "mask": torch.as_tensor(buf.mask.reshape(n, k), dtype=torch.float32),
            "episodes": buf.episodes,
            "executed": buf.executed,
            "goal_norm": mean_of_means(buf.norm_rows("goal_norm")),
            "weight_norm": mean_of_means(buf.norm_rows("weight_norm")),
            "ctrl": buf.ctrl,
            "per_decision": buf.per_decision,
            "carry": None if carry_b is None else carry_b.reshape(n, -1),
        }

    def _after_step(
        self,
        step: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]],
        buf: _Rollout,
        obs_norm: ObsNormalizer,
        dist: PolicyDistribution | None,
        z: torch.Tensor | None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Book one decision's vector step over every env: returns the normalised sub-step
        rewards (truncated episodes bootstrapped from their final observation, normalised by
        ``obs_norm``), the executed-step mask [E, k] and the episode ends [E]; adds the
        controller counters and finished episodes to ``buf``, continues the AR(1) carry (from
        ``dist`` and ``z``) and moves the envs' observation and robot state on."""
        E, k = self.num_envs, self.k
        next_obs, _, term, trunc, infos = step
        term = np.asarray(term, dtype=bool)
        trunc = np.asarray(trunc, dtype=bool)
        done = term | trunc
        sub_r, live, mask = decision_rewards(infos, done, E, k)
        r_n = self.ret_norm(sub_r, mask, done)
        boot = trunc & ~term
        if boot.any():  # bootstrap truncated episodes from their final observation
            fin = np.stack([np.asarray(o, dtype=np.float64) for o in infos["final_obs"][boot]])
            fin_n = torch.from_numpy(obs_norm(fin.reshape(-1, self.obs_dim)))
            with torch.no_grad():
                v_fin = self.rollout_model.value(fin_n)[:, 0].numpy()
            r_n = bootstrap_truncated(r_n, mask, boot, v_fin, self.cfg.gamma)
        for key in CTRL_INFO:
            if key in infos or "final_info" in infos:
                buf.ctrl[key] += float(step_info(infos, done, key).sum())

        self._episodes.add(infos, done, sub_r, live, mask, buf.episodes)
        if self._carry is not None:  # continue the noise; a new episode starts afresh
            assert isinstance(dist, AR1SubActionGaussian) and z is not None  # with a carry
            self._carry = dist.last_noise(z)
            if done.any():
                fresh = torch.from_numpy(done)
                self._carry[fresh] = torch.randn(int(done.sum()), self._carry.shape[1])
        self._obs = np.asarray(next_obs, dtype=np.float64).reshape(E, self.obs_dim)
        self._y0, self._dy0 = decision_start(infos, E, self._dmp_frame)
        return r_n, mask, done

    # ----------------------------------------------------------------------- update
    def learn(self, batch: dict[str, Any]) -> dict[str, float]:
        """PPO epochs over mini-batches of decisions; returns mean loss statistics."""
        p = self.cfg.ppo
        if p.anneal_lr:
            frac = 1.0 - self.update / self.cfg.num_updates
            for g in self.opt.param_groups:
                g["lr"] = p.lr * frac
        if self.device.type != "cpu":
            batch = {
                key: val.to(self.device) if isinstance(val, torch.Tensor) else val
                for key, val in batch.items()
            }
        mask = batch["mask"]
        adv = batch["adv"]
        # the distribution says whether it draws one log-prob per decision (ParamGaussian: NDP
        # with parameter noise, VICES' hold head) or one per sub-action
        if batch["per_decision"]:
            # one log-prob per decision: its advantage is the decision's own GAE advantage
            # A[t, 0] (every reward of the decision, (gamma lambda)^l weighted), one term each
            adv, mask = adv[:, :1], mask[:, :1]
        per_mb_norm = p.norm_adv and p.adv_norm_scope == "minibatch"
        if p.norm_adv and not per_mb_norm:
            adv = normalize_advantages(adv, mask)
        n = mask.shape[0]
        n_mb = min(p.minibatches, n)
        stats: dict[str, list[torch.Tensor]] = {
            k: [] for k in ("policy", "value", "entropy", "approx_kl", "clipfrac", "grad_norm")
        }
        vclip = p.clip if p.clip_value_loss else None
        keys: tuple[str, ...] = ("obs", "y0", "dy0", "z", "logp", "values", "returns")
        if batch.get("carry") is not None:
            keys += ("carry",)
        vmask_all = batch["mask"]
        for _ in range(p.epochs):
            perm = torch.randperm(n, device=mask.device)
            # one gather per epoch; mini-batches are then contiguous slices (views)
            shuf = {key: batch[key][perm] for key in keys}
            shuf["adv"], shuf["mask"], shuf["vmask"] = adv[perm], mask[perm], vmask_all[perm]
            bounds = [int(b) for b in np.linspace(0, n, n_mb + 1)]
            for lo, hi in itertools.pairwise(bounds):
                mb = {key: val[lo:hi] for key, val in shuf.items()}
                for key, val in self._minibatch_step(mb, per_mb_norm, vclip).items():
                    stats[key].append(val)
        self._check_params("after the update")
        self._sync_rollout_model()
        out = {k: float(torch.stack(v).mean()) for k, v in stats.items()}
        out["explained_variance"] = explained_variance(batch["returns"], batch["values"], vmask_all)
        return out

    def _minibatch_step(
        self, mb: dict[str, torch.Tensor], per_mb_norm: bool, vclip: float | None
    ) -> dict[str, torch.Tensor]:
        """One PPO gradient step on the mini-batch ``mb`` (advantages normalised over it when
        ``per_mb_norm``; ``vclip`` the value clip, None for none); returns its statistics
        (detached): policy, value and entropy losses, approximate KL, clip fraction, gradient
        norm.

        Raises:
            TrainingDivergedError: a non-finite DMP input, loss or gradient.
        """
        p = self.cfg.ppo
        try:
            dist, _ = self.model.distribution(mb["obs"], mb["y0"], mb["dy0"])
        except FloatingPointError as exc:
            raise self._diverged(f"non-finite DMP input in the update ({exc})") from None
        dist = self._explore(dist, mb.get("carry"))
        m, vm = mb["mask"], mb["vmask"]
        mb_adv = normalize_advantages(mb["adv"], m) if per_mb_norm else mb["adv"]
        if isinstance(dist, SubActionGaussian):  # fused surrogate: one autograd node
            pg, kl, cf = gaussian_policy_loss(
                dist.mean, dist.log_std, mb["z"], mb["logp"], mb_adv, m, p.clip
            )
        else:
            pg, kl, cf = policy_loss(dist.log_prob(mb["z"]), mb["logp"], mb_adv, m, p.clip)
        v = self.model.value(mb["obs"])
        vl = value_loss(v, mb["values"], mb["returns"], vm, vclip)
        if p.ent_coef > 0:
            ent = entropy_mean(dist.entropy(), vm)
            loss = pg + p.vf_coef * vl - p.ent_coef * ent
        else:
            with torch.no_grad():
                ent = entropy_mean(dist.entropy(), vm)
            loss = pg + p.vf_coef * vl
        self.opt.zero_grad()
        loss.backward()  # type: ignore[no-untyped-call]  # torch: Tensor.backward is unannotated
        gn = self.opt.clip_grad_norm(p.max_grad_norm)
        if not bool(torch.isfinite(loss.detach() + gn)):  # one check for both
            raise self._diverged(
                f"non-finite loss or gradient (policy {float(pg.detach())}, value "
                f"{float(vl.detach())}, gradient norm {float(gn)})"
            )
        self.opt.step()
        stats = {"policy": pg, "value": vl, "entropy": ent, "approx_kl": kl, "clipfrac": cf,
                 "grad_norm": gn}  # fmt: skip
        return {key: val.detach() for key, val in stats.items()}

    # ----------------------------------------------------------------------- loop
    def iterate(self) -> dict[str, float]:
        """One update: collect T decisions per env, then the PPO epochs; returns its metrics row.

        Raises:
            TrainingDivergedError: NaN / Inf in a loss, gradient or parameter.
        """
        t0 = time.perf_counter()
        batch = self.collect()
        t1 = time.perf_counter()
        stats = self.learn(batch)
        t2 = time.perf_counter()
        self.update += 1
        before, self.global_step = self.global_step, self.global_step + batch["executed"]
        last = self.update >= self.cfg.num_updates
        evaluation = self.evaluator.maybe(
            before, self.global_step, last, self.rollout_model, self.obs_norm
        )
        with torch.no_grad():
            std = float(self.model.head.log_std.exp().mean())
        return {
            "update": self.update,
            "global_step": self.global_step,
            **episode_charts(batch["episodes"]),
            "charts/env_steps_per_s": batch["executed"] / max(t2 - t0, 1e-9),
            "charts/learning_rate": float(self.opt.param_groups[0]["lr"]),
            "losses/policy": stats["policy"],
            "losses/value": stats["value"],
            "losses/entropy": stats["entropy"],
            "losses/approx_kl": stats["approx_kl"],
            "losses/clipfrac": stats["clipfrac"],
            "losses/grad_norm": stats["grad_norm"],
            "losses/explained_variance": stats["explained_variance"],
            "policy/std": std,
            "dmp/goal_norm": batch["goal_norm"],
            "dmp/weight_norm": batch["weight_norm"],
            **self._ctrl_metrics(batch),
            "time/rollout_s": t1 - t0,
            "time/update_s": t2 - t1,
            **evaluation,
        }

    def _ctrl_metrics(self, batch: dict[str, Any]) -> dict[str, float]:
        """Controller counters of the torque-actuated tasks (NaN for the others): gain entries
        clipped and non-finite torques over the update, saturated torque entries per env
        step."""
        if self.spec.actuation != "torque":
            return dict.fromkeys(
                ("ctrl/gains_clipped", "ctrl/torque_saturated", "ctrl/nonfinite"), math.nan
            )
        c = batch["ctrl"]
        return {
            "ctrl/gains_clipped": c["ctrl_gains_clipped"],
            "ctrl/torque_saturated": c["ctrl_torque_saturated"] / max(batch["executed"], 1),
            "ctrl/nonfinite": c["ctrl_nonfinite"],
        }

    def close(self) -> None:
        """Close the environments (training and evaluation) and release the run."""
        self.envs.close()
        self.evaluator.close()
        self.session.close()


class _Rollout:
    """One rollout's buffers, filled decision by decision (rows: all envs, or one group's)."""

    def __init__(self, T: int, E: int, k: int, obs_dim: int, D: int) -> None:
        self.T, self.E = T, E
        self.obs = torch.zeros(T, E, obs_dim)
        self.y0 = torch.zeros(T, E, D)
        self.dy0 = torch.zeros(T, E, D)
        self.z: torch.Tensor | None = None  # sized at the first decision
        self.logp: torch.Tensor | None = None
        self.carry: torch.Tensor | None = None
        self.val = np.zeros((T, E, k))
        self.rew = np.zeros((T, E, k))
        self.mask = np.zeros((T, E, k))
        self.end = np.zeros((T, E))
        self.aux: dict[str, torch.Tensor] = {}  # the head's diagnostics [T, E]
        self.episodes: list[tuple[float, float, float, float, float]] = []
        self.ctrl = dict.fromkeys(CTRL_INFO, 0.0)
        self.executed = 0
        self.per_decision = False

    def record(
        self,
        t: int,
        rows: slice,
        obs_n: torch.Tensor,
        y0: torch.Tensor,
        dy0: torch.Tensor,
        carry: torch.Tensor | None,
        d: Decision,
    ) -> None:
        """Store decision ``t``'s inputs and :class:`Decision` (all E envs' rows) for the envs
        ``rows``."""
        T, E = self.T, self.E
        self.per_decision = bool(d.dist.per_decision)
        if self.z is None or self.logp is None:  # (both None until the first decision)
            self.z = torch.zeros((T, E, *d.z.shape[1:]))
            self.logp = torch.zeros((T, E, d.logp.shape[1]))
        self.obs[t, rows], self.y0[t, rows], self.dy0[t, rows] = obs_n[rows], y0[rows], dy0[rows]
        self.z[t, rows], self.logp[t, rows] = d.z[rows], d.logp[rows]
        if carry is not None:
            if self.carry is None:
                self.carry = torch.zeros(T, E, carry.shape[1])
            self.carry[t, rows] = carry[rows]
        self.val[t, rows] = d.values[rows].numpy()
        for key in ("goal_norm", "weight_norm"):
            if key in d.aux:
                if key not in self.aux:
                    self.aux[key] = torch.zeros(T, E, dtype=d.aux[key].dtype)
                self.aux[key][t, rows] = d.aux[key][rows]

    def add_step(self, t: int, r_n: np.ndarray, mask: np.ndarray, done: np.ndarray) -> None:
        """Store decision ``t``'s step over every env: rewards, mask, ends."""
        self.rew[t], self.mask[t], self.end[t] = r_n, mask, done
        self.executed += int(mask.sum())

    def norm_rows(self, key: str) -> list[torch.Tensor]:
        """The head's diagnostic ``key`` per decision ([E] rows; none without it)."""
        return list(self.aux[key]) if key in self.aux else []


def mean_of_means(rows: list[torch.Tensor]) -> float:
    """The mean over decisions of each decision's mean diagnostic (rows [E] each; NaN for
    none): one row-wise mean of the stacked rows, the same float32 means as one per row."""
    if not rows:
        return math.nan
    return float(np.mean(torch.stack(rows).mean(dim=1).double().numpy()))


def explained_variance(returns: torch.Tensor, values: torch.Tensor, mask: torch.Tensor) -> float:
    """``1 - Var(returns - values) / Var(returns)`` over the executed sub-steps (``mask`` > 0);
    NaN where the returns do not vary."""
    valid = mask > 0
    y, yhat = returns[valid], values[valid]
    var_y = float(y.var()) if y.numel() > 1 else 0.0
    return math.nan if var_y == 0 else 1.0 - float((y - yhat).var()) / var_y


def ppo_state(
    model: torch.nn.Module,
    opt: FlatAdam,
    obs_norm: ObsNormalizer,
    ret_norm: ReturnNormalizer,
    update: int,
    global_step: int,
    obs_dim: int,
) -> dict[str, Any]:
    """The PPO checkpoint's learner state (the run session adds ``rng`` and ``config``): the one
    layout :class:`Trainer` writes and reads, and behaviour cloning writes for a cloned policy
    that ``ndp rl train --resume`` fine-tunes."""
    return {
        "model": model.state_dict(),
        "optimizer": opt.state_dict(),
        "obs_norm": obs_norm.state_dict(),
        "ret_norm": ret_norm.state_dict(),
        "update": int(update),
        "global_step": int(global_step),
        "obs_dim": int(obs_dim),
    }
