"""Behaviour cloning of NDP and of a plain network on recorded demonstrations.

For every recorded step t, the policy sees the observation (and, for NDP, the robot state the
DMP starts from) and predicts the k actions the expert took at t..t+k-1; the loss is the mean
squared error between the policy's mean sub-actions [k, A] and those actions, over the sub-steps
that stay inside the episode. The loss is on the actions, not on trajectory points, because the
actions are what both policies output and what the executed behaviour depends on (for NDP the
DMP rollout passes through the task's inverse controller, so the gradient reaches the goal and
forcing weights through the same map RL uses).

The run directory is an RL run at update 0 (``config.json`` = the RL ``TrainConfig`` of the
method, ``checkpoint.pt`` with the policy, the observation statistics of the demonstrations and
a fresh PPO state), plus ``bc.json`` and ``bc_metrics.csv``. So ``ndp rl eval / render /
export`` and ``ndp.load_policy`` use it as they are, and ``ndp rl train --resume RUN --steps N``
fine-tunes the cloned policy with PPO.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import json
import math
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np

from ndp.checks import check_int, plain_numbers
from ndp.policies.config import PolicyConfig
from ndp.runs.cli import cli
from ndp.runs.driver import run
from ndp.runs.session import LearnerDefaults

if TYPE_CHECKING:
    import torch

    from ndp.bc.demos import Demos
    from ndp.envs.spec import TaskSpec
    from ndp.policies import ActorCritic
    from ndp.rl.config import TrainConfig
    from ndp.rl.normalize import ObsNormalizer
    from ndp.runs.session import Manifest, RunSession

BC_MODELS = {"ndp": "ndp", "nn": "ppo-multi", "nn-step": "ppo"}
"""BC model -> the RL method whose actor it trains."""

BC_METRICS = ("epoch", "train/loss", "val/loss", "time/epoch_s")
"""Columns of ``bc_metrics.csv`` (one row per epoch; MSE of the actions, in action units^2)."""


@dataclass(frozen=True)
class BCConfig:
    """``ndp il bc``: clone a demonstrator into an NDP or plain-network policy."""

    demos: Annotated[str, cli(aliases=("--data",))] = ""
    """Demonstrations file (.npz from ``ndp il collect``, or your own in that format)."""
    model: str = "ndp"
    """'ndp' (DMP head through the task's inverse controller), 'nn' (k raw actions per
    decision, the PPO-multi actor) or 'nn-step' (one action per env step, the PPO actor)."""
    run_dir: Annotated[str, cli(aliases=("--out",))] = "runs/bc"
    """Run directory (refused if it holds a run, unless --overwrite)."""
    episodes: int = 0
    """Use the first this many demonstrated episodes (0: all)."""
    epochs: int = 100
    """Passes over the demonstrations."""
    batch_size: int = 256
    """Samples (recorded steps) per Adam step."""
    lr: float = 1e-3
    """Adam learning rate."""
    val_fraction: float = 0.1
    """Fraction of the episodes held out for the validation loss (0: none)."""
    obs_std_floor: float = 0.01
    """Smallest per-feature std of the observation normalisation (observation units: m, rad,
    m/s). A feature that barely varies over the demonstrations (a joint the expert never moves)
    would otherwise be divided by a tiny std, so that physically negligible closed-loop deviations
    reach the network as inputs many std out of the training range (0: no floor)."""
    seed: int = 0
    """Seed of initialisation, split and batch order."""
    threads: int = 1
    """torch CPU threads."""
    progress: bool = True
    """Show a progress bar."""
    tensorboard: bool = True
    """Write TensorBoard events (under RUN/tb_bc) besides the CSV."""
    policy: PolicyConfig = field(default_factory=PolicyConfig)
    """Network and head settings, as for RL (the head follows the model)."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        if self.model not in BC_MODELS:
            raise ValueError(f"model: expected one of {', '.join(BC_MODELS)}, got {self.model!r}")
        for name, low in (("episodes", 0), ("epochs", 1), ("batch_size", 1), ("threads", 1),
                          ("seed", 0)):  # fmt: skip
            v = getattr(self, name)
            check_int(name, v, low)
        if not (isinstance(self.lr, (int, float)) and math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr: expected a finite number > 0, got {self.lr!r}")
        floor = self.obs_std_floor
        if not (isinstance(floor, (int, float)) and math.isfinite(floor) and floor >= 0):
            raise ValueError(f"obs_std_floor: expected a finite number >= 0, got {floor!r}")
        if not 0.0 <= self.val_fraction < 1.0:
            raise ValueError(
                f"val_fraction: expected a number in [0, 1), got {self.val_fraction!r}"
            )
        if self.policy.ndp.param_noise:
            raise ValueError("param_noise: behaviour cloning trains the mean; not supported")

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _windows(episode: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices [S, k] of the k steps from each step and their mask (same episode) [S, k]."""
    s = len(episode)
    idx = np.minimum(np.arange(s)[:, None] + np.arange(k)[None, :], s - 1)
    mask = episode[idx] == episode[:, None]
    return idx, mask


class CloningLearner(LearnerDefaults):
    """Behaviour cloning, an epoch per :meth:`iterate` (an :class:`ndp.runs.session.Learner`):
    Adam on the mean squared error of the policy's mean sub-actions against the demonstrated
    ones (the actor only: not the critic, not the exploration std).

    Tensors (S recorded steps, k sub-steps, A actions, O observations, D DMP DoF): ``obs``
    [S, O] normalised, ``y0`` / ``dy0`` [S, D], ``target`` [S, k, A], ``mask`` [S, k, 1] (the
    sub-steps inside the episode), ``train_idx`` / ``val_idx`` the steps of each split.
    """

    def __init__(self, model: ActorCritic, session: RunSession, *, obs: torch.Tensor,
                 y0: torch.Tensor, dy0: torch.Tensor, target: torch.Tensor, mask: torch.Tensor,
                 train_idx: torch.Tensor, val_idx: torch.Tensor, cfg: BCConfig,
                 rl_cfg: TrainConfig, obs_norm: ObsNormalizer,
                 meta: dict[str, Any]) -> None:  # fmt: skip
        import torch

        self.model, self.session, self.cfg = model, session, cfg
        self.rl_cfg, self.obs_norm, self.meta = rl_cfg, obs_norm, meta
        self.obs, self.y0, self.dy0, self.target, self.mask = obs, y0, dy0, target, mask
        self.train_idx, self.val_idx = train_idx, val_idx
        params = [q for name, q in model.named_parameters()
                  if not name.startswith("critic") and not name.endswith("log_std")]  # fmt: skip
        self.opt = torch.optim.Adam(params, lr=cfg.lr)
        self.gen = torch.Generator().manual_seed(cfg.seed)
        self.step = 0

    def loss_of(self, sel: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean squared action error over the selected steps' valid sub-steps, and the
        per-entry squared errors [n, k, A]."""
        dist, _ = self.model.distribution(self.obs[sel], self.y0[sel], self.dy0[sel])
        err = (dist.mean - self.target[sel]) ** 2 * self.mask[sel]
        return err.sum() / (self.mask[sel].sum() * self.target.shape[-1]).clamp(min=1.0), err

    def iterate(self) -> dict[str, float]:
        """One pass over the training steps; returns the epoch's row.

        Raises:
            TrainingDivergedError: the loss became NaN / Inf.
        """
        import torch

        t0 = time.perf_counter()
        tr = self.train_idx
        perm = tr[torch.randperm(len(tr), generator=self.gen)]
        total, seen = 0.0, 0
        for lo in range(0, len(perm), self.cfg.batch_size):
            sel = perm[lo : lo + self.cfg.batch_size]
            loss, _ = self.loss_of(sel)
            if not bool(torch.isfinite(loss)):
                raise self.session.diverged(
                    f"the cloning loss became {float(loss.detach())}", self.step
                )
            self.opt.zero_grad(set_to_none=True)
            loss.backward()  # type: ignore[no-untyped-call]  # torch: Tensor.backward is unannotated
            self.opt.step()
            total += float(loss.detach()) * len(sel)
            seen += len(sel)
        with torch.no_grad():
            val = float(self.loss_of(self.val_idx)[0]) if len(self.val_idx) else math.nan
        self.step += 1
        if self.step >= self.cfg.epochs:  # the fit is done: its error is the exploration std
            self.set_exploration_std()
        return {"epoch": self.step, "train/loss": total / max(seen, 1), "val/loss": val,
                "time/epoch_s": time.perf_counter() - t0}  # fmt: skip

    def set_exploration_std(self) -> None:
        """The exploration std for stochastic use and RL fine-tuning: the fit's per-dimension
        error on the training steps (clamped to [0.05, 1])."""
        import torch

        with torch.no_grad():
            _, err = self.loss_of(self.train_idx)
            per_dim = err.sum(dim=(0, 1)) / self.mask[self.train_idx].sum().clamp(min=1.0)
            self.model.head.log_std.copy_(per_dim.sqrt().clamp(0.05, 1.0).log())

    def state_dict(self) -> dict[str, Any]:
        """The cloned policy as an RL run's state at update 0 (what ``ndp rl train --resume``
        fine-tunes with PPO: a fresh optimiser and return statistics), plus ``bc.json``'s
        record. Cloning itself does not resume."""
        import torch

        from ndp.rl.normalize import ReturnNormalizer
        from ndp.rl.onpolicy.trainer import ppo_state
        from ndp.rl.optim import FlatAdam

        p = self.rl_cfg.ppo
        with torch.no_grad():
            model = copy.deepcopy(self.model)
        state = ppo_state(
            self.model,
            FlatAdam(model, lr=p.lr, eps=p.adam_eps),
            self.obs_norm,
            ReturnNormalizer(self.rl_cfg.num_envs, self.rl_cfg.gamma, p.clip_reward, p.norm_return),
            update=0,
            global_step=0,
            obs_dim=int(self.obs.shape[1]),
        )
        return {**state, "bc": self.meta}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """The policy of :meth:`state_dict` (its weights and observation statistics)."""
        self.model.load_state_dict(state["model"])
        self.obs_norm.load_state_dict(state["obs_norm"])

    def nonfinite(self) -> str | None:
        from ndp.runs.session import nonfinite_parameter

        return nonfinite_parameter(self.model.named_parameters())

    def close(self) -> None:
        pass


def bc_manifest(cfg: BCConfig, task: str, epoch: int) -> Manifest:
    """The :class:`ndp.runs.session.Manifest` of a cloning run at ``epoch``."""
    from ndp.runs.session import Manifest

    finished = epoch >= cfg.epochs
    return Manifest(kind="bc", task=task, label=cfg.model, seed=int(cfg.seed),
                    budget=int(cfg.epochs), unit="epochs", done=int(epoch), finished=finished,
                    reason="budget" if finished else "")  # fmt: skip


def train_bc(cfg: BCConfig, overwrite: bool = False) -> dict[str, Any]:
    """Clone the demonstrations of ``cfg.demos``; returns a summary (losses, sizes, paths).

    Raises:
        FileNotFoundError, ValueError: bad demonstrations file or settings (one line).
    """
    from ndp.bc.demos import load_demos
    from ndp.rl.config import TrainConfig, resolve_config
    from ndp.rl.envs import resolve_task

    if not cfg.demos:
        raise ValueError("demos: expected a demonstrations file (--demos FILE)")
    demos = load_demos(cfg.demos)
    if cfg.episodes:
        if cfg.episodes > demos.n_episodes:
            raise ValueError(
                f"episodes: {cfg.demos} holds {demos.n_episodes} episodes, asked {cfg.episodes}"
            )
        demos = demos.first(cfg.episodes)
    task = resolve_task(demos.task)
    spec = task.spec
    horizon = demos.meta.get("horizon")
    rl_cfg = resolve_config(
        TrainConfig(
            task=spec.name,
            algo=BC_MODELS[cfg.model],
            seed=cfg.seed,
            run_dir=cfg.run_dir,
            horizon=None if horizon in (None, spec.horizon) else int(horizon),
            torch_threads=cfg.threads,
            policy=cfg.policy,
        ),
        spec,
    )
    if demos.actions.shape[1] != spec.action_dim:
        raise ValueError(
            f"actions: {cfg.demos} has {demos.actions.shape[1]} action dimensions, task "
            f"{spec.name} has {spec.action_dim}"
        )
    n_val = round(cfg.val_fraction * demos.n_episodes) if demos.n_episodes >= 2 else 0
    if n_val >= demos.n_episodes:
        raise ValueError(
            f"val_fraction: {cfg.val_fraction} of {demos.n_episodes} demonstration episodes "
            "leaves none for training; give a smaller --val-fraction or more episodes"
        )
    if cfg.val_fraction > 0 and n_val == 0:
        print(
            f"ndp: bc: --val-fraction {cfg.val_fraction} of {demos.n_episodes} demonstration "
            "episode(s) rounds to no validation episode: val/loss is not measured (empty in "
            "metrics.csv, null in the summary); give more episodes for a validation split",
            file=sys.stderr,
        )
    recipe = CloningRecipe(cfg, demos, spec, rl_cfg)
    return run(recipe, overwrite=overwrite)


class CloningRecipe:
    """The run driver's recipe of a cloning run (:mod:`ndp.runs.driver`): the run is an RL run
    at update 0 (kind ``rl``, ``config.json`` the RL config), counted in epochs, not
    resumable, with one checkpoint at the end: the cloned policy as the RL checkpoint that
    ``ndp rl train --resume`` fine-tunes (:meth:`CloningLearner.state_dict`)."""

    def __init__(self, cfg: BCConfig, demos: Demos, spec: TaskSpec, rl_cfg: TrainConfig) -> None:
        from ndp.runs.driver import RunPlan

        self.cfg, self.demos, self.spec, self.rl_cfg = cfg, demos, spec, rl_cfg
        self.plan = RunPlan.of_config(
            rl_cfg,
            rl_cfg.to_dict(),
            cfg.epochs,
            run_dir=cfg.run_dir,
            seed=cfg.seed,
            kind="rl",  # the run is an RL run at update 0 (see the module docstring)
            unit="epoch",
            threads=int(cfg.threads),
            hint="Try a lower --lr.",
            resumable=False,  # ndp il bc has no --resume
        )
        self.meta = {"bc": cfg.to_dict(), "demos": str(cfg.demos), "episodes": demos.n_episodes,
                     "steps": len(demos.obs), "demos_meta": demos.meta}  # fmt: skip
        self.t_run = time.perf_counter()

    def check_checkpoint(self, ckpt: dict[str, Any]) -> None:
        pass  # never resumed

    def build(self, session: RunSession, fresh: bool) -> CloningLearner:
        import torch

        from ndp.io import atomic_write_text
        from ndp.policies import build_actor_critic
        from ndp.rl.normalize import ObsNormalizer

        cfg, demos, spec, rl_cfg = self.cfg, self.demos, self.spec, self.rl_cfg
        atomic_write_text(
            session.run.path / "bc.json", json.dumps(self.meta, indent=2, default=str) + "\n"
        )
        obs_dim = demos.obs.shape[1]
        model = build_actor_critic(obs_dim, spec, rl_cfg.policy)
        k = rl_cfg.k
        obs_norm = ObsNormalizer(obs_dim, rl_cfg.clip_obs, rl_cfg.norm_obs)
        obs_norm.rms.update(demos.obs)
        obs_norm.rms.var = np.maximum(obs_norm.rms.var, cfg.obs_std_floor**2)
        commanded = rl_cfg.policy.dmp_state == "commanded"
        idx, mask = _windows(demos.episode, k)
        rng = np.random.default_rng(cfg.seed)
        n_ep = demos.n_episodes
        n_val = round(cfg.val_fraction * n_ep) if n_ep >= 2 else 0
        val_eps = set(rng.choice(n_ep, size=n_val, replace=False).tolist()) if n_val else set()
        is_val = np.isin(demos.episode, list(val_eps))
        return CloningLearner(
            model,
            session,
            obs=torch.from_numpy(obs_norm(demos.obs)),
            y0=torch.as_tensor(
                demos.cmd_pos if commanded else demos.robot_pos, dtype=torch.float32
            ),
            dy0=torch.as_tensor(
                demos.cmd_vel if commanded else demos.robot_vel, dtype=torch.float32
            ),
            target=torch.as_tensor(demos.actions[idx], dtype=torch.float32),  # [S, k, A]
            mask=torch.as_tensor(mask, dtype=torch.float32).unsqueeze(-1),  # [S, k, 1]
            train_idx=torch.as_tensor(np.flatnonzero(~is_val)),
            val_idx=torch.as_tensor(np.flatnonzero(is_val)),
            cfg=cfg,
            rl_cfg=rl_cfg,
            obs_norm=obs_norm,
            meta=self.meta,
        )

    def manifest(self, learner: CloningLearner) -> Manifest:
        return bc_manifest(self.cfg, self.spec.name, learner.step)

    @contextlib.contextmanager
    def log(
        self, learner: CloningLearner, session: RunSession
    ) -> Iterator[Callable[[dict[str, float]], None]]:
        from tqdm import tqdm

        from ndp.runs import MetricsLogger

        cfg = self.cfg
        bar = tqdm(total=cfg.epochs, disable=not cfg.progress,
                   desc=f"bc {cfg.model} {self.spec.name}")  # fmt: skip
        self.t_run = time.perf_counter()
        with MetricsLogger(session.run.path, BC_METRICS, step="epoch",
                           tensorboard=cfg.tensorboard, filename="bc_metrics.csv",
                           tb_dir="tb_bc") as metrics:  # fmt: skip

            def log_row(row: dict[str, float]) -> None:
                metrics.log(row)
                bar.update(1)
                bar.set_postfix(loss=f"{row['train/loss']:.4f}")

            try:
                yield log_row
            finally:
                bar.close()

    def checkpoint_due(self, learner: CloningLearner) -> bool:
        return learner.step >= self.cfg.epochs  # one checkpoint, at the end

    def summary(
        self, learner: CloningLearner, last: dict[str, float], session: RunSession
    ) -> dict[str, Any]:
        return {
            "run_dir": str(session.run.path),
            "algo": self.rl_cfg.algo,
            "episodes": self.demos.n_episodes,
            "train_steps": len(learner.train_idx),
            "val_steps": len(learner.val_idx),
            "final": {**last, "val/loss": None if not len(learner.val_idx) else last["val/loss"]},
            "train_wall_s": time.perf_counter() - self.t_run,
        }
