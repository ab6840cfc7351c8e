"""The off-policy collection loop shared by the SAC family (:mod:`ndp.rl.sac`: SAC, chunked
SAC, NDP-SAC), TD3 (:mod:`ndp.rl.td3`) and Dyn-E (:mod:`ndp.rl.dyne`): env stepping over
decisions of k env steps, the chunk return and its bootstrap weight, replay insertion, the
random steps before learning, the gradient-step budget, the periodic evaluation and the
metrics row.

One iteration (E envs, T decisions per env, k sub-steps, A actions, O observations)::

    obs [E, O] (through obs_norm), robot state y0, dy0 [E, D] --algorithm.act--> actions
    [E, k, A] + the algorithm's replay columns --ChunkedEnv x E--> sub-rewards [E, k], mask
    [E, k] --algorithm.store (default: chunk return, bootstrap weight)--> replay (one row per
    decision) --> once random_steps env steps have run and the replay holds a batch:
    updates_per_step x (executed env steps) gradient steps (algorithm.gradient_step on a
    replay batch) --> algorithm.end_iteration --> the row (algorithm.algorithm_metrics,
    algorithm.evaluate)

A learner subclasses :class:`OffPolicyLearner` and supplies only the algorithm's part
(:class:`OffPolicyAlgorithm`: acting, one gradient step, its metrics and its state); the run
driver (:mod:`ndp.runs.driver`) opens, seeds, restores, drives and checkpoints it. Dyn-E uses
the hooks too: its exploration phase acts with random action sequences, its ``store`` keeps
them for the embedding (then its own replay rows: the latent, the sub-rewards and the mask),
its ``end_iteration`` fits the embedding, and its ``evaluate`` waits for the fitted embedding.
"""

from __future__ import annotations

import contextlib
import copy
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import torch
from torch import nn

from ndp.chunk_info import dmp_start_keys
from ndp.policies import build_actor_critic
from ndp.rl import envs as rl_envs
from ndp.rl.config import TrainConfig
from ndp.rl.logger import METRICS
from ndp.rl.methods import SETTINGS
from ndp.rl.normalize import ObsNormalizer
from ndp.rl.offpolicy.replay import DecisionReplay
from ndp.rl.offpolicy.returns import bootstrap_discount, chunk_return
from ndp.rl.offpolicy.state import OffPolicyState, Part
from ndp.rl.periodic_eval import PeriodicEvaluator
from ndp.rl.progress import episode_charts
from ndp.rl.replay import RingReplay
from ndp.runs.session import (
    CountsUpdates,
    RunSession,
    TrainingDivergedError,
    nonfinite_parameter,
)

REPLAY_COLUMNS = ("obs", "y0", "dy0", "ret", "discount", "next_obs", "next_y0", "next_dy0")
"""Replay columns the loop fills itself (a batch holds them as [B, width] tensors; ``ret``
and ``discount`` are [B, 1]); an algorithm adds its own (``act``'s second value)."""


class LoopSettings(Protocol):
    """The loop's budget in a learner's settings (``SACConfig``, ``TD3Config``)."""

    @property
    def random_steps(self) -> int:
        """Env steps of random actions before learning starts."""
        ...

    @property
    def batch_size(self) -> int:
        """Decisions per gradient step."""
        ...

    @property
    def updates_per_step(self) -> float:
        """Gradient steps per executed env step."""
        ...


class ReplaySettings(LoopSettings, Protocol):
    """The loop's budget and the replay's size in a learner's settings (``SACConfig``,
    ``TD3Config``: :func:`check_learning_budget`)."""

    @property
    def buffer_size(self) -> int:
        """Replay capacity in env steps (decisions x k)."""
        ...


def replay_decisions(buffer_size: int, k: int) -> int:
    """The decisions a replay of ``buffer_size`` env steps keeps: ceil(buffer_size / k)."""
    return -(-buffer_size // k)


def check_learning_budget(cfg: TrainConfig, section: str) -> None:
    """Refuse (ValueError naming the argument) a run of a learner on the decision replay (the
    SAC family, TD3) that can take no gradient step: a replay smaller than one batch, a budget
    that ends before the random steps and the first batch are in, or one in which
    ``updates_per_step`` never adds up to one gradient step. ``section``: the learner's
    settings section (``cfg.sac``: ``"sac"``; its options ``--sac-*``)."""
    s: ReplaySettings = getattr(cfg, section)
    opt = f"--{SETTINGS[section].flag_prefix}"
    k, E = cfg.k, cfg.num_envs
    capacity = replay_decisions(s.buffer_size, k)
    first = first_learning_decision(s.random_steps, s.batch_size, capacity, k, E)
    if first is None:
        raise ValueError(
            f"{section}.buffer_size: expected at least batch_size x k = {s.batch_size * k} env "
            f"steps (the replay keeps {capacity} decision(s) of k={k}; a gradient step samples "
            f"{s.batch_size}), got {s.buffer_size} (use a larger {opt}-buffer-size or a smaller "
            f"{opt}-batch-size)"
        )
    rounds = cfg.num_updates * cfg.decisions_per_env
    if first >= rounds:
        need = (first + 1) * E * k
        raise ValueError(
            f"steps: --algo {cfg.algo} takes its first gradient step after {need:,} env steps "
            f"({section}.random_steps={s.random_steps:,} random env steps, then a batch of "
            f"{section}.batch_size={s.batch_size} decisions from num_envs={E} envs), but the run "
            f"trains {rounds * E * k:,} (use more --steps, or fewer {opt}-random-steps / a "
            f"smaller {opt}-batch-size)"
        )
    if s.updates_per_step * (rounds - first) * E * k < 1.0:
        raise ValueError(
            f"{section}.updates_per_step: expected at least one gradient step in the run's "
            f"{(rounds - first) * E * k:,} learning env steps, got {s.updates_per_step!r}"
        )


@dataclass(frozen=True)
class LoopBudget:
    """The loop's budget (:class:`LoopSettings`) for a learner whose settings name it
    otherwise (Dyn-E: no random steps of the loop's own)."""

    random_steps: int
    batch_size: int
    updates_per_step: float


@dataclass(frozen=True)
class Decision:
    """One decision of every env, as the loop hands it to ``store`` (E envs)."""

    obs: np.ndarray
    """The observations the algorithm acted on [E, O] (float32, through ``obs_norm``)."""
    y0: np.ndarray
    """The robot state at the decision's start [E, D] (float64, the loop's ``frame``)."""
    dy0: np.ndarray
    """Its velocity [E, D]."""
    columns: dict[str, np.ndarray]
    """The algorithm's replay columns (``act``'s second value)."""
    sub_rewards: np.ndarray
    """The k sub-rewards [E, k] (0 after an episode's end)."""
    mask: np.ndarray
    """The executed sub-steps [E, k] (1 / 0)."""
    terminated: np.ndarray
    """Episodes that terminated inside the decision [E] (bool; a truncation is not one)."""
    next_obs: np.ndarray
    """The observations after the decision [E, O] (float32, through ``obs_norm``; the final
    one where an episode ended)."""
    next_y0: np.ndarray
    """The robot state after the decision [E, D] (the finished episode's where one ended)."""
    next_dy0: np.ndarray
    """Its velocity [E, D]."""


class OffPolicyAlgorithm(Protocol):
    """The algorithm-specific part of an off-policy learner (what :class:`OffPolicyLearner`
    calls)."""

    def act(
        self, obs: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor, explore: bool
    ) -> tuple[torch.Tensor, dict[str, np.ndarray]]:
        """One decision of every env from obs [E, O], y0 / dy0 [E, D] (no gradient):
        ``explore`` False means the random steps (act uniformly at random; an algorithm with
        phases of its own, Dyn-E, decides itself). Returns the actions [E, k, A] (float32)
        inside the task's bounds and the algorithm's replay columns ({name: [E, w]})."""
        ...

    def gradient_step(self, batch: dict[str, torch.Tensor]) -> dict[str, float]:
        """One gradient step on a replay batch; returns the values to average into the row
        ({name: value}; a name missing from a step is not averaged for it)."""
        ...

    def algorithm_metrics(self, losses: dict[str, list[float]]) -> dict[str, float]:
        """The row's algorithm columns (``losses/*``, ``charts/learning_rate``, its own) from
        the iteration's gradient-step values."""
        ...

    def store(self, d: Decision) -> None:
        """Insert one decision of every env into the replay (:class:`OffPolicyLearner`'s:
        the chunk return and bootstrap weight with the loop's and the algorithm's columns)."""
        ...

    def end_iteration(self) -> None:
        """Work after an iteration's decisions, timed as update time (none by default)."""
        ...

    def evaluate(self, before: int, last: bool) -> dict[str, float]:
        """The periodic evaluation's columns of the row (the evaluator's by default)."""
        ...


class OffPolicyLearner(OffPolicyState, CountsUpdates):
    """The collection loop of an off-policy learner over decisions of k env steps (see the
    module docstring). A subclass calls :meth:`_open_loop` (envs) before building its
    networks, then :meth:`_open_replay` (replay, evaluator, generator; or
    :meth:`_open_collection` with its own replay), and implements
    :class:`OffPolicyAlgorithm`, and names its checkpoint's parts
    (:class:`ndp.rl.offpolicy.state.OffPolicyState`).

    Every off-policy learner here is an actor-critic: the actor is the run's
    :class:`ndp.policies.ActorCritic` (``model``, built by :meth:`_open_loop`), with twin
    critics and their target (:meth:`_open_critics`; a TD3-style learner also keeps the
    actor's target), an actor and a critic optimiser (``actor_opt``, ``critic_opt``); the
    checkpoint's parts, the finite check and the row's shared columns follow from them.

    Attributes set by the loop: ``cfg``, ``spec``, ``session``, ``run``, ``k``, ``E``, ``T``,
    ``gamma``, ``envs``, ``obs_dim``, ``model``, ``replay``, ``obs_norm`` (what the observations
    pass through before ``act`` and the replay; by default disabled: they enter unnormalised),
    ``evaluator``, ``low`` / ``high`` [A] (action bounds),
    ``rng`` (numpy, seeded with the run's seed: random actions and replay batches), ``frame``,
    ``update``, ``global_step``, ``grad_steps``, ``update_debt``.
    """

    own_columns: tuple[str, ...] = ()
    """The learner's own ``metrics.csv`` columns, after :data:`ndp.rl.logger.METRICS`."""
    random_steps: int
    batch_size: int
    updates_per_step: float
    critic: nn.Module
    critic_target: nn.Module
    actor_target: nn.Module | None = None
    """The actor's target (TD3 and Dyn-E), or None (the SAC family keeps none)."""
    actor_opt: torch.optim.Optimizer
    critic_opt: torch.optim.Optimizer
    _critic_params: list[torch.nn.Parameter]

    def _open_loop(self, cfg: TrainConfig, session: RunSession, settings: LoopSettings) -> None:
        """Resolve the task and build the training envs, then the actor (the run's
        ``ActorCritic``, ``model``): the order of the global RNG's draws is every learner's;
        the loop's budget comes from ``settings``."""
        task = rl_envs.resolve_task(cfg.task, **cfg.env_options())
        self.cfg, self.spec, self.session = cfg, task.spec, session
        self.run = session.run
        self.random_steps, self.batch_size = settings.random_steps, settings.batch_size
        self.updates_per_step = settings.updates_per_step
        self.k, self.E, self.T = cfg.k, cfg.num_envs, cfg.decisions_per_env
        self.gamma = float(cfg.gamma)
        self.envs, self.obs_dim = rl_envs.run_envs(cfg, task)
        self.model = build_actor_critic(self.obs_dim, self.spec, cfg.policy)

    def _open_critics(self, critic: nn.Module, actor_target: nn.Module | None = None) -> None:
        """The twin critics ``critic`` (the parameters :meth:`_critics_frozen` freezes), their
        target (a frozen copy) and, given ``actor_target`` (TD3: the actor), its frozen
        copy."""
        self.critic = critic
        self.critic_target = copy.deepcopy(critic).requires_grad_(False)
        if actor_target is not None:
            self.actor_target = copy.deepcopy(actor_target).requires_grad_(False)
        self._critic_params = list(critic.parameters())

    def _open_replay(self, buffer_size: int, dims: dict[str, int]) -> None:
        """The replay (``buffer_size`` env steps: :func:`replay_decisions` decisions; the
        loop's columns plus the algorithm's ``dims``), then the rest of
        :meth:`_open_collection`."""
        D = int(self.spec.dmp_dofs)
        cols = {"obs": self.obs_dim, "next_obs": self.obs_dim, **dims,
                "y0": D, "dy0": D, "next_y0": D, "next_dy0": D}  # fmt: skip
        self._open_collection(DecisionReplay(replay_decisions(buffer_size, self.k), cols))

    def _open_collection(
        self, replay: RingReplay, obs_norm: ObsNormalizer | None = None, frame: str | None = None
    ) -> None:
        """The replay (``replay``: one an algorithm's ``store`` fills), the observation
        statistics (default: disabled, the observations enter unnormalised), the periodic
        evaluator, the action bounds, the generator, the robot state's frame (default: the
        policy's ``dmp_state``) and the counters."""
        self.replay = replay
        if obs_norm is None:
            obs_norm = ObsNormalizer(self.obs_dim, self.cfg.clip_obs, enabled=False)
        self.obs_norm = obs_norm
        self.evaluator = PeriodicEvaluator(self.cfg, self.spec)
        self.low = torch.as_tensor(self.spec.action_low, dtype=torch.float32)
        self.high = torch.as_tensor(self.spec.action_high, dtype=torch.float32)
        self.rng = np.random.default_rng(self.cfg.seed)
        if frame is None:
            frame = self.cfg.policy.dmp_state
        assert frame is not None  # resolve_config fills it from the task's preset
        self.frame: str = frame
        self.update = 0
        self.global_step = 0
        self.grad_steps = 0
        self.update_debt = 0.0
        self._tracker = rl_envs.EpisodeTracker(self.E)
        self._started = False  # the envs are reset at the first iteration, after any restore

    # ----------------------------------------------------------------------- the learner
    @property
    def columns(self) -> tuple[str, ...]:
        """``metrics.csv``'s columns (docs/metrics.md): the RL run's and :attr:`own_columns`."""
        return (*METRICS, *self.own_columns)

    def nonfinite(self) -> str | None:
        """The first actor or critic parameter holding NaN / Inf, else None."""
        return nonfinite_parameter(
            [*self.model.actor.named_parameters(), *self.critic.named_parameters()]
        )

    def parts(self) -> dict[str, Part]:
        """Saved under :attr:`section`: the critics, their target, the actor's target (where
        kept), the two optimisers, then :meth:`extra_parts`."""
        actor = {} if self.actor_target is None else {"actor_target": self.actor_target}
        return {"critic": self.critic, "critic_target": self.critic_target, **actor,
                "actor_opt": self.actor_opt, "critic_opt": self.critic_opt,
                **self.extra_parts()}  # fmt: skip

    def extra_parts(self) -> dict[str, Part]:
        """The learner's own networks and optimisers to save (none by default)."""
        return {}

    def loop_metrics(self, losses: dict[str, list[float]], lr: float) -> dict[str, float]:
        """The row's columns every off-policy learner fills: the learning rate ``lr``, the
        iteration's mean actor and critic losses, and its section's mean Q, replay size and
        gradient steps (``<section>/q``, ``/replay``, ``/gradient_steps``)."""
        return {
            "charts/learning_rate": lr,
            "losses/policy": mean_of(losses, "actor"),
            "losses/value": mean_of(losses, "critic"),
            f"{self.section}/q": mean_of(losses, "q"),
            f"{self.section}/replay": float(self.replay.size),
            f"{self.section}/gradient_steps": float(self.grad_steps),
        }

    # ----------------------------------------------------------------------- the algorithm
    def act(
        self, obs: torch.Tensor, y0: torch.Tensor, dy0: torch.Tensor, explore: bool
    ) -> tuple[torch.Tensor, dict[str, np.ndarray]]:
        """:meth:`OffPolicyAlgorithm.act`."""
        raise NotImplementedError

    def gradient_step(self, batch: dict[str, torch.Tensor]) -> dict[str, float]:
        """:meth:`OffPolicyAlgorithm.gradient_step`."""
        raise NotImplementedError

    def algorithm_metrics(self, losses: dict[str, list[float]]) -> dict[str, float]:
        """:meth:`OffPolicyAlgorithm.algorithm_metrics`."""
        raise NotImplementedError

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
        random steps are done, then :meth:`end_iteration`; returns the iteration's metrics row.

        Raises:
            TrainingDivergedError: NaN / Inf in an action, a loss or a parameter.
        """
        if not self._started:
            self._start()
        t0 = time.perf_counter()
        episodes: list[tuple[float, float, float, float, float]] = []
        losses: dict[str, list[float]] = {}
        executed, t_update = 0, 0.0
        for _ in range(self.T):
            n_exec = self._decide(self.global_step + executed >= self.random_steps, episodes)
            executed += n_exec
            if (
                self.global_step + executed >= self.random_steps
                and self.replay.size >= self.batch_size
            ):
                self.update_debt += self.updates_per_step * n_exec
                t1 = time.perf_counter()
                while self.update_debt >= 1.0:
                    batch = self.replay.sample(self.batch_size, self.rng)
                    for name, value in self.gradient_step(batch).items():
                        losses.setdefault(name, []).append(value)
                    self.grad_steps += 1
                    self.update_debt -= 1.0
                t_update += time.perf_counter() - t1
        t1 = time.perf_counter()
        self.end_iteration()
        t_update += time.perf_counter() - t1
        self.update += 1
        before, self.global_step = self.global_step, self.global_step + executed
        wall = time.perf_counter() - t0
        t_roll = wall - t_update
        row = {
            "update": self.update,
            "global_step": self.global_step,
            **episode_charts(episodes),
            "charts/env_steps_per_s": executed / max(t_roll + t_update, 1e-9),
            "time/rollout_s": t_roll,
            "time/update_s": t_update,
            **self.algorithm_metrics(losses),
        }
        row.update(self.evaluate(before, self.update >= self.cfg.num_updates))
        return row

    def _decide(
        self, acting: bool, episodes: list[tuple[float, float, float, float, float]]
    ) -> int:
        """One decision of every env: act (``acting`` False: the random steps), step the envs,
        hand the :class:`Decision` to :meth:`store`; returns the env steps it executed."""
        E, k = self.E, self.k
        obs = self.obs_norm(self._obs)
        y0 = torch.as_tensor(self._y0, dtype=torch.float32)
        dy0 = torch.as_tensor(self._dy0, dtype=torch.float32)
        with torch.no_grad():
            act, columns = self.act(torch.as_tensor(obs), y0, dy0, acting)
        if not bool(torch.isfinite(act).all()):
            raise self._diverged("non-finite actions (check the observations)")
        nxt, _, term, trunc, infos = self.envs.step(act.numpy())
        term = np.asarray(term, dtype=bool)
        done = term | np.asarray(trunc, dtype=bool)
        sub_r, live, mask = rl_envs.decision_rewards(infos, done, E, k)
        self._tracker.add(infos, done, sub_r, live, mask, episodes)
        nxt = np.asarray(nxt, dtype=np.float64).reshape(E, self.obs_dim)
        final = nxt.copy()
        if done.any() and "final_obs" in infos:
            for i in np.flatnonzero(done):
                final[i] = np.asarray(infos["final_obs"][i], dtype=np.float64).reshape(-1)
        next_y0, next_dy0 = self._next_start(infos, done)
        self.store(Decision(obs, self._y0, self._dy0, columns, sub_r, mask, term,
                            self.obs_norm(final), next_y0, next_dy0))  # fmt: skip
        self._obs = nxt
        self._y0, self._dy0 = rl_envs.decision_start(infos, E, self.frame)
        return int(mask.sum())

    def store(self, d: Decision) -> None:
        """:meth:`OffPolicyAlgorithm.store`: one replay row per env with the chunk return and
        its bootstrap weight (the loop's :data:`REPLAY_COLUMNS` and the algorithm's)."""
        ret, n = chunk_return(torch.as_tensor(d.sub_rewards), torch.as_tensor(d.mask), self.gamma)
        discount = bootstrap_discount(n, torch.as_tensor(d.terminated, dtype=n.dtype), self.gamma)
        self.replay.add(obs=d.obs, y0=d.y0, dy0=d.dy0, **d.columns, ret=ret.numpy(),
                        discount=discount.numpy(), next_obs=d.next_obs, next_y0=d.next_y0,
                        next_dy0=d.next_dy0)  # fmt: skip

    def end_iteration(self) -> None:
        """:meth:`OffPolicyAlgorithm.end_iteration` (nothing by default)."""

    def evaluate(self, before: int, last: bool) -> dict[str, float]:
        """:meth:`OffPolicyAlgorithm.evaluate`: the periodic evaluator's columns when an
        evaluation is due between ``before`` and ``global_step`` (or ``last``)."""
        return self.evaluator.maybe(before, self.global_step, last, self.model, self.obs_norm)

    def _diverged(self, what: str) -> TrainingDivergedError:
        return self.session.diverged(what, self.update)

    @contextlib.contextmanager
    def _critics_frozen(self) -> Iterator[None]:
        """The critics' parameters (``_critic_params``) take no gradient inside the block."""
        for p in self._critic_params:
            p.requires_grad_(False)
        try:
            yield
        finally:
            for p in self._critic_params:
                p.requires_grad_(True)

    def _step(self, opt: torch.optim.Optimizer, loss: torch.Tensor, what: str) -> None:
        """One optimiser step on ``loss`` (the ``what`` loss: its name in the divergence
        message when it is not finite)."""
        if not bool(torch.isfinite(loss)):
            raise self._diverged(f"the {what} loss became {float(loss.detach())}")
        opt.zero_grad(set_to_none=True)
        loss.backward()  # type: ignore[no-untyped-call]  # torch: Tensor.backward is unannotated
        opt.step()


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


def mean_of(losses: dict[str, list[float]], key: str) -> float:
    """The mean of an iteration's values of ``key`` (NaN when no gradient step gave one)."""
    v = losses.get(key, [])
    return float(np.mean(v)) if v else math.nan
