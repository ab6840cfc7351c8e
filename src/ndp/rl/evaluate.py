"""Evaluate a trained run (success over N episodes) and render it to mp4."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import gymnasium as gym
import numpy as np

from ndp import zoo
from ndp.checks import check_int
from ndp.envs.base import check_render_size
from ndp.envs.render import GIF_MAX_FPS, check_video_size, write_gif, write_mp4
from ndp.hub import is_hub_ref, parse_hub_ref
from ndp.io import atomic_write_text, check_output_path
from ndp.provenance import git_commit
from ndp.rl.card import wilson_interval
from ndp.rl.config import EVAL_SEED
from ndp.rl.envs import FrameRecorder
from ndp.rl.exec_k import exec_k_values
from ndp.rl.policy import Policy, load_policy

__all__ = [
    "Policy",
    "evaluate",
    "evaluate_policy",
    "load_policy",
    "render",
    "save_evaluation",
    "wilson_interval",
]

EVAL_FILE = "eval-{mode}-e{episodes}-s{seed}{exec_k}.json"
"""A saved evaluation in the run directory (:func:`save_evaluation`): mode 'det' or 'sto'."""


def _check_episodes(episodes: object, seed: object) -> None:
    """Episode count and first seed checked before anything loads (one-line errors)."""
    check_int("episodes", episodes, 1)
    check_int("seed", seed, 0, note="(the first episode seed)")


def default_output_dir(run_dir: str | Path) -> Path:
    """Where a command writes by default for ``run_dir``: the run directory itself, or for a
    shipped policy ``"zoo:<name>"`` the folder ``<name>`` in the working directory (not a
    folder named ``zoo:<name>``, and not the installed package); for a Hub address
    ``"hf://ORG/NAME[@REV]"`` the folder ``NAME`` (not the Hub's cache)."""
    text = str(run_dir)
    if text.startswith(zoo.PREFIX):
        return Path(text[len(zoo.PREFIX) :])

    if is_hub_ref(text):
        return Path(parse_hub_ref(text).repo_id.split("/")[1])
    return Path(run_dir)


def check_save_target(run_dir: str | Path) -> None:
    """Refuse to save an evaluation into a policy shipped with the package (``zoo:<name>``).

    Raises:
        ValueError: naming ``run_dir`` and what to do instead.
    """
    if str(run_dir).startswith(zoo.PREFIX):
        raise ValueError(
            f"run_dir: --save writes into a run directory; {run_dir} is a policy shipped with "
            "the package (export it first: ndp rl export zoo:NAME DIR)"
        )
    if str(run_dir).startswith("hf://"):
        raise ValueError(
            f"run_dir: --save writes into a run directory; {run_dir} is a policy on the Hub "
            "(export it first: ndp rl export hf://ORG/NAME DIR)"
        )


def save_evaluation(run_dir: str | Path, result: Mapping[str, float], seed: int) -> Path:
    """Write an :func:`evaluate` result into the run (atomic; one file per protocol, replaced
    when the same protocol is evaluated again) with the protocol and the Wilson 95% interval
    of the success at any step.

    Args:
        run_dir: the evaluated run directory.
        result: :func:`evaluate`'s dict.
        seed: the first episode seed the evaluation used.

    Returns:
        The file written: ``<run_dir>/eval-<det|sto>-e<episodes>-s<seed>[-k<K2>].json``.
    """
    check_save_target(run_dir)
    n = int(result["episodes"])
    successes = round(float(result["success_any"]) * n)
    low, high = wilson_interval(successes, n)
    mode = "det" if result["deterministic"] else "sto"
    k2 = result.get("exec_k")
    trained_k = result.get("m", 1) == 1
    name = EVAL_FILE.format(mode=mode, episodes=n, seed=seed, exec_k="" if trained_k else f"-k{k2}")
    data = {
        **result,
        "protocol": {
            "episodes": n,
            "seeds": [seed, seed + n - 1],
            "policy": "mode of the distribution" if result["deterministic"] else "sampled",
            "success": "success at any step of the episode",
        },
        "success_any_count": successes,
        "success_any_wilson95": [low, high],
        "evaluated_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "evaluated_by_commit": git_commit(),
    }
    path = Path(run_dir) / name
    atomic_write_text(path, json.dumps(data, indent=1) + "\n")
    return path


def env_task(env: object) -> str | None:
    """The task-table row an env built by ``ndp.make_env`` runs (``env.unwrapped.ndp_task``,
    set by the factory), or None for an env built otherwise."""
    task = getattr(getattr(env, "unwrapped", env), "ndp_task", None)
    return task if isinstance(task, str) else None


def check_env_task(pol: Policy, env: object, force: bool = False) -> None:
    """Refuse to act with ``pol`` in an env of another task: tasks of one family share their
    observation and action sizes (reach-v3 and push-v3: 39 and 4), so nothing else would say.

    Raises:
        ValueError: naming ``env``, both tasks and ``force``, unless ``force``.
    """
    have = env_task(env)
    spec = pol.spec
    if force or have is None or have == spec.name:
        return
    raise ValueError(
        f"env: the policy was trained on {spec.name!r}, the env runs {have!r}; pass force=True "
        "to evaluate it on another task on purpose"
    )


def run_episode(
    pol: Policy, env: gym.Env, seed: int, deterministic: bool, force: bool = False
) -> dict[str, float]:
    """One episode of ``pol`` in ``env`` (a chunked env) from reset seed ``seed``: success at
    any step and at the final step, return and length in env steps. An env of another task than
    the policy's is refused unless ``force`` (:func:`check_env_task`)."""
    check_env_task(pol, env, force)
    obs, info = env.reset(seed=seed)
    pol.reset(seed)  # the action noise of a stochastic episode is seeded by the episode seed
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
    seed: int = EVAL_SEED,
    exec_k: int | None = None,
) -> dict[str, float]:
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
    _check_episodes(episodes, seed)
    pol = load_policy(run_dir)
    if exec_k is not None:
        pol = pol.at_exec_k(exec_k)
    return evaluate_policy(pol, episodes, deterministic, seed)


def evaluate_policy(
    pol: Policy, episodes: int = 10, deterministic: bool = True, seed: int = EVAL_SEED
) -> dict[str, float]:
    """:func:`evaluate` of a loaded policy (or its ``at_exec_k`` copy) in ``pol.make_env()``."""
    _check_episodes(episodes, seed)
    env = pol.make_env()
    try:
        rows = [run_episode(pol, env, seed + i, deterministic) for i in range(episodes)]
    finally:
        env.close()
    out: dict[str, float] = {"episodes": episodes, "deterministic": deterministic}
    for key in rows[0]:
        out[key] = float(np.mean([r[key] for r in rows]))
    out["episode_seconds"] = out["episode_length"] * float(pol.spec.control_dt)
    out["exec_k"] = pol.exec_k
    out["m"] = pol.substeps
    return out


def _record(
    run_dir: str | Path,
    episodes: int,
    deterministic: bool,
    seed: int,
    exec_k: int | None = None,
    render_size: tuple[int | None, int | None] | None = None,
) -> tuple[list[np.ndarray], list[dict[str, float]], Policy]:
    """Frames (every env step, ``render_size`` = (width, height) px where given) and episode
    rows of a run's policy (at ``exec_k`` sub-steps per decision where given:
    ``Policy.at_exec_k``), and the policy."""
    _check_episodes(episodes, seed)
    pol = load_policy(run_dir)
    if exec_k is not None:
        pol = pol.at_exec_k(exec_k)
    recorders: list[FrameRecorder] = []

    def record(base: gym.Env) -> FrameRecorder:
        recorders.append(FrameRecorder(base))
        return recorders[-1]

    env = pol.make_env(render_mode="rgb_array", wrap=record, render_size=render_size)
    try:
        rows = [run_episode(pol, env, seed + i, deterministic) for i in range(episodes)]
    finally:
        env.close()
    return recorders[0].frames, rows, pol


def video_rate(control_dt: float, max_fps: int = 60) -> tuple[int, int]:
    """``(stride, fps)``: keep every ``stride``-th frame of a recording made every
    ``control_dt`` s so that the video plays in real time at ``fps`` <= ``max_fps``."""
    rate = 1.0 / float(control_dt)
    stride = max(1, math.ceil(rate / max_fps - 1e-9))
    return stride, max(1, round(rate / stride))


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
    seed: int = EVAL_SEED,
    compare: str | Path | None = None,
    exec_k: int | None = None,
    width: int | None = None,
    height: int | None = None,
    overwrite: bool = False,
) -> dict[str, object]:
    """Render ``episodes`` episodes of a trained policy to one mp4 (every env step is a frame;
    in real time, at most 60 frames per second: finer steps are subsampled), or to a looping
    GIF where ``out`` ends in ``.gif`` (at most 25 frames per second).

    Args:
        run_dir: a training run directory.
        out: mp4 or ``.gif`` path (default ``run_dir/video.mp4``; for ``"zoo:<name>"``,
            ``./<name>/video.mp4``, never the installed package's folder).
        episodes: episodes to record back to back.
        deterministic: act with the mode.
        seed: first episode seed.
        compare: a second run of the same task, rendered on the same seeds to the right of the
            first (e.g. NDP vs PPO-multi, the supplement's videos).
        exec_k: run each decision as this many sub-steps of the same duration (``ndp rl eval
            --exec-k``; both runs with ``compare``); None: as trained.
        width: frame width in px (each run's, with ``compare``); None: the env's own (480
            for the robots, 96 for the point mass).
        height: frame height in px; None: the env's own.
        overwrite: replace an existing ``out`` (default: refused, FileExistsError naming
            ``out``, before anything is loaded or rendered); the run's own ``video.mp4`` (no
            ``out``) is a regenerable output of the run and is replaced.

    Returns:
        ``{"path", "frames", "width", "height", "success_any", ...}``
        (``success_any_compare`` with ``compare``; width and height of one run's frames).
    """
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")

    target = _render_target(run_dir, out, compare, width, height, overwrite)
    size = (width, height)
    frames, rows, pol = _record(run_dir, episodes, deterministic, seed, exec_k, size)
    frame_h, frame_w = frames[0].shape[:2]  # one run's frame (before side_by_side)
    result: dict[str, float] = {}
    if compare is not None:
        frames_b, rows_b, pol_b = _record(compare, episodes, deterministic, seed, exec_k, size)
        if pol_b.substeps != pol.substeps:
            raise ValueError(
                f"compare: exec_k={exec_k} runs {compare} at {pol_b.substeps} env steps per "
                f"trained one and {run_dir} at {pol.substeps}; the videos would not line up"
            )
        result["success_any_compare"] = float(np.mean([r["success_any"] for r in rows_b]))
        frames = side_by_side(frames, frames_b)
    gif = target.suffix.lower() == ".gif"
    max_fps = GIF_MAX_FPS if gif else 60
    stride, fps = video_rate(float(pol.spec.control_dt), max_fps)  # the finer row at exec_k
    frames = frames[::stride]
    (write_gif if gif else write_mp4)(frames, target, fps=fps)
    return {
        "path": str(target),
        "frames": len(frames),
        "width": int(frame_w),
        "height": int(frame_h),
        "success_any": float(np.mean([r["success_any"] for r in rows])),
        "exec_k": pol.exec_k,
        "fps": fps,
        **result,
    }


def _render_target(
    run_dir: str | Path,
    out: str | Path | None,
    compare: str | Path | None,
    width: int | None,
    height: int | None,
    overwrite: bool,
) -> Path:
    """:func:`render`'s mp4 path, its arguments checked before anything is rendered: the path
    (an existing file the user named needs ``overwrite``), the frame size, and that a
    ``compare`` run is of the same task."""
    target = Path(out) if out is not None else default_output_dir(run_dir) / "video.mp4"
    # before rendering anything; an existing file at a path the user named needs overwrite
    check_output_path(target, "out", overwrite=None if out is None else overwrite)
    for name, side in (("width", width), ("height", height)):
        if side is not None:
            check_render_size(name, side)  # before loading or rendering anything
            check_video_size(name, side)  # what the mp4 encoder accepts
    if compare is not None:
        other = load_policy(compare)
        mine = load_policy(run_dir)
        if other.cfg.task != mine.cfg.task:
            raise ValueError(
                f"compare: {compare} is a {other.cfg.task} run, {run_dir} a {mine.cfg.task} run"
            )
    return target


EXEC_K_TABLE_KEYS = (
    "run",
    "task",
    "algo",
    "k",
    "exec_k",
    "m",
    "execution",
    "episodes",
    "deterministic",
    "success_any",
    "success_final",
    "episode_return",
    "episode_length",
    "episode_seconds",
    "seconds",
)
"""Columns of :func:`exec_k_table` rows."""


def exec_k_table(
    run_dirs: Sequence[str | Path],
    values: Sequence[int] | None = None,
    episodes: int = 20,
    seed: int = EVAL_SEED,
    deterministic: bool = True,
    every: bool = False,
    ndp_hold: bool = False,
) -> list[dict[str, object]]:
    """Success vs K2 for trained runs: one :func:`ndp.rl.evaluate.evaluate` per run and K2.

    Args:
        run_dirs: training run (or export) directories.
        values: K2 values evaluated for every run (each must be allowed for each run); None:
            per run, the trained k and the finest ``k * m_max`` (:func:`exec_k_values`), or
            every allowed K2 with ``every``.
        episodes: episodes per run and K2 (the same seeds ``seed ..`` for every K2).
        seed: first episode seed.
        deterministic: act with the mode (else sample).
        every: with ``values`` None, every K2 of :func:`exec_k_values` (Jaco: k, 2k, 5k, 10k).
        ndp_hold: for NDP runs at K2 > k, also a row with the trained k sub-actions held for m
            env steps (``at_exec_k(..., hold=True)``).

    Returns:
        One dict per (run, K2, execution) with the keys of :data:`EXEC_K_TABLE_KEYS` (means over
        episodes; ``execution``: ``"trained"`` at m = 1, ``"dmp"`` for NDP's DMP sampled at K2,
        ``"hold"`` for held sub-actions; ``seconds``: wall time of that evaluation).
    """
    rows = []
    for run in run_dirs:
        trained = load_policy(run)
        allowed = exec_k_values(trained)
        if values is not None:
            ks = list(values)
        else:
            ks = list(allowed) if every else sorted({allowed[0], allowed[-1]})
        is_ndp = trained.cfg.policy.head == "ndp"
        for k2 in ks:
            variants = [False, True] if (is_ndp and ndp_hold and k2 != trained.cfg.k) else [False]
            for hold in variants:
                pol = trained.at_exec_k(k2, hold=hold)
                t0 = time.perf_counter()
                ev = evaluate_policy(pol, episodes, deterministic, seed)
                if pol.substeps == 1:
                    execution = "trained"
                else:
                    execution = "dmp" if (is_ndp and not hold) else "hold"
                row = {
                    "run": str(run),
                    "task": trained.cfg.task,
                    "algo": trained.cfg.algo,
                    "k": trained.cfg.k,
                    "execution": execution,
                    **ev,
                    "seconds": time.perf_counter() - t0,
                }
                rows.append({key: row[key] for key in EXEC_K_TABLE_KEYS})
    return rows
