"""SAC, chunked SAC and NDP-SAC: one learner (an :class:`ndp.rl.run.RLLearner`).

Data flow of one iteration (E envs, T decisions per env, k sub-steps, A actions, D DMP DoF,
P bounded parameters per decision, C the critic's action input)::

    obs [E, O], robot state y0, dy0 [E, D] --actor--> squashed Gaussian over u [E, P]
    u (random in the bounded space for the first random_steps) --head decode--> [E, k, A]
    --ChunkedEnv x E--> sub-rewards [E, k], mask [E, k] --> chunk return, bootstrap weight
    --> replay (one row per decision) --> updates_per_step x k gradient steps per decision:
        critics on the k-step soft target, actor on alpha log pi - min Q, temperature

The actor is the run's :class:`ndp.policies.ActorCritic` (its ``squashed`` or
``ndp-squashed`` head; its PPO critic is unused), so evaluation, rendering, ONNX export and
``ndp.load_policy`` read a SAC run like a PPO one; the twin critics, their targets, the
optimisers, the temperature and the replay buffer are saved under the checkpoint's ``sac`` key.
Observations are not normalised (SAC's usual setting; the identity statistics are saved as
every RL run's).
"""

from __future__ import annotations

import copy
import math
import time
import warnings
from typing import Any

import numpy as np
import torch
from torch import nn

from ndp.chunk_info import dmp_start_keys
from ndp.nets.mlp import MLP
from ndp.policies import build_actor_critic
from ndp.policies.squashed import SquashedGaussian, SquashedNDPHead
from ndp.rl import envs as rl_envs
from ndp.rl.config import TrainConfig
from ndp.rl.logger import METRICS
from ndp.rl.sac import SAC_METRICS
from ndp.rl.normalize import ObsNormalizer
from ndp.rl.periodic_eval import PeriodicEvaluator
from ndp.rl.progress import episode_charts
from ndp.rl.sac.health import Q_RUNAWAY, q_runaway
from ndp.rl.sac.losses import (
    actor_loss,
    alpha_loss,
    bootstrap_discount,
    chunk_return,
    critic_loss,
    critic_target,
    soft_update,
)
from ndp.rl.sac.replay import DecisionReplay
from ndp.runs.session import CountsUpdates, RunSession, TrainingDivergedError, nonfinite_parameter

COLUMNS = (*METRICS, *SAC_METRICS)
"""Columns of a SAC-family run's ``metrics.csv``."""


def scores_params(head: nn.Module, critic_input: str) -> bool:
    """Whether the critics score the bounded parameters ``tanh(u)`` (NDP-SAC with
    ``critic_input='params'``) rather than the k actions."""
    return isinstance(head, SquashedNDPHead) and critic_input == "params"


def critic_input(
    u: torch.Tensor,
    dist: SquashedGaussian,
    params: bool,
    low: torch.Tensor,
    high: torch.Tensor,
) -> torch.Tensor:
    """What the critics score with the state [B, C] for raw parameters ``u`` [B, P]: ``tanh(u)``
    (``params``, see :func:`scores_params`) or the k actions ``u`` gives, inside the bounds
    ``low``, ``high`` [A] (differentiable)."""
    if params:
        return torch.tanh(u)
    return torch.maximum(torch.minimum(dist.decode(u), high), low).flatten(1)


def first_learning_decision(
    random_steps: int, batch_size: int, capacity: int, k: int, num_envs: int
) -> int | None:
    """The decision round (0-based: round j is the (j+1)-th step of every env together) of the
    first gradient step, counting every decision as k executed env steps; None when the replay
    (``capacity`` decisions) can never hold a batch. Gradient steps start once the run has
    executed ``random_steps`` env steps and the replay holds ``batch_size`` decisions; a round
    adds ``num_envs`` decisions of up to ``k`` env steps each. Episodes that end inside a
    decision execute fewer env steps, so the true first round can come later, never earlier."""
    if capacity < batch_size:
        return None
    by_steps = -(-random_steps // (num_envs * k))  # rounds until random_steps have run
    by_batch = -(-batch_size // num_envs)  # rounds until the replay holds one batch
    return max(by_steps, by_batch, 1) - 1


def check_budget(cfg: TrainConfig) -> None:
    """Refuse (ValueError naming the argument) a SAC-family run that can take no gradient step:
    a replay smaller than one batch, or a budget that ends before the random steps and the
    first batch are in (or before ``updates_per_step`` adds up to one gradient step)."""
    s, k, E = cfg.sac, cfg.k, cfg.num_envs
    capacity = -(-s.buffer_size // k)
    first = first_learning_decision(s.random_steps, s.batch_size, capacity, k, E)
    if first is None:
        raise ValueError(
            f"sac.buffer_size: expected at least batch_size x k = {s.batch_size * k} env steps "
            f"(the replay keeps {capacity} decision(s) of k={k}; a gradient step samples "
            f"{s.batch_size}), got {s.buffer_size} (use a larger --sac-buffer-size or a smaller "
            f"--sac-batch-size)"
        )
    rounds = cfg.num_updates * cfg.decisions_per_env
    budget = rounds * E * k
    if first >= rounds:
        need = (first + 1) * E * k
        raise ValueError(
            f"steps: --algo {cfg.algo} takes its first gradient step after {need:,} env steps "
            f"(sac.random_steps={s.random_steps:,} random env steps, then a batch of "
            f"sac.batch_size={s.batch_size} decisions from num_envs={E} envs), but the run "
            f"trains {budget:,} (use more --steps, or fewer --sac-random-steps / a smaller "
            f"--sac-batch-size)"
        )
    if s.updates_per_step * (rounds - first) * E * k < 1.0:
        raise ValueError(
            f"sac.updates_per_step: expected at least one gradient step in the run's "
            f"{(rounds - first) * E * k:,} learning env steps, got {s.updates_per_step!r}"
        )


class TwinQ(nn.Module):
    """Two critics ``Q_i(s, c)`` [B] of a state [B, O] and its action input [B, C]
    (``layer_norm``: LayerNorm after each hidden linear map, :class:`ndp.nets.mlp.MLP`)."""

    def __init__(
        self,
        obs_dim: int,
        in_dim: int,
        hidden: tuple[int, ...],
        activation: str,
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        self.q1 = MLP(obs_dim + in_dim, hidden, 1, activation, layer_norm=layer_norm)
        self.q2 = MLP(obs_dim + in_dim, hidden, 1, activation, layer_norm=layer_norm)

    def forward(self, obs: torch.Tensor, c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.cat([obs, c], dim=-1)
        return self.q1(x)[:, 0], self.q2(x)[:, 0]


class SACLearner(CountsUpdates):
    """SAC over decisions of k env steps (see the module docstring).

    Args:
        cfg: the resolved config (``cfg.sac``: :class:`ndp.rl.sac.config.SACConfig`).
        session: the run's session (paths, the divergence message).
    """

    def __init__(self, cfg: TrainConfig, session: RunSession) -> None:
        check_budget(cfg)  # before any env is built
        task = rl_envs.resolve_task(cfg.task, **cfg.env_options())
        self.cfg, self.spec, self.session = cfg, task.spec, session
        self.run = session.run
        s = cfg.sac
        self.k, self.E, self.T = cfg.k, cfg.num_envs, cfg.decisions_per_env
        self.gamma = float(cfg.ppo.gamma)
        self.envs, self.obs_dim = rl_envs.run_envs(cfg, task)
        self.model = build_actor_critic(self.obs_dim, self.spec, cfg.policy)
        self.P = self.model.head.n_params // 2
        self.is_ndp = isinstance(self.model.head, SquashedNDPHead)
        self.scores_params = scores_params(self.model.head, s.critic_input)
        c_dim = self.P if self.scores_params else self.k * self.spec.action_dim
        pol = cfg.policy
        assert pol.hidden is not None and pol.activation is not None  # resolve_config fills them
        self.critic = TwinQ(
            self.obs_dim, c_dim, tuple(pol.hidden), pol.activation, s.critic_layer_norm
        )
        self.critic_target = copy.deepcopy(self.critic).requires_grad_(False)
        self.log_alpha = torch.tensor(math.log(s.init_alpha), requires_grad=True)
        # fused Adam: one kernel for all tensors (the per-tensor loop of the default CPU Adam
        # was a tenth of a gradient step); same numbers up to rounding
        self.actor_opt = torch.optim.Adam(self.model.actor.parameters(), lr=s.lr, fused=True)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=s.lr, fused=True)
        self.alpha_opt = torch.optim.Adam([self.log_alpha], lr=s.lr)
        self._critic_params = list(self.critic.parameters())
        self.target_entropy = float(-self.P if s.target_entropy is None else s.target_entropy)
        D = int(self.spec.dmp_dofs)
        dims = {"obs": self.obs_dim, "next_obs": self.obs_dim, "u": self.P, "critic_in": c_dim,
                "y0": D, "dy0": D, "next_y0": D, "next_dy0": D}  # fmt: skip
        self.replay = DecisionReplay(-(-s.buffer_size // self.k), dims)
        self.obs_norm = ObsNormalizer(self.obs_dim, cfg.ppo.clip_obs, enabled=False)
        self.evaluator = PeriodicEvaluator(cfg, self.spec)
        self.low = torch.as_tensor(self.spec.action_low, dtype=torch.float32)
        self.high = torch.as_tensor(self.spec.action_high, dtype=torch.float32)
        self.rng = np.random.default_rng(cfg.seed)
        frame = cfg.policy.dmp_state
        assert frame is not None  # resolve_config fills it from the task's preset
        self.frame: str = frame
        self.update = 0
        self.global_step = 0
        self.grad_steps = 0
        self.update_debt = 0.0
        self._tracker = rl_envs.EpisodeTracker(self.E)
        self._started = False  # the envs are reset at the first iteration, after any restore
        self.return_peak: float | None = None
        """The largest |mean training-episode return| of any update so far (None: no episode
        has ended yet); saved with the checkpoint (critic health, :mod:`ndp.rl.sac.health`)."""
        self._q_warned = False  # the runaway is said once per session

    # ----------------------------------------------------------------------- protocol
    @property
    def columns(self) -> tuple[str, ...]:
        """``metrics.csv``'s columns (docs/metrics.md)."""
        return COLUMNS

    def nonfinite(self) -> str | None:
        """The first actor or critic parameter (or the temperature) holding NaN / Inf."""
        named = [*self.model.actor.named_parameters(), *self.critic.named_parameters(),
                 ("log_alpha", self.log_alpha)]  # fmt: skip
        return nonfinite_parameter(named)

    def state_dict(self) -> dict[str, Any]:
        """The policy checkpoint keys (``ndp.rl.methods.POLICY_CHECKPOINT_KEYS``) plus ``sac``:
        critics, targets, optimisers, temperature, replay, generator, counters."""
        return {
            "model": self.model.state_dict(),
            "obs_norm": self.obs_norm.state_dict(),
            "obs_dim": self.obs_dim,
            "update": self.update,
            "global_step": self.global_step,
            "sac": {
                "critic": self.critic.state_dict(),
                "critic_target": self.critic_target.state_dict(),
                "actor_opt": self.actor_opt.state_dict(),
                "critic_opt": self.critic_opt.state_dict(),
                "alpha_opt": self.alpha_opt.state_dict(),
                "log_alpha": self.log_alpha.detach().clone(),
                "replay": self.replay.state_dict(),
                "rng": self.rng.bit_generator.state,
                "grad_steps": self.grad_steps,
                "update_debt": self.update_debt,
                "return_peak": self.return_peak,
            },
        }

    def load_state_dict(self, ckpt: dict[str, Any]) -> None:
        """Continue from :meth:`state_dict`'s output (the session restores the global RNGs)."""
        self.model.load_state_dict(ckpt["model"])
        self.obs_norm.load_state_dict(ckpt["obs_norm"])
        self.update, self.global_step = int(ckpt["update"]), int(ckpt["global_step"])
        s = ckpt["sac"]
        self.critic.load_state_dict(s["critic"])
        self.critic_target.load_state_dict(s["critic_target"])
        self.actor_opt.load_state_dict(s["actor_opt"])
        self.critic_opt.load_state_dict(s["critic_opt"])
        self.alpha_opt.load_state_dict(s["alpha_opt"])
        with torch.no_grad():
            self.log_alpha.copy_(s["log_alpha"])
        self.replay.load_state_dict(s["replay"])
        self.rng.bit_generator.state = s["rng"]
        self.grad_steps, self.update_debt = int(s["grad_steps"]), float(s["update_debt"])
        self.return_peak = s.get("return_peak")  # checkpoints before 2026-12-05 lack it

    def close(self) -> None:
        """Close the environments (training and evaluation)."""
        self.envs.close()
        self.evaluator.close()

    # ----------------------------------------------------------------------- acting
    def _start(self) -> None:
        seeds = rl_envs.env_seeds(self.cfg.seed, self.E, epoch=self.update)
        obs, info = self.envs.reset(seed=seeds)  # type: ignore[arg-type]
        self._obs = np.asarray(obs, dtype=np.float64).reshape(self.E, self.obs_dim)
        self._y0, self._dy0 = rl_envs.decision_start(info, self.E, self.frame)
        self._started = True

    def _dist(self, obs: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor) -> SquashedGaussian:
        dist, _ = self.model.distribution(obs, y0, dy0)
        assert isinstance(dist, SquashedGaussian)  # the squashed heads
        return dist

    def critic_input(self, u: torch.Tensor, dist: SquashedGaussian) -> torch.Tensor:
        """What the critics score with the state [B, C] (:func:`critic_input`)."""
        return critic_input(u, dist, self.scores_params, self.low, self.high)

    def _random_u(self) -> torch.Tensor:
        """Raw parameters [E, P] uniform in the bounded space (tanh(u) ~ U(-1, 1)^P)."""
        p = self.rng.uniform(-1.0 + 1e-6, 1.0 - 1e-6, size=(self.E, self.P))
        return torch.as_tensor(np.arctanh(p), dtype=torch.float32)

    def _next_start(self, infos: dict[str, Any], done: np.ndarray) -> tuple[np.ndarray, ...]:
        """The robot state (y0, dy0) [E, D] after the decision: the finished step's where an
        episode ended (the next state of its last transition), else the env's."""
        ky, kdy = dmp_start_keys(self.frame)
        y0, dy0 = rl_envs.decision_start(infos, self.E, self.frame)
        if done.any() and ky in infos.get("final_info", {}):
            y0 = rl_envs.step_info(infos, done, ky).reshape(self.E, -1)
            dy0 = rl_envs.step_info(infos, done, kdy).reshape(self.E, -1)
        return y0, dy0

    # ----------------------------------------------------------------------- learning
    def iterate(self) -> dict[str, float]:
        """T decisions per env, with ``updates_per_step`` gradient steps per env step once the
        random steps are done; returns the iteration's metrics row.

        Raises:
            TrainingDivergedError: NaN / Inf in a loss or parameter.
        """
        if not self._started:
            self._start()
        t0 = time.perf_counter()
        s, E, k = self.cfg.sac, self.E, self.k
        episodes: list[tuple[float, float, float, float, float]] = []
        losses: dict[str, list[float]] = {"critic": [], "actor": [], "alpha": [], "q": []}
        executed, t_update = 0, 0.0
        for _ in range(self.T):
            obs = torch.as_tensor(self._obs, dtype=torch.float32)
            y0 = torch.as_tensor(self._y0, dtype=torch.float32)
            dy0 = torch.as_tensor(self._dy0, dtype=torch.float32)
            with torch.no_grad():
                dist = self._dist(obs, y0, dy0)
                acting = self.global_step + executed >= s.random_steps
                u = dist.sample() if acting else self._random_u()
                act = torch.maximum(torch.minimum(dist.actions(u), self.high), self.low)
                c = self.critic_input(u, dist)
            if not bool(torch.isfinite(act).all()):
                raise self.session.diverged("non-finite actions (check the observations)",
                                            self.update)  # fmt: skip
            nxt, _, term, trunc, infos = self.envs.step(act.numpy())
            term = np.asarray(term, dtype=bool)
            done = term | np.asarray(trunc, dtype=bool)
            sub_r, live, mask = rl_envs.decision_rewards(infos, done, E, k)
            self._tracker.add(infos, done, sub_r, live, mask, episodes)
            ret, n = chunk_return(torch.as_tensor(sub_r), torch.as_tensor(mask), self.gamma)
            discount = bootstrap_discount(n, torch.as_tensor(term, dtype=n.dtype), self.gamma)
            nxt = np.asarray(nxt, dtype=np.float64).reshape(E, self.obs_dim)
            final = nxt.copy()
            if done.any() and "final_obs" in infos:
                for i in np.flatnonzero(done):
                    final[i] = np.asarray(infos["final_obs"][i], dtype=np.float64).reshape(-1)
            next_y0, next_dy0 = self._next_start(infos, done)
            self.replay.add(obs=self._obs, y0=self._y0, dy0=self._dy0, u=u.numpy(),
                            critic_in=c.numpy(), ret=ret.numpy(), discount=discount.numpy(),
                            next_obs=final, next_y0=next_y0, next_dy0=next_dy0)  # fmt: skip
            n_exec = int(mask.sum())
            executed += n_exec
            self._obs = nxt
            self._y0, self._dy0 = rl_envs.decision_start(infos, E, self.frame)
            if self.global_step + executed >= s.random_steps and self.replay.size >= s.batch_size:
                self.update_debt += s.updates_per_step * n_exec
                t1 = time.perf_counter()
                while self.update_debt >= 1.0:
                    self._gradient_step(losses)
                    self.update_debt -= 1.0
                t_update += time.perf_counter() - t1
        self.update += 1
        before, self.global_step = self.global_step, self.global_step + executed
        wall = time.perf_counter() - t0
        row = self._metrics(episodes, losses, executed, wall - t_update, t_update)
        last = self.update >= self.cfg.num_updates
        row.update(self.evaluator.maybe(before, self.global_step, last, self.model, self.obs_norm))
        self._watch_critic(row)
        return row

    def _watch_critic(self, row: dict[str, float]) -> None:
        """Track the largest mean episode return and say once (stderr, RuntimeWarning) when the
        critics' estimate runs away from it (:func:`ndp.rl.sac.health.q_runaway`)."""
        ret = row.get("charts/episode_return", math.nan)
        if math.isfinite(ret):
            self.return_peak = max(self.return_peak or 0.0, abs(ret))
        q = row.get("sac/q", math.nan)
        if self._q_warned or self.return_peak is None or not q_runaway(q, self.return_peak):
            return
        self._q_warned = True
        warnings.warn(
            f"sac: at update {self.update} (env step {self.global_step:,}) the critics' mean "
            f"value estimate is {q:,.0f}, above {Q_RUNAWAY:g}x the largest mean episode return "
            f"so far ({self.return_peak:,.0f}): the critic is running away; numbers of this "
            "run are those of a diverged critic (docs/offpolicy.md, 'Critic health'; said once)",
            RuntimeWarning,
            stacklevel=2,
        )

    def _gradient_step(self, losses: dict[str, list[float]]) -> None:
        """One step of the critics, the actor and the temperature on a replay batch."""
        s = self.cfg.sac
        b = self.replay.sample(s.batch_size, self.rng)
        alpha = self.log_alpha.detach().exp()
        with torch.no_grad():
            dist_n = self._dist(b["next_obs"], b["next_y0"], b["next_dy0"])
            u_n = dist_n.sample()
            q1_t, q2_t = self.critic_target(b["next_obs"], self.critic_input(u_n, dist_n))
            logp_n = dist_n.log_prob(u_n)[:, 0]
            y = critic_target(b["ret"][:, 0], b["discount"][:, 0], q1_t, q2_t, logp_n, alpha)
        q1, q2 = self.critic(b["obs"], b["critic_in"])
        lc = critic_loss(q1, q2, y)
        self._step(self.critic_opt, lc, "critic")
        dist = self._dist(b["obs"], b["y0"], b["dy0"])
        u = dist.rsample()
        logp = dist.log_prob(u)[:, 0]
        for p in self._critic_params:  # the actor's loss does not train the critics
            p.requires_grad_(False)
        try:
            q1_pi, q2_pi = self.critic(b["obs"], self.critic_input(u, dist))
        finally:
            for p in self._critic_params:
                p.requires_grad_(True)
        la = actor_loss(logp, q1_pi, q2_pi, alpha)
        self._step(self.actor_opt, la, "actor")
        lt = alpha_loss(self.log_alpha, logp, self.target_entropy)
        self._step(self.alpha_opt, lt, "temperature")
        soft_update(self.critic_target, self.critic, s.tau)
        self.grad_steps += 1
        losses["critic"].append(float(lc.detach()))
        losses["actor"].append(float(la.detach()))
        losses["alpha"].append(float(lt.detach()))
        losses["q"].append(float(torch.minimum(q1, q2).detach().mean()))

    def _step(self, opt: torch.optim.Optimizer, loss: torch.Tensor, what: str) -> None:
        if not bool(torch.isfinite(loss)):
            raise self._diverged(f"the {what} loss became {float(loss)}")
        opt.zero_grad(set_to_none=True)
        loss.backward()  # type: ignore[no-untyped-call]  # torch: Tensor.backward is unannotated
        opt.step()

    def _diverged(self, what: str) -> TrainingDivergedError:
        return self.session.diverged(what, self.update)

    def _metrics(
        self,
        episodes: list[tuple[float, float, float, float, float]],
        losses: dict[str, list[float]],
        executed: int,
        t_roll: float,
        t_upd: float,
    ) -> dict[str, float]:
        def mean(key: str) -> float:
            v = losses[key]
            return float(np.mean(v)) if v else math.nan

        return {
            "update": self.update,
            "global_step": self.global_step,
            **episode_charts(episodes),
            "charts/env_steps_per_s": executed / max(t_roll + t_upd, 1e-9),
            "charts/learning_rate": self.cfg.sac.lr,
            "losses/policy": mean("actor"),
            "losses/value": mean("critic"),
            "time/rollout_s": t_roll,
            "time/update_s": t_upd,
            "sac/alpha": float(self.log_alpha.detach().exp()),
            "sac/alpha_loss": mean("alpha"),
            "sac/q": mean("q"),
            "sac/replay": float(self.replay.size),
            "sac/gradient_steps": float(self.grad_steps),
        }
