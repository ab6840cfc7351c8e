"""Class-realism features: judge generated digits with classifiers trained on REAL digits.

Two views, both independent of the generator:

- trajectory shape with direction (:func:`trajectory_features`): the path resampled to ``m``
  points equally spaced in arc length, centred and scaled by its bounding box; a classifier
  trained on Pendigits pen trajectories should recognise generated trajectories, and reversed
  ones (a digit drawn backwards) should look different;
- image (:func:`optdigits_features`): the ink cropped to its bounding box, scaled to fit 32 x 32
  and block-summed 4 x 4 into the 8 x 8 (0..16) format of scikit-learn's bundled digits.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F


def trajectory_features(trajs: np.ndarray, m: int = 8) -> np.ndarray:
    """Direction-aware shape features of pen trajectories.

    Args:
        trajs: [n, T, 2] trajectories (any units).
        m: points kept per trajectory.

    Returns:
        [n, 2 m] features: the arc-length-resampled points, centred on the bounding box and
        divided by its larger side (so in [-0.5, 0.5]).
    """
    trajs = np.asarray(trajs, dtype=np.float64)
    out = np.zeros((trajs.shape[0], 2 * m))
    for i, t in enumerate(trajs):
        d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(t, axis=0), axis=1))])
        s = np.linspace(0.0, d[-1], m)
        p = np.stack([np.interp(s, d, t[:, 0]), np.interp(s, d, t[:, 1])], axis=1)
        lo, hi = p.min(axis=0), p.max(axis=0)
        p = (p - 0.5 * (lo + hi)) / max(float((hi - lo).max()), 1e-6)
        out[i] = p.ravel()
    return out


def optdigits_features(images: np.ndarray, threshold: float = 0.3) -> np.ndarray:
    """Convert [n, H, W] ink images to scikit-learn's 8 x 8 digits format.

    The ink (> ``threshold``) is cropped to its bounding box, resized to fit 32 x 32 with its
    aspect kept, centred, binarised and summed over 4 x 4 blocks (values 0..16), as in the UCI
    optdigits preprocessing behind ``sklearn.datasets.load_digits``.

    Returns:
        [n, 64] float features.
    """
    out = np.zeros((images.shape[0], 64))
    for i, im in enumerate(np.asarray(images, dtype=np.float32)):
        r, c = np.nonzero(im > threshold)
        if r.size == 0:
            continue
        crop = im[r.min() : r.max() + 1, c.min() : c.max() + 1]
        h, w = crop.shape
        s = 32.0 / max(h, w)
        nh, nw = max(1, round(h * s)), max(1, round(w * s))
        x = F.interpolate(
            torch.from_numpy(np.ascontiguousarray(crop))[None, None],
            size=(nh, nw),
            mode="bilinear",
            align_corners=False,
        )[0, 0].numpy()
        canvas = np.zeros((32, 32))
        r0, c0 = (32 - nh) // 2, (32 - nw) // 2
        canvas[r0 : r0 + nh, c0 : c0 + nw] = x > threshold
        out[i] = canvas.reshape(8, 4, 8, 4).sum(axis=(1, 3)).ravel()
    return out
