"""Paired tests for arms that share seeds: the sign-flip permutation test of per-seed differences.

Where two arms ran the same seeds (seed i of each arm trains from the same seed), the per-seed
differences d_i = a_i - b_i can be tested directly: under the null hypothesis that the labels
within each pair are exchangeable, each d_i is as likely to be -d_i. The test enumerates every
sign pattern (exact: 2^n patterns) or samples them (Monte-Carlo) and reports the two-sided p of
the mean difference. A seed in RL fixes the initial weights and the environment's random
stream; it does not make two methods' runs alike, so the pairing gains power only where the
seed's task draws matter to both arms. The report gives it beside the unpaired test, never in
its place (docs/metrics.md).

Pooled over tasks ("stratified"): the statistic is the mean over tasks of each task's mean
difference, with the signs flipped independently per (task, seed).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["PairedResult", "paired_pooled", "paired_sign_flip"]

EXACT_LIMIT = 20
"""At most this many pairs (2^20 sign patterns) are enumerated; more are sampled."""
RESAMPLES = 100_000
"""Sign patterns drawn for the Monte-Carlo test."""


@dataclass(frozen=True)
class PairedResult:
    """A paired sign-flip test of a mean difference."""

    diff: float
    """Mean per-seed difference (pooled: the mean over tasks of each task's mean)."""
    p: float
    """Two-sided p: the share of sign patterns whose |statistic| is at least the observed one
    (the observed pattern included, so p >= 1 / patterns)."""
    n_pairs: int
    """Pairs (seeds, or task x seed pairs when pooled)."""
    method: str
    """How p was computed: "exact sign-flip (all 2^n patterns)" or "Monte-Carlo sign-flip (N
    resamples)"."""


def _signs(n: int, rng: np.random.Generator) -> tuple[np.ndarray, str]:
    """Sign patterns [S, n]: all 2^n where n <= EXACT_LIMIT, else RESAMPLES random ones."""
    if n <= EXACT_LIMIT:
        codes = np.arange(2**n, dtype=np.int64)[:, None]
        bits = (codes >> np.arange(n, dtype=np.int64)) & 1
        return 1.0 - 2.0 * bits, f"exact sign-flip (all 2^{n} = {2**n:,} patterns)"
    signs = rng.choice(np.array([-1.0, 1.0]), size=(RESAMPLES, n))
    return signs, f"Monte-Carlo sign-flip ({RESAMPLES:,} resamples)"


def _p(stat: np.ndarray, observed: float) -> float:
    # a small tolerance so that ties with the observed statistic count as at least as extreme
    return float(np.mean(np.abs(stat) >= abs(observed) - 1e-12))


def paired_sign_flip(
    a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray, seed: int = 0
) -> PairedResult:
    """Two-sided paired sign-flip test of mean(a - b).

    Args:
        a, b: per-seed scores [n] in the same seed order (a[i] and b[i] share seed i).
        seed: the generator of the Monte-Carlo patterns (n > EXACT_LIMIT).

    Raises:
        ValueError: different lengths, fewer than 2 pairs, or non-finite scores.
    """
    x, y = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(
            f"a, b: expected two [n] vectors of the same length, got {x.shape}, {y.shape}"
        )
    if x.size < 2:
        raise ValueError(f"a, b: expected at least 2 pairs, got {x.size}")
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise ValueError("a, b: expected finite scores")
    d = x - y
    signs, how = _signs(d.size, np.random.default_rng(seed))
    stat = signs @ d / d.size
    return PairedResult(float(d.mean()), _p(stat, float(d.mean())), int(d.size), how)


def paired_pooled(
    pairs: Mapping[str, tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray]],
    seed: int = 0,
) -> PairedResult:
    """The paired test pooled over tasks: statistic = mean over tasks of the task's mean
    difference; signs flipped independently for every (task, seed) pair.

    Args:
        pairs: task -> (a [n_t], b [n_t]), each in the same seed order.
    """
    if not pairs:
        raise ValueError("pairs: expected at least one task")
    diffs, weights = [], []
    for task, (a, b) in pairs.items():
        x, y = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
        if x.shape != y.shape or x.ndim != 1 or x.size < 1:
            raise ValueError(f"pairs[{task!r}]: expected two [n] vectors of the same length")
        diffs.append(x - y)
        weights.append(np.full(x.size, 1.0 / (x.size * len(pairs))))
    d, w = np.concatenate(diffs), np.concatenate(weights)
    signs, how = _signs(d.size, np.random.default_rng(seed))
    observed = float(w @ d)
    stat = signs @ (w * d)
    return PairedResult(observed, _p(stat, observed), int(d.size), how)
