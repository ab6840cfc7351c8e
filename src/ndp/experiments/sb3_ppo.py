"""Stable-Baselines3 PPO on this package's per-step tasks, logged like ``ndp rl train``.

The reference trainer of ``benchmarks/ppo_vs_sb3.py``: SB3's PPO with the supplement's
hyperparameters (those of ``ndp.rl.config.PPOConfig``'s defaults; SB3's own value loss, i.e. no
value clip, advantages normalised per mini-batch) on the same per-step env this package's PPO
trains on (``ndp.envs.make_env``; Meta-World random goals at every reset), ``DummyVecEnv`` +
``VecNormalize`` (observations and returns, clip 10), one torch thread.

Success is counted per env and per episode: a per-env flag is set when ``info["success"]`` is
true at any step of the episode and read when that env's episode ends (a callback that pools
every env's infos into one list miscounts when several envs end at the same step). One row per
rollout goes to ``<run_dir>/metrics.csv`` with the keys ``update``, ``global_step``,
``charts/episodes``, ``charts/success_any``, ``charts/episode_return`` (this package's metric
names, docs/metrics.md), and ``done.json`` is written atomically at the end. The run directory
is made by the run session like every trainer's (:mod:`ndp.runs.session`: refused over another
run, ``config.json`` (:class:`SB3RunConfig`), provenance, ``run.json``). A killed run is
restarted from scratch (SB3 runs are short; nothing partial is reported as finished).

Usage::

    python -m ndp.experiments.sb3_ppo --task push-v3 --steps 150000 --seed 0 --run-dir DIR
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ndp.io import atomic_write_text
from ndp.runs import MetricsLogger
from ndp.runs.session import Manifest, RunSession

FIELDS = (
    "update",
    "global_step",
    "charts/episodes",
    "charts/success_any",
    "charts/episode_return",
    "time/wall_s",
)


class EpisodeCounter:
    """Per-env success-any and return of finished episodes (pure bookkeeping, testable).

    Args:
        num_envs: envs of the vector env.
    """

    def __init__(self, num_envs: int) -> None:
        self.success = np.zeros(num_envs, dtype=bool)
        self.ret = np.zeros(num_envs)
        self.finished: list[tuple[float, float]] = []

    def step(self, rewards: np.ndarray, dones: np.ndarray, infos: list[dict[str, Any]]) -> None:
        """One vector step: rewards [E] (raw, unnormalised), dones [E], infos (one per env)."""
        for i, info in enumerate(infos):
            self.success[i] |= bool(info.get("success", False))
            self.ret[i] += float(rewards[i])
            if dones[i]:
                self.finished.append((float(self.success[i]), float(self.ret[i])))
                self.success[i] = False
                self.ret[i] = 0.0

    def pop(self) -> tuple[int, float, float]:
        """(episodes, mean success-any, mean return) since the last pop (NaN when none)."""
        eps, self.finished = self.finished, []
        if not eps:
            return 0, math.nan, math.nan
        arr = np.array(eps)
        return len(eps), float(arr[:, 0].mean()), float(arr[:, 1].mean())


def make_sb3_ppo(venv: Any, seed: int, num_envs: int) -> Any:
    """SB3 PPO with the supplement's settings (``PPOConfig`` defaults) on a normalised venv."""
    import torch
    from stable_baselines3 import PPO

    from ndp.rl.config import PPOConfig

    p = PPOConfig()
    n_steps = p.steps_per_update // num_envs
    return PPO(
        "MlpPolicy",
        venv,
        learning_rate=p.lr,
        n_steps=n_steps,
        batch_size=n_steps * num_envs // p.minibatches,
        n_epochs=p.epochs,
        gamma=p.gamma,
        gae_lambda=p.gae_lambda,
        clip_range=p.clip,
        ent_coef=p.ent_coef,
        vf_coef=p.vf_coef,
        max_grad_norm=p.max_grad_norm,
        seed=seed,
        device="cpu",
        verbose=0,
        policy_kwargs={
            "net_arch": {"pi": [100, 100], "vf": [100, 100]},
            "activation_fn": torch.nn.Tanh,
            "optimizer_kwargs": {"eps": p.adam_eps},
        },
    )


@dataclass(frozen=True)
class SB3RunConfig:
    """The reference run's settings (its ``config.json``)."""

    task: str
    """The per-step task (``push-v3``)."""
    steps: int
    """Env steps (SB3's ``total_timesteps``)."""
    seed: int = 0
    """Seed of SB3, its envs and torch."""
    num_envs: int = 4
    """Envs of the ``DummyVecEnv``."""
    horizon: int | None = None
    """Episode length in env steps (None: the task's)."""
    run_dir: str = ""
    """Where the run is (never compared on a restart)."""

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SB3RunConfig:
        return cls(**d)


def train_sb3(
    task: str, steps: int, seed: int, run_dir: Path, num_envs: int = 4, horizon: int | None = None
) -> Path:
    """Train SB3 PPO; returns the run directory (see the module docstring)."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from ndp.rl.config import PPOConfig
    from ndp.rl.envs import resolve_task

    torch.set_num_threads(1)
    run_dir = Path(run_dir)
    cfg = SB3RunConfig(task, int(steps), int(seed), int(num_envs), horizon, str(run_dir))
    session, _ = RunSession.open(
        run_dir,
        kind="sb3",
        config=cfg,
        config_from_dict=SB3RunConfig.from_dict,
        safe_on_resume=(),
        resume=False,
        resumable=False,
    )

    def manifest(done: int) -> Manifest:
        end = done >= steps
        return Manifest(kind="sb3", task=task, label="sb3-ppo", seed=int(seed),
                        budget=int(steps), unit="env_steps", done=int(done), finished=end,
                        reason="budget" if end else "")  # fmt: skip

    session.start(dataclasses.asdict(cfg), manifest(0))
    p = PPOConfig()
    h = resolve_task(task)
    raw_venv = DummyVecEnv([lambda: h.make(horizon=horizon) for _ in range(num_envs)])
    raw_venv.seed(seed)
    venv = VecNormalize(raw_venv, gamma=p.gamma, clip_obs=p.clip_obs, clip_reward=p.clip_reward)
    model = make_sb3_ppo(venv, seed, num_envs)
    counter = EpisodeCounter(num_envs)
    log = MetricsLogger(run_dir, FIELDS, step="global_step", tensorboard=False)
    t0 = time.perf_counter()

    class _Log(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.update = 0

        def _on_step(self) -> bool:
            norm = self.training_env
            assert isinstance(norm, VecNormalize)  # the model's env is the venv above
            raw = norm.get_original_reward()  # unnormalised rewards
            counter.step(raw, self.locals["dones"], self.locals["infos"])
            return True

        def _on_rollout_end(self) -> None:
            self.update += 1
            n, succ, ret = counter.pop()
            log.log(
                {
                    "update": self.update,
                    "global_step": self.num_timesteps,
                    "charts/episodes": n,
                    "charts/success_any": succ,
                    "charts/episode_return": ret,
                    "time/wall_s": time.perf_counter() - t0,
                }
            )

    try:
        model.learn(total_timesteps=steps, callback=_Log())
    finally:
        log.close()
        venv.close()
    atomic_write_text(
        run_dir / "done.json",
        json.dumps(
            {
                "task": task,
                "steps": steps,
                "seed": seed,
                "num_envs": num_envs,
                "global_step": int(model.num_timesteps),
                "wall_s": time.perf_counter() - t0,
            }
        )
        + "\n",
    )
    session.finish(manifest(int(model.num_timesteps)))
    return run_dir


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--task", required=True)
    ap.add_argument("--steps", type=int, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--num-envs", type=int, default=4)
    ap.add_argument("--run-dir", type=Path, required=True)
    a = ap.parse_args(argv)
    train_sb3(a.task, a.steps, a.seed, a.run_dir, a.num_envs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
