"""The DMP's own floor on digit writing: how close a DMP can get to each test trajectory at all.

For every test trajectory of a data set (its split as ``ndp il train`` makes it), the
least-squares DMP fit (:func:`ndp.dmp.fit_dmp`: goal and forcing weights jointly, the
trajectory's first point as y0, starting at rest) is integrated with the same DMP the NDP and
CNN-DMP models use (``ModelConfig.dmp_config()``: 30 basis functions by default, a_z 25,
tau 1, ``steps`` Euler steps, 301 reported points) and scored like a model's prediction (mean
squared error per point, px^2). No model can write a digit closer than this with that DMP; a
model below the floor of one N is using more than that DMP can represent.

``ndp il floor --data synthetic --n-basis 10 20 30 --out FILE.json`` writes the table.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import TypedDict

import torch

from ndp.dmp import DMPLayer, fit_dmp
from ndp.il.config import DataConfig, ModelConfig
from ndp.il.metrics import per_sample_mse, summarize


class FloorRow(TypedDict):
    """One N of :func:`dmp_floor`."""

    n_basis: int
    n_test: int
    mse_px2: dict[str, float]
    """mean, std, median, max, percentiles over trajectories (:func:`ndp.il.metrics.summarize`)."""
    fit_s: float


def dmp_floor(
    data_cfg: DataConfig,
    n_basis: Sequence[int] = (30,),
    model_cfg: ModelConfig | None = None,
    ridge: float = 0.0,
    chunk: int = 2000,
) -> list[FloorRow]:
    """Test MSE (px^2) of least-squares DMP fits to every test trajectory, per N.

    Args:
        data_cfg: the data set and split (the test part is scored; split 'all': every sample).
        n_basis: the numbers of basis functions N to fit with.
        model_cfg: the DMP settings besides N (default: the models' defaults).
        ridge: ridge of the least-squares fit (0: plain least squares).
        chunk: trajectories fitted at once.

    Returns:
        One dict per N: ``n_basis``, ``n_test``, ``mse_px2`` (mean, std, median, max over
        trajectories), ``fit_s``.
    """
    from ndp.il.train import load_data, make_split

    base = model_cfg or ModelConfig()
    data = load_data(data_cfg, base.n_points)
    tr, te = make_split(data, data_cfg)
    scored = te if len(te) else tr
    demos = torch.from_numpy(data.trajs[scored]).to(torch.float64)
    out: list[FloorRow] = []
    for n in n_basis:
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"n_basis: expected integers >= 1, got {n!r}")
        cfg = dataclasses.replace(base, n_basis=n).dmp_config()
        layer = DMPLayer(cfg)
        t0 = time.perf_counter()
        fits = []
        for s in range(0, len(demos), chunk):
            d = demos[s : s + chunk]
            goal, weights = fit_dmp(d, cfg, ridge=ridge)
            fits.append(layer(goal, weights, d[:, 0]).pos)
        pred = torch.cat(fits).numpy()
        mse = per_sample_mse(pred, demos.numpy())
        out.append({"n_basis": n, "n_test": len(scored), "mse_px2": summarize(mse),
                    "fit_s": time.perf_counter() - t0})  # fmt: skip
    return out
