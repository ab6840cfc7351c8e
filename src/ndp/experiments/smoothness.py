"""Smoothness of executed motions: mean squared jerk and spectral arc length (SPARC).

Both are computed from a path sampled at a fixed step ``dt`` (the executed robot coordinates
at every env step: end-effector position for Meta-World, joint angles for the Jaco tasks).

- **Mean squared jerk** [units^2 / s^6]: the third finite difference of the path divided by
  dt^3, squared, averaged over time and coordinates. Lower is smoother; it depends on the
  amplitude and duration of the motion, so compare it only between methods on the same task.
- **SPARC** (Balasubramanian, Melendez-Calderon, Roby-Brami, Burdet, "On the analysis of
  movement smoothness", J. NeuroEng. Rehabil. 2015): the arc length of the normalised Fourier
  magnitude spectrum of the speed profile, over frequencies up to an adaptive cut-off (the last
  frequency below ``fc`` where the normalised magnitude exceeds ``amp_threshold``), negated.
  Dimensionless and independent of the motion's amplitude and duration; closer to 0 (less
  negative) is smoother.

:func:`rollout_paths` records the executed paths of a trained run (any method) in its own env.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import ndp
from ndp.checks import check_int
from ndp.experiments.report import find_run_dirs, run_info
from ndp.experiments.run_kinds import run_kind
from ndp.io import atomic_write_text
from ndp.rl.config import EVAL_SEED


def mean_squared_jerk(path: np.ndarray, dt: float) -> float:
    """Mean squared jerk of ``path`` [T, D] (or [T]) sampled every ``dt`` seconds (T >= 4).

    Raises:
        ValueError: fewer than 4 samples or a non-positive dt.
    """
    p = np.asarray(path, dtype=np.float64)
    p = p[:, None] if p.ndim == 1 else p
    if p.shape[0] < 4:
        raise ValueError(f"path: expected at least 4 samples, got {p.shape[0]}")
    if not dt > 0:
        raise ValueError(f"dt: expected a number > 0, got {dt!r}")
    jerk = np.diff(p, n=3, axis=0) / dt**3
    return float(np.mean(jerk**2))


def sparc(
    speed: np.ndarray,
    dt: float,
    fc: float = 10.0,
    amp_threshold: float = 0.05,
    pad_level: int = 4,
) -> float:
    """Spectral arc length of a speed profile [T] sampled every ``dt`` seconds.

    Args:
        speed: speed (norm of the velocity) at every sample.
        dt: sampling step (s).
        fc: largest frequency considered (Hz; 10 Hz as in the SPARC paper for human reaching,
            capped at the Nyquist frequency).
        amp_threshold: the adaptive cut-off keeps frequencies up to the last one whose
            normalised magnitude is at least this.
        pad_level: zero padding to 2^(ceil(log2 T) + pad_level) samples.

    Returns:
        SPARC (<= 0; closer to 0 is smoother). 0 for a motionless profile.
    """
    v = np.asarray(speed, dtype=np.float64).reshape(-1)
    if v.size < 2 or not dt > 0:
        raise ValueError(f"speed: expected at least 2 samples and dt > 0, got {v.size}, {dt!r}")
    n = int(2 ** (math.ceil(math.log2(v.size)) + pad_level))
    mag = np.abs(np.fft.rfft(v, n))
    if mag[0] <= 0 or not np.isfinite(mag).all():
        return 0.0
    mag = mag / mag[0]
    freq = np.fft.rfftfreq(n, dt)
    fc = min(fc, 0.5 / dt)
    sel = freq <= fc
    f_sel, m_sel = freq[sel], mag[sel]
    above = np.flatnonzero(m_sel >= amp_threshold)
    last = int(above[-1]) if above.size else 0
    f_sel, m_sel = f_sel[: last + 1], m_sel[: last + 1]
    if f_sel.size < 2:
        return 0.0
    df = np.diff(f_sel) / (f_sel[-1] - f_sel[0])
    dm = np.diff(m_sel)
    return float(-np.sum(np.sqrt(df**2 + dm**2)))


def path_smoothness(path: np.ndarray, dt: float) -> dict[str, float]:
    """``{"jerk": mean squared jerk, "sparc": SPARC of the path's speed}`` for [T, D]."""
    p = np.asarray(path, dtype=np.float64)
    p = p[:, None] if p.ndim == 1 else p
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    return {"jerk": mean_squared_jerk(p, dt), "sparc": sparc(speed, dt)}


def rollout_paths(
    run: str | Path, episodes: int, seed: int = EVAL_SEED, deterministic: bool = True
) -> tuple[list[np.ndarray], list[float], float]:
    """Executed robot paths of a trained run in its own (chunked) env.

    Returns:
        (paths: one [T + 1, D] array per episode (every env step), success at any step per
        episode, the control step dt).
    """
    policy = ndp.load_policy(run)
    env = policy.make_env()
    dt = float(policy.spec.control_dt)
    paths, success = [], []
    try:
        for ep in range(episodes):
            obs, info = env.reset(seed=seed + ep)
            policy.reset()
            path = [np.asarray(info["robot_pos"], dtype=np.float64).reshape(-1)]
            while True:
                obs, _, term, trunc, info = env.step(policy.act(obs, info, deterministic))
                rows = np.asarray(info["robot_pos"], dtype=np.float64)
                n = int(info.get("n_substeps", len(rows) - 1))
                path.extend(rows[1 : n + 1])
                if term or trunc:
                    break
            paths.append(np.stack(path))
            success.append(float(info["success_any"]))
    finally:
        env.close()
    return paths, success, dt


def run_smoothness(
    run: str | Path, episodes: int = 10, seed: int = EVAL_SEED, dofs: slice | None = None
) -> dict[str, float]:
    """Success, mean squared jerk and SPARC of a run's executed paths, means over episodes.

    ``dofs`` selects the coordinates measured (default: the task's arm coordinates, i.e. every
    DMP DoF except a gripper or fingers: hand xyz on Meta-World, the 6 joints on Jaco).
    """
    paths, success, dt = rollout_paths(run, episodes, seed)
    if dofs is None:
        names = ndp.load_policy(run).spec.dof_names
        keep = [i for i, n in enumerate(names) if "gripper" not in n and "finger" not in n]
    else:
        keep = list(range(paths[0].shape[1]))[dofs]
    rows = [path_smoothness(p[:, keep], dt) for p in paths if len(p) >= 4]
    return {
        "episodes": episodes,
        "success": float(np.mean(success)),
        "jerk": float(np.mean([r["jerk"] for r in rows])),
        "sparc": float(np.mean([r["sparc"] for r in rows])),
        "dt": dt,
    }


# ----------------------------------------------------------------------------- study over runs

SMOOTHNESS_FILE = "smoothness-e{episodes}-s{seed}.json"
"""Per-run cache of :func:`run_smoothness` (in the run directory; reused when present)."""


def smoothness_of_runs(
    paths: Sequence[str | Path],
    episodes: int = 20,
    seed: int = EVAL_SEED,
    tasks: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    log: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """:func:`run_smoothness` of every finished RL run found in ``paths`` (filters optional).

    Each run's result is cached in ``<run>/smoothness-e<episodes>-s<seed>.json`` (atomic write),
    so an interrupted study resumes and a rerun only measures new runs. Unfinished runs are
    skipped (and named through ``log``).

    Returns:
        One row per run: ``{"task", "method", "seed", "run", "success", "jerk", "sparc",
        "dt", "episodes"}``, ordered by task, method, seed.
    """
    import json

    check_int("episodes", episodes, 1)
    rows = []
    for path in find_run_dirs(paths):
        info = run_info(path)
        if info is None or not run_kind(info.kind).evaluable:
            continue
        if tasks is not None and info.task not in tasks:
            continue
        if methods is not None and info.label not in methods:
            continue
        if seeds is not None and info.seed not in seeds:
            continue
        if not info.finished:
            if log:
                log(f"[smoothness] {path.name}: not finished, skipped")
            continue
        cache = path / SMOOTHNESS_FILE.format(episodes=episodes, seed=seed)
        if cache.is_file():
            res = json.loads(cache.read_text())
        else:
            res = run_smoothness(path, episodes, seed)
            atomic_write_text(cache, json.dumps(res) + "\n")
            if log:
                log(f"[smoothness] {path.name}: {res}")
        rows.append(
            {"task": info.task, "method": info.label, "seed": info.seed, "run": str(path), **res}
        )
    rows.sort(key=lambda r: (r["task"], r["method"], r["seed"]))
    return rows


def summarise(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (task, method): mean and std over seeds of success, jerk and SPARC, and the seeds."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["task"], r["method"]), []).append(r)
    out = []
    for (task, method), rs in groups.items():
        row: dict[str, Any] = {"task": task, "method": method, "n_seeds": len(rs)}
        row["seeds"] = " ".join(str(r["seed"]) for r in rs)
        for key in ("success", "jerk", "sparc"):
            v = np.array([r[key] for r in rs], dtype=np.float64)
            row[f"{key}_mean"], row[f"{key}_std"] = float(np.nanmean(v)), float(np.nanstd(v))
        out.append(row)
    return out
