"""Slow learning check on a real task (skipped by default; run with ``pytest -m slow``)."""

from __future__ import annotations

import numpy as np
import pytest

from ndp.rl.config import TrainConfig
from ndp.rl.run import train
from ndp.runs import read_metrics


@pytest.mark.slow
def test_ndp_learns_reach_v3_in_100k_steps(tmp_path):
    # Measured: seed 0 reaches success_any 0.8-1.0 after ~60-80k env steps (docs/rl.md).
    train(
        TrainConfig(
            task="reach-v3",
            algo="ndp",
            steps=100_000,
            seed=0,
            run_dir=str(tmp_path / "r"),
            progress=False,
            tensorboard=False,
        )
    )
    rows = read_metrics(tmp_path / "r" / "metrics.csv")
    assert np.nanmean([r["charts/success_any"] for r in rows[-5:]]) >= 0.6
