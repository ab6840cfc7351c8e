"""``ndp demo``: the main job of the README quick start.

Runs, in order, each part that exists in this build and writes its figures into ``--out``:

1. DMP rollouts (``dmp_rollouts.png``): the forcing term shaping a trajectory, the spring
   constant a_z, the RBF kinds, and a least-squares fit of a smooth demonstration.
2. Digit writing by imitation (``ndp.il.demo.run_il_demo``): a short NDP training run.
3. Reinforcement learning (``ndp.rl.demo.run_rl_demo``): a short NDP run with its learning
   curve and a video.
"""

from __future__ import annotations

import argparse
import importlib
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ndp.io import atomic_savefig, atomic_write_text, check_output_path

if TYPE_CHECKING:
    import torch
    from matplotlib.axes import Axes


def run_dmp_demo(out_dir: Path) -> dict[str, str | float]:
    """Plot DMP rollouts and a fit; returns a summary with the fit error."""
    import matplotlib
    import torch

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    gen = torch.Generator().manual_seed(0)
    y0 = torch.zeros(6, 2)
    goal = torch.tensor([[1.0, 1.0]]).expand(6, 2)
    fig, axes = plt.subplots(1, 4, figsize=(18, 4.4))
    t = _random_weights(axes[0], gen, goal, y0)
    _only_g(axes[1], goal, y0, t)
    _rbf_kinds(axes[2], gen, goal, y0, t)
    mse = _fit(axes[3], t)
    fig.tight_layout()
    path = out_dir / "dmp_rollouts.png"
    atomic_savefig(fig, path, dpi=110)
    plt.close(fig)
    return {"figure": str(path), "fit_mse_px2": mse}


def _random_weights(
    ax: Axes, gen: torch.Generator, goal: torch.Tensor, y0: torch.Tensor
) -> torch.Tensor:
    """Panel 1: six rollouts with random forcing weights (the first with none); returns the
    DMP's time axis for the other panels."""
    import torch

    from ndp.dmp import DMPConfig, dmp_rollout

    cfg = DMPConfig(n_basis=10, a_z=25.0, steps=300)
    weights = torch.randn(6, 2, 10, generator=gen) * 150.0
    weights[0] = 0.0
    traj = dmp_rollout(goal, weights, y0, None, cfg)
    for i in range(6):
        label = "w = 0 (spring to g)" if i == 0 else None
        ax.plot(traj.pos[i, :, 0], traj.pos[i, :, 1], lw=2 if i == 0 else 1, label=label)
    ax.plot(0, 0, "ko", label="y0")
    ax.plot(1, 1, "r*", ms=12, label="g")
    ax.set_title("Random forcing weights, N = 10")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_aspect("equal")
    return torch.linspace(0, 1, cfg.n_out)


def _only_g(ax: Axes, goal: torch.Tensor, y0: torch.Tensor, t: torch.Tensor) -> None:
    """Panel 2: the goal-only DMP (a critically damped spring) at four a_z."""
    from ndp.dmp import DMPConfig, dmp_rollout

    for a_z in (5.0, 10.0, 25.0, 50.0):
        c = DMPConfig(n_basis=10, a_z=a_z, steps=300, only_g=True)
        p = dmp_rollout(goal[:1, :1], None, y0[:1, :1], None, c).pos[0, :, 0]
        ax.plot(t, p, label=f"a_z = {a_z:g}")
    ax.set_title("Only-g: critically damped spring")
    ax.set_xlabel("DMP time")
    ax.legend(fontsize=8)


def _rbf_kinds(
    ax: Axes, gen: torch.Generator, goal: torch.Tensor, y0: torch.Tensor, t: torch.Tensor
) -> None:
    """Panel 3: the same weights under every RBF kind."""
    import torch

    from ndp.dmp import RBF_KINDS, DMPConfig, dmp_rollout

    w1 = torch.randn(1, 1, 10, generator=gen) * 40.0
    for kind in RBF_KINDS:
        c = DMPConfig(n_basis=10, a_z=25.0, steps=300, rbf=kind)
        p = dmp_rollout(goal[:1, :1], w1, y0[:1, :1], None, c).pos[0, :, 0]
        ax.plot(t, p, label=kind)
    ax.set_title("Same weights, five RBF kinds")
    ax.set_xlabel("DMP time")
    ax.legend(fontsize=8)


def _fit(ax: Axes, t: torch.Tensor) -> float:
    """Panel 4: a least-squares fit of (g, w) to a drawn demonstration; returns its MSE."""
    import torch

    from ndp.dmp import DMPConfig, dmp_rollout, fit_dmp

    cfg30 = DMPConfig(n_basis=30, a_z=25.0, steps=300)
    s = t.double()
    s = 10 * s**3 - 15 * s**4 + 6 * s**5
    demo = torch.stack(
        [20 + 9 * torch.sin(2.4 * torch.pi * s), 12 + 18 * s - 6 * torch.sin(4.0 * torch.pi * s)],
        dim=-1,
    ).unsqueeze(0)
    g_fit, w_fit = fit_dmp(demo, cfg30)
    rec = dmp_rollout(g_fit, w_fit, demo[:, 0], None, cfg30).pos
    mse = float(((rec - demo) ** 2).sum(-1).mean())
    ax.plot(demo[0, :, 0], demo[0, :, 1], "k-", lw=4, alpha=0.3, label="demonstration")
    ax.plot(rec[0, :, 0], rec[0, :, 1], "r--", label=f"fit N=30 (MSE {mse:.1e} px²)")
    ax.invert_yaxis()
    ax.set_title("Least-squares fit of (g, w)")
    ax.legend(fontsize=8)
    ax.set_aspect("equal")
    return mse


_PARTS = (
    ("il", "ndp.il.demo", "run_il_demo"),
    ("rl", "ndp.rl.demo", "run_rl_demo"),
)


def run(args: argparse.Namespace) -> int:
    out = check_output_path(args.out, "out", folder=True)  # a file there: one line naming --out
    summary: dict[str, Any] = {}
    t0 = time.perf_counter()
    print("[1] DMP rollouts ...", flush=True)
    summary["dmp"] = run_dmp_demo(out / "dmp")
    for i, (key, module_name, fn_name) in enumerate(_PARTS, start=2):
        if key in args.skip:
            continue
        try:
            fn = getattr(importlib.import_module(module_name), fn_name)
        except (ModuleNotFoundError, AttributeError):
            summary[key] = "not available in this build"
            continue
        print(f"[{i}] {key} ...", flush=True)
        summary[key] = fn(out / key, quick=not args.full)
    summary["wall_s"] = round(time.perf_counter() - t0, 1)
    text = json.dumps(summary, indent=2, default=str)
    atomic_write_text(out / "summary.json", text)
    print(text)
    return 0


def add_subparser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("demo", help="run the quick-start demo (DMP plot, digit writing, RL)")
    p.add_argument("--out", default="runs/demo", help="output directory (default runs/demo)")
    p.add_argument("--full", action="store_true", help="longer runs instead of the quick ones")
    p.add_argument("--skip", nargs="*", default=[], choices=["il", "rl"], help="parts to leave out")
    p.set_defaults(func=run)
