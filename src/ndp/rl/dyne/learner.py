"""Dyn-E (Whitney, Agarwal, Cho, Gupta, "Dynamics-aware Embeddings", ICLR 2020): TD3 acting once
per k env steps in a learned embedding of k-action sequences (``ndp rl train --algo dyne``).

A run has two phases, on one budget of env steps (``--steps``) and one ``metrics.csv``:

1. **Exploration** (``explore_steps``, rounded up to whole iterations): every env runs uniformly
   random k-action sequences through the chunked env. Each full chunk gives (robot state at its
   start, the k actions, the state change over the chunk), state = the chunked env's
   ``robot_pos`` / ``robot_vel`` (joint or hand positions and velocities). The embedding
   (:class:`ndp.policies.dyne.SequenceEmbedding`) and the action decoder are trained on them
   (:func:`train_embedding`), then frozen; the decoder and the latent range become the policy's
   action head (:class:`ndp.policies.dyne.DyneHead`). These env steps count in ``global_step``.
2. **TD3 in the latent** (Fujimoto et al., 2018): the actor (``--hidden``, 400-300 ReLU) outputs
   ``max_latent * tanh(.)``; exploration adds N(0, (expl_noise * max_latent)^2) and clips; the
   latent is decoded into k actions, clipped to the action bounds and executed open loop by the
   chunked env with the same stale-world rule as NDP. A replay entry is one decision: (obs,
   latent, k sub-rewards, k sub-step mask, next decision's obs, terminated). Twin critics
   ``Q(obs, latent)`` (the latent repeated to about half the observation size, as in the
   original) regress onto ``sum_j gamma^j r_j + gamma^n (1 - terminated) min Q'(obs', pi'(obs') +
   clip(noise))`` (n = executed sub-steps; a truncated episode bootstraps from its final
   observation); the actor and the targets update every ``policy_delay`` critic steps (soft,
   ``tau``). ``updates_per_step`` gradient steps per env step (the original's ratio: 1).

Iterations: one row of ``metrics.csv`` (``update``) per ``cfg.decisions_per_env`` decisions in
every env, as for PPO (``--steps-per-update``), so budgets, ``--checkpoint-every`` and the
studies' bookkeeping are the same. The first checkpoint is written once the embedding is
trained (a run killed during exploration restarts from scratch); from then on a checkpoint holds
the policy (``model``: actor + head with the frozen decoder, the keys of
``ndp.rl.methods.POLICY_CHECKPOINT_KEYS``), the embedding, critics, target nets, optimisers, the
replay buffer (filled part), RNGs and counters: ``--resume`` continues with all of them; only
the simulator states are not saved (every env starts a new episode, as for PPO).

Both phases run on the off-policy learners' collection loop
(:class:`ndp.rl.offpolicy.loop.OffPolicyLearner`, as SAC and TD3): the exploration phase is
:meth:`DyneLearner.act` (random action sequences) and :meth:`DyneLearner.store` (the chunks
kept for the embedding), the embedding's fit :meth:`DyneLearner.end_iteration`, the TD3 step
:meth:`DyneLearner.gradient_step` on Dyn-E's own replay (:data:`DYNE_REPLAY_FIELDS`).

Observations enter TD3 unnormalised (as in the original); the checkpoint's ``obs_norm`` holds
identity statistics so that ``ndp rl eval`` / ``render`` / ``export`` feed the policy exactly
what it trained on (clipped to +- ``clip_obs``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from ndp.nets.mlp import MLP
from ndp.policies.dyne import ActionDecoder, DyneHead, SequenceEmbedding
from ndp.rl.config import TrainConfig
from ndp.rl.dyne import DYNE_METRICS
from ndp.rl.dyne.config import DyneConfig
from ndp.rl.methods import section, with_section
from ndp.rl.normalize import ObsNormalizer
from ndp.rl.offpolicy.loop import Decision, LoopBudget, OffPolicyLearner
from ndp.rl.offpolicy.state import Part
from ndp.rl.optim import soft_update
from ndp.rl.replay import RingReplay
from ndp.runs.checkpoint import INT, FiniteTensor, Spec
from ndp.runs.session import (
    RunSession,
    TrainingDivergedError,
    checkpoint_due,
)

DEFAULT_EXPLORE_STEPS = 50_000
"""Exploration env steps of the embedding where a task has no preset: 10k sequences of k = 5,
a sixth of the learning study's 300k budget (the original used 100k random 4-step sequences,
400k env steps, for budgets of 1M-10M env steps)."""
DYNE_EXPLORE_STEPS = {"point-mass": 5_000, "point-mass-3d": 5_000}
"""Per-task presets of ``explore_steps`` (env steps of random action sequences)."""


def _dyne(cfg: TrainConfig) -> DyneConfig:
    """The run's Dyn-E settings (``cfg.dyne``, typed)."""
    return section(cfg, DyneConfig)


def resolve_dyne_config(cfg: TrainConfig) -> TrainConfig:
    """Fill ``dyne.explore_steps`` where None: the task's preset, at most a sixth of the budget
    (the preset's share of the 300k study budget), so that short budgets keep TD3 iterations."""
    if _dyne(cfg).explore_steps is not None:
        return cfg
    n = min(DYNE_EXPLORE_STEPS.get(cfg.task, DEFAULT_EXPLORE_STEPS), max(cfg.steps // 6, 1))
    return with_section(cfg, dataclasses.replace(_dyne(cfg), explore_steps=n))


def explore_iterations(cfg: TrainConfig) -> int:
    """Iterations (rows) of the exploration phase: ceil(explore_steps / env steps per row)."""
    n = _dyne(cfg).explore_steps
    assert n is not None
    return math.ceil(n / cfg.env_steps_per_update)


def check_budget(cfg: TrainConfig) -> None:
    """The budget must leave at least one TD3 iteration after the exploration data, and that
    phase must collect one TD3 batch (DyneConfig checks that the replay holds one); otherwise
    ValueError naming the argument."""
    n = explore_iterations(cfg)
    if cfg.num_updates <= n:
        raise ValueError(
            f"steps: Dyn-E spends its first {n * cfg.env_steps_per_update} env steps "
            f"(explore_steps={_dyne(cfg).explore_steps}, in iterations of "
            f"{cfg.env_steps_per_update}) on exploration data for the embedding; --steps "
            f"{cfg.steps} leaves no TD3 iteration (use more --steps or fewer --explore-steps)"
        )
    d = _dyne(cfg)
    decisions = (cfg.num_updates - n) * cfg.decisions_per_env * cfg.num_envs
    if decisions < d.batch_size:
        raise ValueError(
            f"steps: Dyn-E's TD3 phase collects {decisions} decision(s) after the exploration "
            f"data, fewer than one batch (dyne.batch_size={d.batch_size}), so TD3 never takes a "
            f"step (use more --steps or a smaller --batch-size)"
        )


# --------------------------------------------------------------------------- embedding
def train_embedding(
    emb: SequenceEmbedding,
    decoder: ActionDecoder,
    s0: torch.Tensor,
    actions: torch.Tensor,
    delta: torch.Tensor,
    cfg: DyneConfig,
    generator: torch.Generator | None = None,
) -> dict[str, float]:
    """Train the embedding on random action sequences, then the decoder; freeze both.

    1. Whitening statistics of ``s0`` and ``delta``; ``embed_updates`` Adam (amsgrad) steps on
       the whitened prediction error + ``kl_weight`` KL (:meth:`SequenceEmbedding.loss`).
    2. The encoder means over the data give the latent's whitening statistics and its range
       ``max_latent`` = the largest whitened magnitude.
    3. ``decoder_updates`` Adam steps on ``|| white(E(D(z))) - z ||^2 + norm_weight * sum ||a||``
       over whitened latents z of the data (the encoder is frozen).

    Args:
        emb, decoder: the networks (trained in place).
        s0: start states [N, S]; actions [N, k, A]; delta: state changes [N, S].
        cfg: the Dyn-E settings.
        generator: torch generator of the mini-batch indices and the VAE noise seed.

    Returns:
        ``embed_loss_first`` / ``embed_loss`` (prediction loss over the first / last 10% of the
        steps), ``embed_kl``, ``decoder_loss_first`` / ``decoder_loss`` (cycle loss, likewise),
        ``max_latent``, ``sequences`` (N).
    """
    n = s0.shape[0]
    if n < 2:
        raise ValueError(f"explore_steps: expected at least 2 full action sequences, got {n}")
    b = min(cfg.embed_batch, n)
    pred_hist, kl_hist = _fit_embedding_net(emb, s0, actions, delta, cfg, b, generator)
    white, max_latent = _whiten_latents(emb, actions)
    dec_hist = _fit_decoder(emb, decoder, white, cfg, b, generator)
    return {
        "embed_loss_first": _window_mean(pred_hist, False),
        "embed_loss": _window_mean(pred_hist, True),
        "embed_kl": _window_mean(kl_hist, True),
        "decoder_loss_first": _window_mean(dec_hist, False),
        "decoder_loss": _window_mean(dec_hist, True),
        "max_latent": max_latent,
        "sequences": float(n),
    }


def _fit_embedding_net(
    emb: SequenceEmbedding,
    s0: torch.Tensor,
    actions: torch.Tensor,
    delta: torch.Tensor,
    cfg: DyneConfig,
    b: int,
    generator: torch.Generator | None,
) -> tuple[list[float], list[float]]:
    """Step 1 of :func:`train_embedding`: whitening statistics, then ``embed_updates`` steps
    on mini-batches of ``b`` sequences; the encoder is frozen after. Returns the prediction
    loss and the KL of every step."""
    n = s0.shape[0]
    emb.set_state_stats(s0, delta)
    opt = torch.optim.Adam(emb.parameters(), lr=cfg.embed_lr, amsgrad=True)
    pred_hist: list[float] = []
    kl_hist: list[float] = []
    emb.train()
    for _ in range(cfg.embed_updates):
        idx = torch.randint(n, (b,), generator=generator)
        loss, pred, kl = emb.loss(s0[idx], actions[idx], delta[idx], cfg.kl_weight)
        if not bool(torch.isfinite(loss)):
            raise TrainingDivergedError(
                f"the embedding's loss became {float(loss.detach())} (check the exploration data)"
            )
        opt.zero_grad()
        loss.backward()  # type: ignore[no-untyped-call]  # torch: Tensor.backward is unannotated
        opt.step()
        pred_hist.append(float(pred.detach()))
        kl_hist.append(float(kl.detach()))
    emb.eval()
    for p in emb.parameters():
        p.requires_grad_(False)
    return pred_hist, kl_hist


def _whiten_latents(emb: SequenceEmbedding, actions: torch.Tensor) -> tuple[torch.Tensor, float]:
    """Step 2 of :func:`train_embedding`: the encoder means of the data set the latent's
    whitening statistics; returns the whitened latents [N, L] and their largest magnitude."""
    n = actions.shape[0]
    with torch.no_grad():
        mu = torch.cat([emb.encode(actions[i : i + 4096])[0] for i in range(0, n, 4096)])
        std = mu.std(0)
        emb.z_mean.copy_(mu.mean(0))
        emb.z_std.copy_(torch.where(std > 1e-6, std, torch.ones_like(std)))
        white = emb.whiten_latent(mu)
        return white, float(white.abs().max())


def _fit_decoder(
    emb: SequenceEmbedding,
    decoder: ActionDecoder,
    white: torch.Tensor,
    cfg: DyneConfig,
    b: int,
    generator: torch.Generator | None,
) -> list[float]:
    """Step 3 of :func:`train_embedding`: ``decoder_updates`` steps of the cycle loss on
    mini-batches of ``b`` whitened latents; the decoder is frozen after. Returns the cycle
    loss of every step."""
    n = white.shape[0]
    dopt = torch.optim.Adam(decoder.parameters(), lr=cfg.embed_lr)
    dec_hist: list[float] = []
    for _ in range(cfg.decoder_updates):
        z = white[torch.randint(n, (b,), generator=generator)]
        a = decoder(z)
        z_hat = emb.whiten_latent(emb.encode(a)[0])
        recon = F.mse_loss(z_hat, z)
        loss = recon + cfg.norm_weight * a.norm(dim=2).sum()
        if not bool(torch.isfinite(loss)):
            raise TrainingDivergedError(f"the action decoder's loss became {float(loss.detach())}")
        dopt.zero_grad()
        loss.backward()
        dopt.step()
        dec_hist.append(float(recon.detach()))
    for p in decoder.parameters():
        p.requires_grad_(False)
    return dec_hist


def _window_mean(h: list[float], last: bool) -> float:
    """The mean of the first (``last`` False) or last tenth (at least one value) of ``h``;
    NaN for none."""
    if not h:
        return math.nan
    m = max(1, len(h) // 10)
    return float(np.mean(h[-m:] if last else h[:m]))


# --------------------------------------------------------------------------- TD3 pieces
class TwinCritic(nn.Module):
    """Two Q networks ``Q_i(obs, latent)``; the latent is repeated ``max(1, (O // 2) // L)``
    times so that it is not drowned by a long observation (the original's critic)."""

    def __init__(self, obs_dim: int, latent_dim: int, hidden: tuple[int, ...], activation: str):
        super().__init__()
        self.repeat = max(1, (obs_dim // 2) // latent_dim)
        in_dim = obs_dim + latent_dim * self.repeat
        self.q1 = MLP(in_dim, hidden, 1, activation)
        self.q2 = MLP(in_dim, hidden, 1, activation)

    def _x(self, obs: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        return torch.cat((obs, z.repeat(1, self.repeat)), dim=-1)

    def forward(self, obs: torch.Tensor, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = self._x(obs, z)
        return self.q1(x).squeeze(-1), self.q2(x).squeeze(-1)

    def first(self, obs: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        q: torch.Tensor = self.q1(self._x(obs, z)).squeeze(-1)
        return q


DYNE_REPLAY_FIELDS = ("obs", "z", "rew", "mask", "next_obs", "term")
"""Dyn-E's replay columns: observation [O], latent action [L], sub-rewards and executed-step
mask [k], next observation [O], termination (scalar)."""


def dyne_replay(capacity: int, obs_dim: int, latent_dim: int, k: int) -> RingReplay:
    """Dyn-E's ring of decisions (:data:`DYNE_REPLAY_FIELDS`)."""
    shapes = {"obs": (obs_dim,), "z": (latent_dim,), "rew": (k,), "mask": (k,),
              "next_obs": (obs_dim,), "term": ()}  # fmt: skip
    return RingReplay(int(capacity), shapes)


# --------------------------------------------------------------------------- learner
class DyneLearner(OffPolicyLearner):
    """Dyn-E on the shared off-policy loop (:class:`ndp.rl.offpolicy.loop.OffPolicyLearner`;
    see the module docstring): the exploration phase and TD3 in the latent are the loop's
    ``act`` / ``store`` / ``gradient_step``, the embedding's fit its ``end_iteration``.

    An :class:`ndp.rl.run.RLLearner`: the run driver opens the run, seeds, restores and
    drives it.

    Args:
        cfg: the resolved config (``resolve_config``); ``dyne.explore_steps`` is filled here.
        session: the run's session (paths, the divergence message).
    """

    section = "dyne"
    own_columns = DYNE_METRICS
    critic: TwinCritic
    actor_target: nn.Module

    def __init__(self, cfg: TrainConfig, session: RunSession) -> None:
        cfg = resolve_dyne_config(cfg)
        check_budget(cfg)  # before any env is built
        d = self.settings = _dyne(cfg)
        # no random steps of the loop's own: Dyn-E's phases are its act's (start_steps included)
        self._open_loop(cfg, session, LoopBudget(0, d.batch_size, d.updates_per_step))
        self.gen = torch.Generator().manual_seed(cfg.seed)
        self.n_explore = explore_iterations(cfg)
        head = self.model.head
        assert isinstance(head, DyneHead)
        self.head: DyneHead = head
        self.L = head.latent_dim
        pol = cfg.policy
        self.state_dim = 2 * int(self.spec.dmp_dofs)
        self.embedding = SequenceEmbedding(self.k, self.spec.action_dim, self.state_dim, self.L)
        assert pol.hidden is not None and pol.activation is not None  # resolve_config fills them
        self._open_critics(TwinCritic(self.obs_dim, self.L, tuple(pol.hidden), pol.activation),
                           actor_target=self.model.actor)  # fmt: skip
        self.actor_opt = torch.optim.Adam(self.model.actor.parameters(), lr=d.actor_lr, fused=True)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=d.critic_lr, fused=True)
        # identity statistics: TD3 sees raw observations (clipped), as eval will; the robot
        # state of the exploration data is the measured one
        self._open_collection(dyne_replay(d.replay_size, self.obs_dim, self.L, self.k),
                              ObsNormalizer(self.obs_dim, cfg.clip_obs, cfg.norm_obs),
                              "measured")  # fmt: skip
        self._low = np.asarray(self.spec.action_low, dtype=np.float64)
        self._high = np.asarray(self.spec.action_high, dtype=np.float64)
        self.rl_steps = 0  # env steps of the TD3 phase
        self.embed_stats: dict[str, float] = {}
        self.embedded = False
        self._explore_data: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._fitted: dict[str, float] = {}  # the fit's statistics, in its iteration's row

    # ----------------------------------------------------------------------- state
    def extra_parts(self) -> dict[str, Part]:
        """The embedding (saved after the shared parts)."""
        return {"embedding": self.embedding}

    def extra_state(self) -> dict[str, object]:
        """The torch generator, the TD3 phase's env steps, the embedding's statistics."""
        return {"gen": self.gen.get_state(), "rl_steps": self.rl_steps,
                "embed_stats": dict(self.embed_stats)}  # fmt: skip

    def extra_schema(self) -> dict[str, Spec]:
        """``gen`` a generator state, ``rl_steps`` an integer, ``embed_stats`` a dict."""
        return {"gen": FiniteTensor(self.gen.get_state()), "rl_steps": INT, "embed_stats": dict}

    def load_extra_state(self, s: dict[str, Any]) -> None:
        """Restore the values of :meth:`extra_state`; the embedding is fitted: freeze it."""
        self.gen.set_state(s["gen"])
        self.rl_steps = int(s["rl_steps"])
        self.embed_stats = dict(s["embed_stats"])
        self.embedded = True
        self._freeze_embedding()

    def _freeze_embedding(self) -> None:
        self.embedding.eval()
        self.embedding.requires_grad_(False)
        self.head.requires_grad_(False)

    def checkpoint_due(self, every: int, last: int) -> bool:
        """Checkpoints start once the embedding is fitted (at the end of exploration), then
        follow the default cadence."""
        return self.embedded and (
            self.update == self.n_explore or checkpoint_due(self.update, every, last)
        )

    # ----------------------------------------------------------------------- acting
    def _exploring(self) -> bool:
        """Whether the current iteration collects the embedding's data."""
        return self.update < self.n_explore

    def act(
        self, obs: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor, explore: bool
    ) -> tuple[torch.Tensor, dict[str, np.ndarray]]:
        """The exploration phase: uniformly random k-action sequences (column ``actions``,
        for the embedding). Then latents [E, L] (column ``z``): uniformly random during
        ``start_steps``, else the actor's plus N(0, (expl_noise max_latent)^2), clipped to the
        latent range; decoded into k actions clipped to the bounds. ``explore`` is unused
        (the loop has no random steps of its own for Dyn-E)."""
        if self._exploring():
            a = self.rng.uniform(self._low, self._high, size=(self.E, self.k, self.spec.action_dim))
            return torch.as_tensor(a.astype(np.float32)), {"actions": a}
        z = self._latent(obs)
        a = self.head.decode(torch.from_numpy(z)).numpy().astype(np.float64)
        a = np.clip(a, self._low, self._high)
        return torch.as_tensor(a.astype(np.float32)), {"z": z}

    def _latent(self, obs: torch.Tensor) -> np.ndarray:
        """Latents [E, L] for the next decision (random during start_steps, else actor +
        exploration noise, clipped to the latent range)."""
        m = float(self.head.max_latent)
        if self.rl_steps < self.settings.start_steps:
            return self.rng.uniform(-m, m, size=(self.E, self.L)).astype(np.float32)
        z = self.head.latent(self.model.actor(obs)).numpy()
        noise = self.rng.normal(0.0, self.settings.expl_noise * m, size=z.shape)
        return np.clip(z + noise, -m, m).astype(np.float32)

    def store(self, d: Decision) -> None:
        """The exploration phase keeps the full chunks (measured robot state at the start,
        the k actions, the state change); the TD3 phase adds one replay row per env
        (:data:`DYNE_REPLAY_FIELDS`) and counts its env steps."""
        if self._exploring():
            s0 = np.concatenate((d.y0, d.dy0), axis=1)
            end = np.concatenate((d.next_y0, d.next_dy0), axis=1)
            full = d.mask.sum(1) == self.k
            self._explore_data.append((s0[full], d.columns["actions"][full], (end - s0)[full]))
            return
        self.replay.add(obs=d.obs, z=d.columns["z"], rew=d.sub_rewards, mask=d.mask,
                        next_obs=d.next_obs, term=d.terminated.astype(np.float32))  # fmt: skip
        self.rl_steps += int(d.mask.sum())

    # ----------------------------------------------------------------------- learning
    def end_iteration(self) -> None:
        """After the last exploration iteration: fit the embedding (its row shows the fit)."""
        self._fitted = self._fit_embedding() if self.update + 1 == self.n_explore else {}

    def _fit_embedding(self) -> dict[str, float]:
        s0, act, delta = (
            torch.as_tensor(np.concatenate(x), dtype=torch.float32)
            for x in zip(*self._explore_data, strict=True)
        )
        stats = train_embedding(self.embedding, self.head.decoder, s0, act, delta, self.settings,
                                self.gen)  # fmt: skip
        with torch.no_grad():
            self.head.max_latent.fill_(stats["max_latent"])
        self._explore_data = []
        self.embedded = True
        self._freeze_embedding()
        self.embed_stats = stats
        return stats

    def evaluate(self, before: int, last: bool) -> dict[str, float]:
        """The periodic evaluation, once the embedding is fitted (before it there is no
        policy to evaluate)."""
        return super().evaluate(before, last) if self.embedded else {}

    def gradient_step(self, b: dict[str, torch.Tensor]) -> dict[str, float]:
        """One TD3 critic step in the latent (the k-step target from the sub-rewards and the
        mask); the actor and the targets every ``policy_delay``-th one."""
        d, k, gamma = self.settings, self.k, self.gamma
        m = self.head.max_latent
        with torch.no_grad():
            noise = (torch.randn_like(b["z"]) * (d.target_noise * m)).clamp(
                -d.target_noise_clip * m, d.target_noise_clip * m
            )
            z2 = torch.maximum(
                torch.minimum(self.head.latent(self.actor_target(b["next_obs"])) + noise, m), -m
            )
            q1t, q2t = self.critic_target(b["next_obs"], z2)
            disc = gamma ** torch.arange(k, dtype=torch.float32)
            ret = (b["rew"] * b["mask"] * disc).sum(1)
            boot = (gamma ** b["mask"].sum(1)) * (1.0 - b["term"])
            y = ret + boot * torch.minimum(q1t, q2t)
        q1, q2 = self.critic(b["obs"], b["z"])
        critic_loss = F.mse_loss(q1, y) + F.mse_loss(q2, y)
        self._step(self.critic_opt, critic_loss, "critic")
        out = {"critic": float(critic_loss.detach()), "q": float(q1.detach().mean())}
        if (self.grad_steps + 1) % d.policy_delay == 0:  # the loop counts the step after
            with self._critics_frozen():
                z = self.head.latent(self.model.actor(b["obs"]))
                actor_loss = -self.critic.first(b["obs"], z).mean()
                self._step(self.actor_opt, actor_loss, "actor")
            out["actor"] = float(actor_loss.detach())
            soft_update(self.critic_target, self.critic, d.tau)
            soft_update(self.actor_target, self.model.actor, d.tau)
        return out

    def algorithm_metrics(self, losses: dict[str, list[float]]) -> dict[str, float]:
        """Dyn-E's columns of the row: the shared ones (the learning rate NaN during
        exploration), the exploration noise and the embedding's fit (its iteration only)."""
        in_rl = self.update > self.n_explore  # the loop has counted this iteration
        m = float(self.head.max_latent) if self.embedded else math.nan
        return {
            **self.loop_metrics(losses, self.settings.critic_lr if in_rl else math.nan),
            "policy/std": self.settings.expl_noise * m if in_rl else math.nan,
            "dyne/embed_loss": self._fitted.get("embed_loss", math.nan),
            "dyne/embed_kl": self._fitted.get("embed_kl", math.nan),
            "dyne/decoder_loss": self._fitted.get("decoder_loss", math.nan),
        }

    def close(self) -> None:
        """Close the environments (training and evaluation) and release the run."""
        super().close()
        self.session.close()
