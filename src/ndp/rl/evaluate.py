"""Evaluate a trained run (success over N episodes) and render it to mp4."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ndp.rl.envs import FrameRecorder, resolve_task
from ndp.rl.policy import Policy, load_policy

__all__ = ["Policy", "evaluate", "evaluate_policy", "load_policy", "render"]


def _episode(pol: Policy, env: Any, seed: int, deterministic: bool) -> dict[str, float]:
    obs, info = env.reset(seed=seed)
    pol.reset()
    ret, length = 0.0, 0
    while True:
        obs, r, term, trunc, info = env.step(pol.act(obs, info, deterministic))
        ret += float(r)
        length += int(info["n_substeps"])
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
    exec_k: int | None = None,
) -> dict[str, Any]:
    """Success of a trained policy over ``episodes`` fresh episodes.

    Args:
        run_dir: a training run directory.
        episodes: number of episodes (seeds ``seed .. seed + episodes - 1``).
        deterministic: act with the distribution's mode (else sample).
        seed: first episode seed (distinct from training's seeds by default).
        exec_k: K2 sub-steps per decision at a proportionally shorter env step
            (``Policy.at_exec_k``, :mod:`ndp.rl.exec_k`); None: the trained k.

    Returns:
        ``{"episodes", "deterministic", "success_any", "success_final", "episode_return",
        "episode_length", "episode_seconds", "exec_k", "m"}`` (means over episodes; the length
        in env steps of the env that ran, ``episode_seconds`` = length * its env step). Success
        compares across ``exec_k``; the return does not (m times as many env-step rewards are
        summed at m = exec_k / k).
    """
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: expected an integer >= 1, got {episodes!r}")
    pol = load_policy(run_dir)
    if exec_k is not None:
        pol = pol.at_exec_k(exec_k)
    return evaluate_policy(pol, episodes, deterministic, seed)


def evaluate_policy(
    pol: Policy, episodes: int = 10, deterministic: bool = True, seed: int = 10_000
) -> dict[str, Any]:
    """:func:`evaluate` of a loaded policy (or its ``at_exec_k`` copy) in ``pol.make_env()``."""
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes: expected an integer >= 1, got {episodes!r}")
    env = pol.make_env()
    try:
        rows = [_episode(pol, env, seed + i, deterministic) for i in range(episodes)]
    finally:
        env.close()
    out: dict[str, Any] = {"episodes": episodes, "deterministic": deterministic}
    for key in rows[0]:
        out[key] = float(np.mean([r[key] for r in rows]))
    out["episode_seconds"] = out["episode_length"] * float(pol.spec.control_dt)
    out["exec_k"] = pol.exec_k
    out["m"] = pol.substeps
    return out


def _record(
    run_dir: str | Path, episodes: int, deterministic: bool, seed: int
) -> tuple[list[np.ndarray], list[dict[str, Any]], Any]:
    """Frames (every env step) and episode rows of a run's policy, and the policy."""
    from ndp.envs.chunked import ChunkedEnv

    pol = load_policy(run_dir)
    cfg = pol.cfg
    base = resolve_task(cfg.task).make(horizon=cfg.horizon, render_mode="rgb_array")
    rec = FrameRecorder(base)
    env = ChunkedEnv(rec, cfg.k, stale_world=cfg.stale_world)
    try:
        rows = [_episode(pol, env, seed + i, deterministic) for i in range(episodes)]
    finally:
        env.close()
    return rec.frames, rows, pol


def side_by_side(a: list[np.ndarray], b: list[np.ndarray]) -> list[np.ndarray]:
    """Frames of two videos next to each other (the shorter one holds its last frame)."""
    n = max(len(a), len(b))
    out = []
    for i in range(n):
        fa, fb = a[min(i, len(a) - 1)], b[min(i, len(b) - 1)]
        h = max(fa.shape[0], fb.shape[0])
        fa, fb = (np.pad(f, ((0, h - f.shape[0]), (0, 0), (0, 0))) for f in (fa, fb))
        out.append(np.concatenate([fa, np.full((h, 4, 3), 255, np.uint8), fb], axis=1))
    return out


def render(
    run_dir: str | Path,
    out: str | Path | None = None,
    episodes: int = 1,
    deterministic: bool = True,
    seed: int = 10_000,
    compare: str | Path | None = None,
) -> dict[str, Any]:
    """Render ``episodes`` episodes of a trained policy to one mp4 (every env step is a frame).

    Args:
        run_dir: a training run directory.
        out: mp4 path (default ``run_dir/video.mp4``).
        episodes: episodes to record back to back.
        deterministic: act with the mode.
        seed: first episode seed.
        compare: a second run of the same task, rendered on the same seeds to the right of the
            first (e.g. NDP vs PPO-multi, the supplement's videos).

    Returns:
        ``{"path", "frames", "success_any", ...}`` (``success_any_compare`` with ``compare``).
    """
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    from ndp.envs.render import check_output_path, write_mp4

    target = Path(out) if out is not None else Path(run_dir) / "video.mp4"
    check_output_path(target)  # before rendering anything
    frames, rows, pol = _record(run_dir, episodes, deterministic, seed)
    result: dict[str, Any] = {}
    if compare is not None:
        other = load_policy(compare)
        if other.cfg.task != pol.cfg.task:
            raise ValueError(
                f"compare: {compare} is a {other.cfg.task} run, {run_dir} a {pol.cfg.task} run"
            )
        frames_b, rows_b, _ = _record(compare, episodes, deterministic, seed)
        frames = side_by_side(frames, frames_b)
        result["success_any_compare"] = float(np.mean([r["success_any"] for r in rows_b]))
    fps = max(1, min(60, round(1.0 / float(pol.spec.control_dt))))
    write_mp4(frames, target, fps=fps)
    return {
        "path": str(target),
        "frames": len(frames),
        "success_any": float(np.mean([r["success_any"] for r in rows])),
        **result,
    }
