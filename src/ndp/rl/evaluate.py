"""Evaluate a trained run (success over N episodes) and render it to mp4."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ndp.policies import ActorCritic, build_actor_critic
from ndp.rl.checkpoint import CHECKPOINT_NAME, load_checkpoint
from ndp.rl.config import TrainConfig, load_config
from ndp.rl.envs import FrameRecorder, resolve_task
from ndp.rl.normalize import ObsNormalizer


@dataclass
class LoadedPolicy:
    """A trained actor-critic with its observation normaliser and task."""

    cfg: TrainConfig
    """The run's resolved config."""
    spec: Any
    """The task spec."""
    model: ActorCritic
    """The actor-critic (eval mode)."""
    obs_norm: ObsNormalizer
    """The observation normaliser (statistics frozen)."""
    make_env: Any
    """Per-step env factory of the task."""

    def act(
        self, obs: np.ndarray, y0: np.ndarray, dy0: np.ndarray, deterministic: bool = True
    ) -> np.ndarray:
        """Sub-actions [E, k, A] (clipped to the task's bounds) for obs [E, O], y0 / dy0 [E, D]."""
        o = torch.from_numpy(self.obs_norm(np.asarray(obs).reshape(len(y0), -1)))
        with torch.no_grad():
            dist, _ = self.model.distribution(
                o,
                torch.as_tensor(y0, dtype=torch.float32),
                torch.as_tensor(dy0, dtype=torch.float32),
            )
            z = dist.mode() if deterministic else dist.sample()
            act = dist.actions(z)
        low = torch.as_tensor(self.spec.action_low, dtype=torch.float32)
        high = torch.as_tensor(self.spec.action_high, dtype=torch.float32)
        return torch.maximum(torch.minimum(act, high), low).numpy()


def load_policy(run_dir: str | Path) -> LoadedPolicy:
    """Load ``run_dir``'s config and latest checkpoint.

    Raises:
        FileNotFoundError: no config or checkpoint in ``run_dir``.
    """
    run_dir = Path(run_dir)
    cfg = load_config(run_dir / "config.json")
    ckpt = load_checkpoint(run_dir / CHECKPOINT_NAME)
    task = resolve_task(cfg.task)
    model = build_actor_critic(int(ckpt["obs_dim"]), task.spec, cfg.policy)
    model.load_state_dict(ckpt["model"])
    model.eval()
    obs_norm = ObsNormalizer(int(ckpt["obs_dim"]), cfg.ppo.clip_obs, cfg.ppo.norm_obs)
    obs_norm.load_state_dict(ckpt["obs_norm"])
    return LoadedPolicy(cfg, task.spec, model, obs_norm, task.make)


def _episode(pol: LoadedPolicy, env: Any, seed: int, deterministic: bool) -> dict[str, float]:
    obs, info = env.reset(seed=seed)
    key = "cmd" if pol.cfg.policy.dmp_state == "commanded" else "dmp"
    y0, dy0 = info[f"{key}_y0"], info[f"{key}_dy0"]
    ret, length = 0.0, 0
    while True:
        act = pol.act(obs[None], y0[None], dy0[None], deterministic)[0]
        obs, r, term, trunc, info = env.step(act)
        ret += float(r)
        length += int(info["n_substeps"])
        y0, dy0 = info[f"{key}_y0"], info[f"{key}_dy0"]
        if term or trunc:
            return {
                "success_any": float(info["success_any"]),
                "success_final": float(info["success"]),
                "episode_return": ret,
                "episode_length": float(length),
            }


def evaluate(
    run_dir: str | Path,
    episodes: int = 10,
    deterministic: bool = True,
    seed: int = 10_000,
) -> dict[str, Any]:
    """Success of a trained policy over ``episodes`` fresh episodes.

    Args:
        run_dir: a training run directory.
        episodes: number of episodes (seeds ``seed .. seed + episodes - 1``).
        deterministic: act with the distribution's mode (else sample).
        seed: first episode seed (distinct from training's seeds by default).

    Returns:
        ``{"episodes", "deterministic", "success_any", "success_final", "episode_return",
        "episode_length"}`` (means over episodes).
    """
    from ndp.envs.chunked import ChunkedEnv

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: expected an integer >= 1, got {episodes!r}")
    pol = load_policy(run_dir)
    cfg = pol.cfg
    env = ChunkedEnv(pol.make_env(horizon=cfg.horizon), cfg.k, stale_world=cfg.stale_world)
    try:
        rows = [_episode(pol, env, seed + i, deterministic) for i in range(episodes)]
    finally:
        env.close()
    out: dict[str, Any] = {"episodes": episodes, "deterministic": deterministic}
    for key in rows[0]:
        out[key] = float(np.mean([r[key] for r in rows]))
    return out


def render(
    run_dir: str | Path,
    out: str | Path | None = None,
    episodes: int = 1,
    deterministic: bool = True,
    seed: int = 10_000,
) -> dict[str, Any]:
    """Render ``episodes`` episodes of a trained policy to one mp4 (every env step is a frame).

    Args:
        run_dir: a training run directory.
        out: mp4 path (default ``run_dir/video.mp4``).
        episodes: episodes to record back to back.
        deterministic: act with the mode.
        seed: first episode seed.

    Returns:
        ``{"path", "frames", "success_any", ...}``.
    """
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    from ndp.envs.chunked import ChunkedEnv
    from ndp.envs.render import write_mp4

    pol = load_policy(run_dir)
    cfg = pol.cfg
    rec = FrameRecorder(pol.make_env(horizon=cfg.horizon, render_mode="rgb_array"))
    env = ChunkedEnv(rec, cfg.k, stale_world=cfg.stale_world)
    try:
        rows = [_episode(pol, env, seed + i, deterministic) for i in range(episodes)]
    finally:
        env.close()
    path = Path(out) if out is not None else Path(run_dir) / "video.mp4"
    fps = max(1, min(60, round(1.0 / float(pol.spec.control_dt))))
    write_mp4(rec.frames, path, fps=fps)
    return {
        "path": str(path),
        "frames": len(rec.frames),
        "success_any": float(np.mean([r["success_any"] for r in rows])),
    }
