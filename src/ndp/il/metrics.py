"""Trajectory-error metrics and the prediction picture.

Definitions (pixels of the 40 x 40 frame):

- ``mse_px2`` per sample: mean over the T points and the 2 coordinates of the squared
  difference, ``mean_t,c (pred - demo)^2`` (the training loss of NDP and CNN; the squared
  Euclidean distance per point is twice this). Reported as mean +- std over samples.
- ``dtw_px`` per sample: dynamic time warping between the two point sequences with Euclidean
  point cost, accumulated cost divided by T, i.e. the mean matched distance in pixels; it ignores
  timing and measures only the shape of the path.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch

from ndp.io import atomic_savefig


def per_sample_mse(pred: torch.Tensor | np.ndarray, demo: torch.Tensor | np.ndarray) -> np.ndarray:
    """Per-sample mean squared error in px^2.

    Args:
        pred, demo: [n, T, 2] trajectories.

    Returns:
        [n] float64 errors.
    """
    p = torch.as_tensor(pred, dtype=torch.float64)
    d = torch.as_tensor(demo, dtype=torch.float64)
    if p.shape != d.shape:
        raise ValueError(f"shape mismatch: pred {tuple(p.shape)} vs demo {tuple(d.shape)}")
    return ((p - d) ** 2).mean(dim=(1, 2)).numpy()


def dtw_distance(
    a: np.ndarray | torch.Tensor, b: np.ndarray | torch.Tensor, chunk: int = 64
) -> np.ndarray:
    """Dynamic-time-warping distance between paired trajectories, batched.

    D[i, j] = c[i, j] + min(D[i-1, j], D[i, j-1], D[i-1, j-1]), c the Euclidean distance between
    a_i and b_j; computed along anti-diagonals so every step is vectorised over the batch.

    Args:
        a, b: [n, T, 2] (same T).
        chunk: samples per vectorised block (memory ~ chunk * T^2 * 8 bytes).

    Returns:
        [n] accumulated cost D[T-1, T-1] divided by T (mean matched distance).
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 3:
        raise ValueError(
            f"dtw_distance needs two [n, T, D] arrays of one shape: {a.shape} {b.shape}"
        )
    n, t, _ = a.shape
    out = np.zeros(n)
    kk, ii = np.meshgrid(np.arange(2 * t - 1), np.arange(t), indexing="ij")
    jj = kk - ii
    outside = (jj < 0) | (jj >= t)
    flat = ii * t + np.clip(jj, 0, t - 1)  # [2T-1, T] index into the flattened cost
    for s in range(0, n, chunk):
        aa, bb = a[s : s + chunk], b[s : s + chunk]
        m = aa.shape[0]
        cost = np.zeros((m, t, t))
        for c in range(aa.shape[2]):
            cost += (aa[:, :, None, c] - bb[:, None, :, c]) ** 2
        np.sqrt(cost, out=cost)  # [m, T, T] Euclidean point distances
        # skewed layout: skew[:, k, i] = cost[:, i, k - i] (inf outside the matrix)
        skew = cost.reshape(m, t * t)[:, flat]
        skew[:, outside] = np.inf
        prev2 = np.full((m, t + 1), np.inf)  # D on diagonal k-2 at i-1 (column 0 is i = -1)
        prev1 = np.full((m, t + 1), np.inf)  # D on diagonal k-1
        prev1[:, 1] = cost[:, 0, 0]
        cur = np.empty((m, t + 1))
        best = np.empty((m, t))
        for k in range(1, 2 * t - 1):
            # up: D[i-1, j] = prev1 at i-1; left: D[i, j-1] = prev1 at i; diag: prev2 at i-1
            np.minimum(prev1[:, :-1], prev1[:, 1:], out=best)
            np.minimum(best, prev2[:, :-1], out=best)
            cur[:, 0] = np.inf
            np.add(skew[:, k], best, out=cur[:, 1:])
            prev2, prev1, cur = prev1, cur, prev2
        out[s : s + m] = prev1[:, t] / t
    return out


PERCENTILES = (10, 25, 75, 90, 99)
"""Percentiles :func:`summarize` reports besides the median."""


def summarize(errors: np.ndarray) -> dict[str, float]:
    """Mean, std, median, max and the :data:`PERCENTILES` (``p10``, ...) of per-sample errors
    (NaN for an empty set)."""
    e = np.asarray(errors, dtype=np.float64)
    if e.size == 0:
        return dict.fromkeys(("mean", "std", "median", "max", *(f"p{q}" for q in PERCENTILES)),
                             math.nan)  # fmt: skip
    out = {
        "mean": float(e.mean()),
        "std": float(e.std()),
        "median": float(np.median(e)),
        "max": float(e.max()),
    }
    for q, v in zip(PERCENTILES, np.percentile(e, PERCENTILES), strict=True):
        out[f"p{q}"] = float(v)
    return out


def grouped(errors: np.ndarray, groups: np.ndarray) -> dict[str, dict[str, float]]:
    """Per group (digit class, writer): count, mean, median and max of per-sample errors.

    Samples whose group is -1 (unknown) are left out; an empty dict when no group is known."""
    e = np.asarray(errors, dtype=np.float64)
    g = np.asarray(groups)
    out: dict[str, dict[str, float]] = {}
    for key in np.unique(g[g >= 0]):
        sel = e[g == key]
        out[str(int(key))] = {
            "n": int(sel.size),
            "mean": float(sel.mean()),
            "median": float(np.median(sel)),
            "max": float(sel.max()),
        }
    return out


GRID_PICKS = ("first", "random", "median", "worst")
"""Which samples the prediction picture shows."""


def pick_samples(errors: np.ndarray, n: int, how: str = "first", seed: int = 0) -> np.ndarray:
    """Indices of ``n`` samples to draw: the first ones, a seeded random set, those around the
    median error, or the worst."""
    e = np.asarray(errors, dtype=np.float64)
    n = min(n, e.size)
    if how == "first":
        return np.arange(n)
    if how == "random":
        return np.sort(np.random.default_rng(seed).choice(e.size, size=n, replace=False))
    order = np.argsort(e, kind="stable")
    if how == "worst":
        return order[::-1][:n]
    if how == "median":
        lo = max(0, e.size // 2 - n // 2)
        return order[lo : lo + n]
    raise ValueError(f"grid: expected one of {', '.join(GRID_PICKS)}, got {how!r}")


def save_prediction_grid(
    path: Path | str,
    images: np.ndarray,
    demos: np.ndarray,
    preds: np.ndarray,
    titles: list[str] | None = None,
    cols: int = 8,
) -> Path:
    """Write a PNG grid of images with demonstrated (green) and predicted (red) trajectories.

    Args:
        path: output PNG (written atomically).
        images: [n, H, W] in [0, 1]; trajectories are in pixel coordinates of this frame.
        demos, preds: [n, T, 2].
        titles: optional per-panel titles.
        cols: panels per row.

    Returns:
        The path written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    n = images.shape[0]
    cols = min(cols, n)
    rows = (n + cols - 1) // cols
    h, w = images.shape[1:3]
    fig, axes = plt.subplots(rows, cols, figsize=(1.6 * cols, 1.7 * rows), squeeze=False)
    for k, ax in enumerate(axes.flat):
        ax.axis("off")
        if k >= n:
            continue
        ax.imshow(images[k], cmap="gray", vmin=0, vmax=1, extent=(0, w, h, 0))
        ax.plot(demos[k, :, 0], demos[k, :, 1], color="lime", lw=1.0)
        ax.plot(preds[k, :, 0], preds[k, :, 1], color="red", lw=1.0, ls="--")
        ax.plot(demos[k, 0, 0], demos[k, 0, 1], "o", color="yellow", ms=2.5)
        if titles is not None:
            ax.set_title(titles[k], fontsize=7)
    fig.suptitle("green: demonstration, red dashed: prediction, yellow: start", fontsize=8)
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=100)
    plt.close(fig)
    return path
