"""A short digit-writing run for the README's main demo (``ndp demo`` calls it)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from ndp.il.models import ModelConfig
from ndp.il.train import DataConfig, TrainConfig, evaluate, train


def run_il_demo(out_dir: Path, quick: bool = True, threads: int = 1) -> dict[str, Any]:
    """Train NDP briefly on a small synthetic digit set and draw its test predictions.

    ``quick`` (about a minute on 2 CPU cores): 5,000 generated digits, 4,500 train / 500 test,
    12 epochs (540 Adam steps; about 25 s of training on an idle 2-core machine). Otherwise:
    the paper split (10,000 / 2,000) for 20 epochs (several minutes).

    Args:
        out_dir: output folder; the run goes to ``out_dir/il_ndp`` (replaced if present) and
            the synthetic cache to ``out_dir/il_data``.
        quick: the short setting above.
        threads: torch CPU threads (1 by default: two threads on cores shared with other
            work run many times slower).

    Returns:
        Dict with ``png`` (path of the picture), ``test_mse_px2`` (mean / std / median / max),
        ``test_dtw_px``, ``epochs``, ``run_dir`` and ``train_wall_s``.
    """
    out_dir = Path(out_dir)
    if quick:
        data = DataConfig(
            data_dir=str(out_dir / "il_data"), n_samples=5000, n_train=4500, n_test=500
        )
        epochs = 12
    else:
        data = DataConfig(data_dir=str(out_dir / "il_data"))
        epochs = 20
    cfg = TrainConfig(
        run_dir=str(out_dir / "il_ndp"),
        data=data,
        model=ModelConfig(kind="ndp"),
        epochs=epochs,
        threads=threads,
        progress=False,
        eval_every=0,
    )
    if Path(cfg.run_dir).exists():  # the demo's own output folder: each demo run replaces it
        shutil.rmtree(cfg.run_dir)
    summary = train(cfg)
    ev = evaluate(cfg.run_dir, dtw=True, threads=threads, n_grid=16)
    return {
        "png": ev["png"],
        "test_mse_px2": ev["test_mse_px2"],
        "test_dtw_px": ev["test_dtw_px"],
        "epochs": epochs,
        "run_dir": cfg.run_dir,
        "train_wall_s": summary["train_wall_s"],
    }
