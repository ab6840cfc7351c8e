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

Beside them, what rliable lacks and few-seed comparisons need: a **permutation test**
stratified by task, exact over every split where their number allows, else Monte Carlo
(:func:`permutation_tests`, which says which: :attr:`PermutationResult.method`), **Holm's
correction** of a family of p-values (:func:`holm`; the significance convention of
docs/metrics.md), **t-intervals** (:func:`t_interval`; of a difference, Welch's, stratified by
task: :func:`difference_t_interval`) with the note on coverage at few seeds
(:data:`COVERAGE_NOTE`, measured by ``benchmarks/bootstrap_coverage.py``); and from rliable
itself (the ``[stats]`` extra) the **optimality gap** (:func:`optimality_gap`) and
**performance profiles** (:func:`performance_profile`).

Scores are arrays ``[runs, tasks]`` (a seed per row, a task per column; every task with the same
number of runs). Each function takes a ``numpy.random.Generator`` or a seed, so a report's
intervals are the same every time it is written.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

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


PERMUTATION_EXACT_LIMIT = 200_000
"""Largest number of stratified splits enumerated exactly; above it the test samples
:data:`PERMUTATION_SAMPLES` random splits."""
PERMUTATION_SAMPLES = 100_000
"""Random stratified splits of the Monte-Carlo test (the convention of docs/metrics.md; the
smallest p it can give is 1 / 100,001, and at p = 0.05 its standard error is about 0.0007)."""

ALPHA = 0.05
"""The significance level of the convention (docs/metrics.md): a two-sided p at or below it,
after Holm's correction within the table's family, is "significant"."""


@functools.lru_cache(maxsize=8)
def _splits(n_x: int, n_y: int) -> np.ndarray:
    """Every way to choose which n_x of n_x + n_y pooled runs form group X: [splits, n_x + n_y]
    bool (True: in X); cached (a report tests many pairs of the same sizes), read-only."""
    import itertools

    n = n_x + n_y
    out = np.zeros((math.comb(n, n_x), n), dtype=bool)
    for r, idx in enumerate(itertools.combinations(range(n), n_x)):
        out[r, list(idx)] = True
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class PermutationResult:
    """The p-values of one stratified permutation test (:func:`permutation_tests`) and how they
    were computed."""

    greater: float
    """One-sided p of X > Y: the fraction of splits whose statistic is >= the observed one."""
    less: float
    """One-sided p of Y > X (the statistic <= the observed one)."""
    two_sided: float
    """Two-sided p: |statistic| >= |observed|."""
    exact: bool
    """True: every stratified split was enumerated; False: :attr:`count` random splits were
    drawn (the observed split counted in, so p >= 1 / (count + 1))."""
    count: int
    """The splits enumerated (exact) or drawn (Monte Carlo)."""

    @property
    def method(self) -> str:
        """How the p-values were computed, as every table labels them: ``exact permutation
        (all N splits)`` or ``Monte-Carlo permutation (N resamples)``."""
        if self.exact:
            return f"exact permutation (all {self.count:,} splits)"
        return f"Monte-Carlo permutation ({self.count:,} resamples)"

    def p(self, alternative: str) -> float:
        """The p-value of ``alternative``: 'greater', 'less' or 'two-sided'."""
        if alternative == "greater":
            return self.greater
        if alternative == "less":
            return self.less
        if alternative == "two-sided":
            return self.two_sided
        raise ValueError(
            f"alternative: expected 'greater', 'less' or 'two-sided', got {alternative!r}"
        )


def permutation_tests(
    x: object, y: object, rng: np.random.Generator | int | None = 0
) -> PermutationResult:
    """The permutation test of X's runs against Y's, stratified by task, in both directions and
    two-sided, from one reference distribution.

    Statistic: the sum over tasks of (mean of X's runs - mean of Y's runs) on the task (the mean
    difference over tasks, times the task count). Under the null hypothesis the labels X / Y are
    exchangeable within each task, so the reference distribution is the statistic over every
    re-split of each task's pooled runs into groups of X's and Y's sizes (the product over tasks
    of C(n_x + n_y, n_x) splits). That product is enumerated exactly up to
    :data:`PERMUTATION_EXACT_LIMIT` splits (one task of 10 + 10 runs: 184,756; two tasks of
    3 + 3: 400); above it :data:`PERMUTATION_SAMPLES` random stratified splits are drawn (Monte
    Carlo; two tasks of 10 + 10 runs: 184,756^2 splits), the observed split counted in, so
    p >= 1 / (samples + 1). The result says which (:attr:`PermutationResult.method`).

    Args:
        x: scores [n_x, tasks] (or [n_x]).
        y: scores [n_y, tasks], the same tasks.
        rng: the generator (or seed) of the Monte-Carlo draws; the same seed gives the same
            p-values.

    Returns:
        The one-sided p of each direction and the two-sided p: each the fraction of splits
        whose statistic is at least as extreme as the observed one (the observed split
        included). With 3 + 3 runs on one task the smallest one-sided p is 1 / 20 = 0.05, the
        smallest two-sided 0.1.
    """
    a, b = _scores(x, "x"), _scores(y, "y")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"y: expected {a.shape[1]} tasks like x, got {b.shape[1]}")
    n_x, n_y, m = a.shape[0], b.shape[0], a.shape[1]
    pooled = np.concatenate([a, b], axis=0)  # [n, tasks]
    splits = _splits(n_x, n_y).astype(np.float64)  # [S, n]
    # per task and split: mean of the X group - mean of the Y group
    per_task = splits @ pooled / n_x - (1.0 - splits) @ pooled / n_y  # [S, tasks]
    observed = float((a.mean(0) - b.mean(0)).sum())
    total = splits.shape[0] ** m
    exact = total <= PERMUTATION_EXACT_LIMIT
    if exact:
        stat = np.zeros(1)
        for t in range(m):  # the sum over tasks for every combination of per-task splits
            stat = (stat[:, None] + per_task[None, :, t]).ravel()
        count = total
    else:
        gen = _rng(rng)
        pick = gen.integers(0, splits.shape[0], size=(PERMUTATION_SAMPLES, m))
        stat = np.concatenate([per_task[pick, np.arange(m)].sum(1), [observed]])
        count = PERMUTATION_SAMPLES
    eps = 1e-12 * max(1.0, abs(observed))
    return PermutationResult(
        greater=float((stat >= observed - eps).mean()),
        less=float((stat <= observed + eps).mean()),
        two_sided=float((np.abs(stat) >= abs(observed) - eps).mean()),
        exact=exact,
        count=count,
    )


def permutation_test(
    x: object,
    y: object,
    alternative: str = "greater",
    rng: np.random.Generator | int | None = 0,
) -> float:
    """p-value of a permutation test of X's runs against Y's, stratified by task (one of the
    p-values of :func:`permutation_tests`, which also says whether it was exact).

    Args:
        x: scores [n_x, tasks] (or [n_x]).
        y: scores [n_y, tasks], the same tasks.
        alternative: 'greater' (X > Y), 'less' or 'two-sided' (|statistic| as large).

    Returns:
        The p-value: the fraction of splits whose statistic is at least as extreme as the
        observed one (the observed split included). With 3 + 3 runs on one task the smallest
        one-sided p is 1 / 20 = 0.05.
    """
    if alternative not in ("greater", "less", "two-sided"):
        raise ValueError(
            f"alternative: expected 'greater', 'less' or 'two-sided', got {alternative!r}"
        )
    return permutation_tests(x, y, rng).p(alternative)


def holm(pvalues: object) -> np.ndarray:
    """Holm's step-down adjustment of a family of p-values (Holm 1979), the correction of the
    convention in docs/metrics.md.

    With the m p-values sorted ascending, p_(1) <= ... <= p_(m), the adjusted value of the i-th
    is ``max over j <= i of min(1, (m - j + 1) p_(j))``; each is returned in its input's place.
    A hypothesis is rejected at level alpha where its adjusted p <= alpha, which controls the
    family-wise error rate at alpha (``statsmodels.stats.multitest.multipletests(p,
    method='holm')[1]``). NaN entries (tests not made) stay NaN and do not count in m.

    Args:
        pvalues: the family's p-values, in [0, 1] (any shape; flattened).

    Returns:
        The adjusted p-values, same order, as float64 [m].
    """
    p = np.asarray(pvalues, dtype=np.float64).ravel()
    out = np.full(p.shape, np.nan)
    ok = ~np.isnan(p)
    if ((p[ok] < 0) | (p[ok] > 1)).any():
        raise ValueError(f"pvalues: expected values in [0, 1], got {p[ok].tolist()}")
    q = p[ok]
    m = len(q)
    if m == 0:
        return out
    order = np.argsort(q, kind="stable")
    scaled = np.minimum(1.0, (m - np.arange(m)) * q[order])
    adjusted = np.empty(m)
    adjusted[order] = np.maximum.accumulate(scaled)
    out[ok] = adjusted
    return out


def t_interval(values: object, conf: float = 0.95) -> tuple[float, float]:
    """Student-t interval of the mean of ``values`` [n] (n - 1 degrees of freedom); with one
    value the interval is that value."""
    from scipy import stats as sps

    v = _scores(values, "values")[:, 0]
    if len(v) == 1:
        return float(v[0]), float(v[0])
    half = float(sps.t.ppf(0.5 + conf / 2, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v)))
    return float(v.mean() - half), float(v.mean() + half)


def difference_t_interval(x: object, y: object, conf: float = 0.95) -> tuple[float, float]:
    """Welch's t-interval of the difference of means, X - Y, averaged over tasks.

    The difference is ``d = mean_t (mean(x[:, t]) - mean(y[:, t]))`` (the statistic of
    :func:`permutation_test`, divided by the task count). Its variance is
    ``sum_t (s2_xt / n_x + s2_yt / n_y) / m^2`` (sample variances, ddof 1) and its degrees of
    freedom the Welch-Satterthwaite approximation over the 2 m components, so with one task this
    is Welch's interval (``scipy.stats.ttest_ind(x, y, equal_var=False).confidence_interval``).

    Args:
        x: scores [n_x, tasks] (or [n_x]), n_x >= 2.
        y: scores [n_y, tasks], the same tasks, n_y >= 2.
        conf: the coverage, in (0, 1).

    Returns:
        (low, high); both equal to ``d`` when every group has zero variance.
    """
    from scipy import stats as sps

    a, b = _scores(x, "x"), _scores(y, "y")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"y: expected {a.shape[1]} tasks like x, got {b.shape[1]}")
    if a.shape[0] < 2 or b.shape[0] < 2:
        raise ValueError(f"x, y: expected 2 runs or more each, got {a.shape[0]} and {b.shape[0]}")
    if not 0.0 < conf < 1.0:
        raise ValueError(f"conf: expected a coverage in (0, 1), got {conf}")
    m = a.shape[1]
    d = float((a.mean(0) - b.mean(0)).mean())
    parts = np.concatenate([a.var(0, ddof=1) / a.shape[0], b.var(0, ddof=1) / b.shape[0]])
    dof = np.concatenate([np.full(m, a.shape[0] - 1.0), np.full(m, b.shape[0] - 1.0)])
    var = float(parts.sum())
    if var <= 0.0:
        return d, d
    df = var**2 / float((parts**2 / dof).sum())
    half = float(sps.t.ppf(0.5 + conf / 2, df)) * math.sqrt(var) / m
    return d - half, d + half


COVERAGE_FILE = "docs/results/bootstrap_coverage/bootstrap_coverage.json"
"""Where ``benchmarks/bootstrap_coverage.py`` wrote the coverages :data:`COVERAGE` quotes."""
COVERAGE = {
    "mean_bootstrap_n3": (73, 75),
    "mean_bootstrap_n3_skewed": (62, 68),
    "mean_t_n3": (91, 95),
    "mean_t_n3_skewed": (76, 84),
    "iqm_bootstrap_n3": (81, 84),
    "mean_bootstrap_n10": (89, 91),
    "iqm_bootstrap_n10": (92, 94),
}
"""Simulated coverage (percent, lowest to highest over the distributions) of the report's 95%
intervals, as :data:`COVERAGE_FILE` measured them: scores drawn from Betas fitted to the 10-seed
headline cells (``skewed``: the script's two reference Betas of mean 0.09); a test keeps these
numbers equal to the file's."""


def _pct(key: str) -> str:
    lo, hi = COVERAGE[key]
    return f"{lo}%" if lo == hi else f"{lo}-{hi}%"


COVERAGE_NOTE = (
    "With n seeds, the percentile bootstrap of a mean covers less than its nominal 95%: in "
    "simulation with scores like ours (`benchmarks/bootstrap_coverage.py`, "
    f"`{COVERAGE_FILE}`) {_pct('mean_bootstrap_n3')} per task at n = 3 "
    f"({_pct('mean_bootstrap_n3_skewed')} for strongly skewed scores of mean 0.09; "
    f"{_pct('mean_bootstrap_n10')} at n = 10) and {_pct('iqm_bootstrap_n3')} for the "
    f"stratified-bootstrap IQM over two tasks at n = 3; the t-interval covers "
    f"{_pct('mean_t_n3')} at n = 3 ({_pct('mean_t_n3_skewed')} skewed), at about 2.6 times the "
    "width. Read both; for 'is A ahead "
    "of B' read the permutation tests (docs/metrics.md, significance convention)."
)
"""The one-line note on interval coverage at few seeds that every condition table carries."""


def optimality_gap(scores: object, gamma: float = 1.0) -> float:
    """rliable's optimality gap (``rliable.metrics.aggregate_optimality_gap``): the mean over
    all runs of max(gamma - score, 0): how far the method is from solving every task (0: every
    run at gamma; lower is better)."""
    from rliable import metrics

    return float(metrics.aggregate_optimality_gap(_scores(scores), gamma))


def performance_profile(
    scores: dict[str, np.ndarray], taus: np.ndarray, reps: int = 2000
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """rliable's score distributions (``rliable.library.create_performance_profile``): for
    each method, the fraction of its runs (over tasks) scoring above each tau, and its
    stratified-bootstrap 95% band ([2, len(taus)])."""
    from rliable import library

    clean = {k: _scores(v) for k, v in scores.items()}
    prof, ci = library.create_performance_profile(clean, taus, reps=reps)
    return {k: np.asarray(v) for k, v in prof.items()}, {k: np.asarray(v) for k, v in ci.items()}


# the Wilson interval of a success rate lives with the model cards that report it (ndp.rl sits
# below ndp.experiments in the data flow); re-exported here with the other statistics
from ndp.rl.card import Z95 as Z95  # noqa: E402
from ndp.rl.card import wilson_interval as wilson_interval  # noqa: E402
