"""Statistics for few-seed RL results: bootstrap intervals, IQM, probability of improvement.

The protocol of Agarwal et al., "Deep Reinforcement Learning at the Edge of the Statistical
Precipice" (NeurIPS 2021; the ``rliable`` package), written here in numpy:

- per task, a **percentile bootstrap** 95% interval of the mean over seeds (:func:`bootstrap_ci`);
- over tasks, the **interquartile mean** (IQM: the mean of the middle 50% of all run scores,
  :func:`iqm`) with a **stratified bootstrap** interval: each replicate resamples the runs of
  every task with replacement, within the task (:func:`stratified_bootstrap_ci`);
- the **probability of improvement** P(X > Y) (:func:`probability_of_improvement`): per task
  the Mann-Whitney statistic of X's runs against Y's (ties count half), averaged over tasks,
  with its stratified bootstrap interval (X's and Y's runs resampled independently per task).

Scores are arrays ``[runs, tasks]`` (a seed per row, a task per column; every task with the same
number of runs). Each function takes a ``numpy.random.Generator`` or a seed, so a report's
intervals are the same every time it is written.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

REPS = 5000
"""Bootstrap replicates (rliable's default is 50,000 for its figures; 5,000 keeps a report
under a second and moves a 95% bound by about 0.005 on success rates)."""


def _rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def _scores(scores: object, name: str = "scores") -> np.ndarray:
    x = np.asarray(scores, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] < 1:
        raise ValueError(f"{name}: expected an array [runs, tasks] with runs, tasks >= 1")
    if not np.isfinite(x).all():
        raise ValueError(f"{name}: expected finite values")
    return x


def iqm(scores: object) -> float:
    """Interquartile mean of all run scores (``[runs, tasks]`` or ``[runs]``): the mean after
    dropping ``floor(n / 4)`` values at each end of the n sorted scores (rliable's IQM,
    ``scipy.stats.trim_mean(scores, 0.25, axis=None)``)."""
    x = np.sort(_scores(scores).ravel())
    cut = int(0.25 * len(x))
    return float(x[cut : len(x) - cut].mean())


def mean(scores: object) -> float:
    """Mean of all run scores."""
    return float(_scores(scores).mean())


def bootstrap_ci(
    values: object,
    stat: Callable[[np.ndarray], float] = np.mean,
    reps: int = REPS,
    conf: float = 0.95,
    rng: np.random.Generator | int | None = 0,
) -> tuple[float, float]:
    """Percentile bootstrap interval of ``stat`` over ``values`` [n] (resampled with
    replacement). With one value the interval is that value."""
    v = _scores(values, "values")[:, 0]
    if len(v) == 1:
        return float(v[0]), float(v[0])
    idx = _rng(rng).integers(0, len(v), size=(reps, len(v)))
    boot = np.array([stat(v[i]) for i in idx]) if stat is not np.mean else v[idx].mean(1)
    a = (1 - conf) / 2
    return float(np.quantile(boot, a)), float(np.quantile(boot, 1 - a))


def stratified_bootstrap_ci(
    scores: object,
    stat: Callable[[np.ndarray], float] = iqm,
    reps: int = REPS,
    conf: float = 0.95,
    rng: np.random.Generator | int | None = 0,
) -> tuple[float, float]:
    """Percentile interval of ``stat`` over stratified bootstrap replicates of ``scores``
    [runs, tasks]: each replicate draws, for every task independently, ``runs`` of that task's
    runs with replacement."""
    x = _scores(scores)
    n, m = x.shape
    gen = _rng(rng)
    boot = np.empty(reps)
    cols = np.arange(m)
    for r in range(reps):
        boot[r] = stat(x[gen.integers(0, n, size=(n, m)), cols])
    a = (1 - conf) / 2
    return float(np.quantile(boot, a)), float(np.quantile(boot, 1 - a))


def _poi(x: np.ndarray, y: np.ndarray) -> float:
    """Mean over tasks of P(x > y) + P(x = y) / 2 over all run pairs of the task."""
    gt = (x[:, None, :] > y[None, :, :]).mean((0, 1))
    eq = (x[:, None, :] == y[None, :, :]).mean((0, 1))
    return float(np.mean(gt + 0.5 * eq))


def probability_of_improvement(x: object, y: object) -> float:
    """P(X > Y): the probability that a run of X on a random task scores higher than a run of
    Y on the same task (ties count half), averaged over tasks; ``x`` [n, tasks], ``y``
    [m, tasks]. 0.5: neither is better; 1: every run of X beats every run of Y on every task."""
    a, b = _scores(x, "x"), _scores(y, "y")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"y: expected {a.shape[1]} tasks like x, got {b.shape[1]}")
    return _poi(a, b)


def probability_of_improvement_ci(
    x: object,
    y: object,
    reps: int = REPS,
    conf: float = 0.95,
    rng: np.random.Generator | int | None = 0,
) -> tuple[float, float]:
    """Stratified bootstrap interval of :func:`probability_of_improvement` (the runs of X and of
    Y resampled independently within each task)."""
    a, b = _scores(x, "x"), _scores(y, "y")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"y: expected {a.shape[1]} tasks like x, got {b.shape[1]}")
    gen = _rng(rng)
    (n, m), k = a.shape, b.shape[0]
    cols = np.arange(m)
    boot = np.empty(reps)
    for r in range(reps):
        boot[r] = _poi(
            a[gen.integers(0, n, size=(n, m)), cols], b[gen.integers(0, k, size=(k, m)), cols]
        )
    q = (1 - conf) / 2
    return float(np.quantile(boot, q)), float(np.quantile(boot, 1 - q))


# the Wilson interval of a success rate lives with the model cards that report it (ndp.rl sits
# below ndp.experiments in the data flow); re-exported here with the other statistics
from ndp.rl.card import Z95 as Z95  # noqa: E402
from ndp.rl.card import wilson_interval as wilson_interval  # noqa: E402
