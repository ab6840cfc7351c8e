"""A short NDP run for the README: train, plot the learning curve, render a video."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ndp.io import atomic_savefig
from ndp.rl.config import PPOConfig, TrainConfig
from ndp.runs import read_metrics


def demo_config(out_dir: Path, quick: bool = True) -> TrainConfig:
    """The demo's run configuration.

    quick: NDP on the toy point-mass task, 30k env steps with small updates (512 env steps,
    4 mini-batches, lr 1e-3): about 15-30 s on 2 cores. Otherwise NDP on reach-v3 with the
    paper's hyperparameters for 150k env steps (several minutes).
    """
    cfg = TrainConfig(
        task="reach-v3",
        algo="ndp",
        steps=150_000,
        seed=0,
        num_envs=4,
        run_dir=str(Path(out_dir) / "rl_demo_run"),
        progress=True,
    )
    if not quick:
        return cfg
    return dataclasses.replace(
        cfg,
        task="point-mass",
        steps=30_000,
        progress=False,
        steps_per_update=512,
        ppo=PPOConfig(minibatches=4, lr=1e-3),
    )


def plot_curve(run: Path, out_png: Path, title: str) -> Path:
    """Success (any step) and return vs env steps from a run's ``metrics.csv`` (dir or file)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = read_metrics(run)
    x = [r["global_step"] for r in rows]
    fig, ax = plt.subplots(1, 2, figsize=(8, 3))
    ax[0].plot(x, [r["charts/success_any"] for r in rows], label="success (any step)")
    ax[0].plot(x, [r["charts/success_final"] for r in rows], label="success (final step)")
    ax[0].set_ylim(-0.02, 1.02)
    ax[0].legend(fontsize=8)
    ax[1].plot(x, [r["charts/episode_return"] for r in rows])
    ax[1].set_ylabel("episode return")
    for a in ax:
        a.set_xlabel("env steps")
        a.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    out_png.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, out_png, dpi=80)
    plt.close(fig)
    return out_png


def run_rl_demo(out_dir: Path, quick: bool = True) -> dict[str, object]:
    """Train a short NDP run, write its learning curve (PNG) and a video (mp4).

    Args:
        out_dir: where the run directory, ``rl_curve.png`` and ``rl_video.mp4`` go (an existing
            demo run there is replaced).
        quick: the toy task (seconds) instead of reach-v3 (minutes); see :func:`demo_config`.

    Returns:
        ``{"run_dir", "curve", "video", "train": last metrics, "eval": deterministic eval}``.
    """
    import shutil

    from ndp.rl.evaluate import evaluate, render
    from ndp.rl.run import train

    out_dir = Path(out_dir)
    cfg = demo_config(out_dir, quick)
    run_dir = Path(cfg.run_dir or out_dir / "rl_demo_run")
    if run_dir.exists():
        shutil.rmtree(run_dir)
    metrics = train(cfg)
    curve = plot_curve(run_dir, out_dir / "rl_curve.png", f"NDP on {cfg.task} (seed {cfg.seed})")
    ev = evaluate(run_dir, episodes=10, deterministic=True)
    vid = render(run_dir, out_dir / "rl_video.mp4", episodes=2, overwrite=True)
    return {
        "run_dir": str(run_dir),
        "curve": str(curve),
        "video": vid["path"],
        "train": metrics,
        "eval": ev,
    }
