"""The rliable protocol (ndp.experiments.report.stats) against hand-computed cases and rliable's own
numbers."""

from __future__ import annotations

import numpy as np
import pytest

from ndp.experiments.report import stats as S

# rliable 1.2.0 on these scores (runs x tasks): metrics.aggregate_iqm -> 0.544,
# metrics.probability_of_improvement(X, Y) -> 0.7037037; library.get_interval_estimates with
# 20,000 replicates -> IQM CI [0.392, 0.764], P(X > Y) CI [0.4444, 0.9259].
X = np.array([[0.51, 0.95, 0.14], [0.95, 0.31, 0.42], [0.83, 0.41, 0.55]])
Y = np.array([[0.03, 0.75, 0.54], [0.33, 0.79, 0.3], [0.45, 0.13, 0.4]])


def test_iqm_by_hand():
    # 8 values: drop 2 at each end, mean of the middle 4
    assert S.iqm([1, 2, 3, 4, 5, 6, 7, 100]) == pytest.approx(4.5)
    # 9 values: floor(9 / 4) = 2 dropped at each end, mean of the middle 5
    assert S.iqm(np.arange(9.0)) == pytest.approx(4.0)
    assert S.iqm([[0.0, 1.0], [1.0, 1.0]]) == pytest.approx(1.0)  # 4 values: the middle 2
    assert S.iqm([0.3]) == pytest.approx(0.3)


def test_probability_of_improvement_by_hand():
    # one task: x runs {1, 2}, y runs {1, 0}: pairs (1>1 tie, 1>0, 2>1, 2>0) -> (0.5 + 3) / 4
    assert S.probability_of_improvement([[1.0], [2.0]], [[1.0], [0.0]]) == pytest.approx(0.875)
    # two tasks: X always better on task 0, always worse on task 1 -> 0.5
    x = np.array([[1.0, 0.0], [1.0, 0.0]])
    y = np.array([[0.0, 1.0], [0.0, 1.0]])
    assert S.probability_of_improvement(x, y) == pytest.approx(0.5)
    assert S.probability_of_improvement(x, x) == pytest.approx(0.5)  # all ties


def test_matches_rliable():
    assert S.iqm(X) == pytest.approx(0.544)
    assert S.probability_of_improvement(X, Y) == pytest.approx(0.7037037, abs=1e-7)
    lo, hi = S.stratified_bootstrap_ci(X, S.iqm, reps=20000)
    assert lo == pytest.approx(0.392, abs=0.01) and hi == pytest.approx(0.764, abs=0.01)
    lo, hi = S.probability_of_improvement_ci(X, Y, reps=20000)
    assert lo == pytest.approx(0.4444, abs=0.02) and hi == pytest.approx(0.9259, abs=0.02)


def test_bootstrap_ci_of_the_mean():
    lo, hi = S.bootstrap_ci([0.0, 1.0], reps=20000)
    assert (lo, hi) == (0.0, 1.0)  # resamples of 2 values: means 0, 0.5, 1
    assert S.bootstrap_ci([0.4]) == (0.4, 0.4)
    lo, hi = S.bootstrap_ci([0.2, 0.2, 0.2])
    assert lo == hi == pytest.approx(0.2)
    v = np.random.default_rng(0).normal(0.5, 0.1, 200)
    lo, hi = S.bootstrap_ci(v)
    half = 1.96 * v.std() / np.sqrt(len(v))  # the normal interval of a large sample
    assert lo == pytest.approx(v.mean() - half, abs=0.005)
    assert hi == pytest.approx(v.mean() + half, abs=0.005)
    assert S.bootstrap_ci(v, rng=3) == S.bootstrap_ci(v, rng=3)  # seeded: reproducible


def test_stratified_bootstrap_keeps_tasks_apart():
    # every run of task 0 scores 0 and of task 1 scores 1: any replicate has mean 0.5
    x = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0]])
    assert S.stratified_bootstrap_ci(x, S.mean) == (0.5, 0.5)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="scores: expected finite values"):
        S.iqm([0.1, np.nan])
    with pytest.raises(ValueError, match="y: expected 3 tasks like x, got 2"):
        S.probability_of_improvement(X, Y[:, :2])
    with pytest.raises(ValueError, match="scores: expected an array"):
        S.iqm(np.zeros((0, 2)))


# ------------------------------------------------------------------ permutation test, t, rliable


def test_permutation_test_by_hand_one_task():
    """3 + 3 runs: 20 splits. X = {4, 5, 6} beats Y = {1, 2, 3} in every pair: only the observed
    split is as extreme, p = 1 / 20 one-sided, 2 / 20 two-sided."""
    x, y = [[4.0], [5.0], [6.0]], [[1.0], [2.0], [3.0]]
    assert S.permutation_test(x, y) == pytest.approx(1 / 20)
    assert S.permutation_test(x, y, "two-sided") == pytest.approx(2 / 20)
    assert S.permutation_test(x, y, "less") == pytest.approx(1.0)
    # identical groups: every split is as extreme as the observed 0 difference
    assert S.permutation_test([[1.0], [1.0]], [[1.0], [1.0]]) == pytest.approx(1.0)


def test_permutation_test_is_stratified_by_task():
    """Two tasks, X ahead by the same margin on both: only the observed split of each task is as
    extreme, p = 1 / 20^2; a task on which X is far ahead cannot make up a task mixed across
    seeds (labels are only exchanged within a task)."""
    x = np.array([[4.0, 14.0], [5.0, 15.0], [6.0, 16.0]])
    y = np.array([[1.0, 11.0], [2.0, 12.0], [3.0, 13.0]])
    assert S.permutation_test(x, y) == pytest.approx(1 / 400)
    # against an unstratified test, pooling both tasks would not be exchangeable; check a
    # brute-force enumeration of the stratified splits on a small random case
    rng = np.random.default_rng(3)
    a, b = rng.random((2, 2)), rng.random((3, 2))
    import itertools

    stats = []
    for s0 in itertools.combinations(range(5), 2):
        for s1 in itertools.combinations(range(5), 2):
            tot = 0.0
            for t, sel in enumerate((s0, s1)):
                pool = np.concatenate([a[:, t], b[:, t]])
                m = np.zeros(5, bool)
                m[list(sel)] = True
                tot += pool[m].mean() - pool[~m].mean()
            stats.append(tot)
    obs = float((a.mean(0) - b.mean(0)).sum())
    want = np.mean(np.array(stats) >= obs - 1e-12)
    assert S.permutation_test(a, b) == pytest.approx(want)


def test_permutation_test_monte_carlo_above_the_exact_limit(monkeypatch):
    monkeypatch.setattr(S, "PERMUTATION_EXACT_LIMIT", 10)
    x = np.array([[4.0, 14.0], [5.0, 15.0], [6.0, 16.0]])
    y = np.array([[1.0, 11.0], [2.0, 12.0], [3.0, 13.0]])
    p = S.permutation_test(x, y, rng=0)
    assert 1 / (S.PERMUTATION_SAMPLES + 1) <= p < 0.003  # exact: 1/400
    with pytest.raises(ValueError, match="alternative: expected"):
        S.permutation_test(x, y, "bigger")


def test_permutation_tests_label_exact_and_monte_carlo(monkeypatch):
    """One reference distribution gives both one-sided p and the two-sided p, and says how it
    was computed: all 20 splits of 3 + 3 runs on one task, all 400 over two tasks; above the
    exact limit a Monte-Carlo test of PERMUTATION_SAMPLES resamples."""
    x, y = [[4.0], [5.0], [6.0]], [[1.0], [2.0], [3.0]]
    r = S.permutation_tests(x, y)
    assert (r.greater, r.less, r.two_sided) == pytest.approx((1 / 20, 1.0, 2 / 20))
    assert r.exact and r.count == 20 and r.method == "exact permutation (all 20 splits)"
    assert r.p("two-sided") == S.permutation_test(x, y, "two-sided")
    x2 = np.array([[4.0, 14.0], [5.0, 15.0], [6.0, 16.0]])
    y2 = np.array([[1.0, 11.0], [2.0, 12.0], [3.0, 13.0]])
    r2 = S.permutation_tests(x2, y2)
    assert r2.method == "exact permutation (all 400 splits)" and r2.two_sided == pytest.approx(
        2 / 400
    )
    # 10 + 10 runs on one task: C(20, 10) = 184,756 splits, enumerated; on two tasks sampled
    a, b = np.arange(10.0)[:, None] + 0.5, np.arange(10.0)[:, None]
    assert S.permutation_tests(a, b).method == "exact permutation (all 184,756 splits)"
    monkeypatch.setattr(S, "PERMUTATION_SAMPLES", 2000)
    mc = S.permutation_tests(np.hstack([a, a]), np.hstack([b, b]))
    assert not mc.exact and mc.method == "Monte-Carlo permutation (2,000 resamples)"
    assert mc == S.permutation_tests(np.hstack([a, a]), np.hstack([b, b]))  # seeded


def test_holm_by_hand_and_against_statsmodels():
    """Holm's step-down: sorted p 0.005, 0.01, 0.03, 0.04 times 4, 3, 2, 1 = 0.02, 0.03, 0.06,
    0.04, then the running maximum: 0.02, 0.03, 0.06, 0.06, each back in its place."""
    p = [0.01, 0.04, 0.03, 0.005]
    np.testing.assert_allclose(S.holm(p), [0.03, 0.06, 0.06, 0.02])
    np.testing.assert_allclose(S.holm([0.5, 0.6]), [1.0, 1.0])  # capped at 1
    np.testing.assert_allclose(S.holm([0.04]), [0.04])  # a family of one: unchanged
    assert S.holm([]).shape == (0,)
    out = S.holm([0.01, np.nan, 0.04])  # NaN: a test not made, not counted in m
    assert np.isnan(out[1]) and out[[0, 2]] == pytest.approx([0.02, 0.04])
    with pytest.raises(ValueError, match="pvalues: expected values in"):
        S.holm([0.1, 1.5])
    multitest = pytest.importorskip("statsmodels.stats.multitest")
    rng = np.random.default_rng(0)
    for m in (2, 3, 7, 15):
        q = rng.random(m) ** 3  # some small, some ties after rounding
        q[rng.integers(0, m)] = q[0]
        np.testing.assert_allclose(S.holm(q), multitest.multipletests(q, method="holm")[1])


def test_t_interval_by_hand():
    # mean 2, sample std 1, n 3: half width t(0.975, 2) / sqrt(3) = 4.302653 / 1.732051
    lo, hi = S.t_interval([1.0, 2.0, 3.0])
    assert (lo + hi) / 2 == pytest.approx(2.0)
    assert (hi - lo) / 2 == pytest.approx(4.302653 / np.sqrt(3), rel=1e-6)
    assert S.t_interval([0.4]) == (0.4, 0.4)


def test_difference_t_interval_is_welchs_on_one_task():
    # x: mean 2, var 1; y: mean 0, var 4 (n 3 each): se^2 = 1/3 + 4/3, Welch df = 50/17
    x, y = [1.0, 2.0, 3.0], [-2.0, 0.0, 2.0]
    lo, hi = S.difference_t_interval(x, y)
    from scipy import stats as sps

    half = sps.t.ppf(0.975, 50 / 17) * np.sqrt(5 / 3)
    assert (lo, hi) == pytest.approx((2.0 - half, 2.0 + half), rel=1e-9)
    ref = sps.ttest_ind(x, y, equal_var=False).confidence_interval(0.95)
    assert (lo, hi) == pytest.approx((ref.low, ref.high), rel=1e-9)


def test_difference_t_interval_stratified_by_task():
    # a second task with no spread adds its difference and halves the first task's standard
    # error (the mean over 2 tasks), with the same degrees of freedom
    x1, y1 = np.array([1.0, 2.0, 3.0]), np.array([-2.0, 0.0, 2.0])
    lo1, hi1 = S.difference_t_interval(x1, y1)
    x = np.stack([x1, np.full(3, 0.5)], axis=1)
    y = np.stack([y1, np.full(3, 0.1)], axis=1)
    lo, hi = S.difference_t_interval(x, y)
    assert (lo + hi) / 2 == pytest.approx((2.0 + 0.4) / 2)
    assert (hi - lo) == pytest.approx((hi1 - lo1) / 2, rel=1e-9)
    assert S.difference_t_interval(np.ones((3, 2)), np.zeros((4, 2))) == (1.0, 1.0)
    with pytest.raises(ValueError, match="x, y: expected 2 runs or more"):
        S.difference_t_interval([1.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="conf: expected"):
        S.difference_t_interval(x, y, conf=95)


def test_difference_t_interval_covers_near_nominal():
    # normal scores, unequal variances, 10 + 10 runs on 2 tasks: about 95% of intervals hold
    # the true difference (0.1 per task); 2,000 draws give a standard error of 0.005
    rng = np.random.default_rng(0)
    hits = 0
    for _ in range(2000):
        x = rng.normal(0.3, [0.1, 0.2], size=(10, 2))
        y = rng.normal(0.2, [0.3, 0.05], size=(10, 2))
        lo, hi = S.difference_t_interval(x, y)
        hits += lo <= 0.1 <= hi
    assert 0.93 <= hits / 2000 <= 0.97


def test_optimality_gap_and_performance_profile_from_rliable():
    # gap: mean of max(1 - score, 0) over all runs
    assert S.optimality_gap([[1.0, 0.5], [0.0, 1.2]]) == pytest.approx((0 + 0.5 + 1.0 + 0) / 4)
    prof, ci = S.performance_profile({"a": X}, np.array([0.0, 0.5, 1.0]), reps=200)
    # fraction of the 9 runs above tau: all above 0, 5 of 9 above 0.5, none above 1
    np.testing.assert_allclose(prof["a"], [1.0, 5 / 9, 0.0])
    assert ci["a"].shape == (2, 3)


def test_the_coverage_note_quotes_the_measured_coverages():
    """stats.COVERAGE (and the note every condition table carries) holds the numbers
    benchmarks/bootstrap_coverage.py wrote, rounded to percent, lowest to highest."""
    import json
    from pathlib import Path

    path = Path(__file__).resolve().parents[3] / S.COVERAGE_FILE
    if not path.is_file():
        pytest.skip("the results folder is not in this checkout")
    got = json.loads(path.read_text())
    mean3, mean10 = got["mean"]["3"], got["mean"]["10"]
    skewed = [r["bootstrap"] for r in mean3["reference"].values()]
    skewed_t = [r["t"] for r in mean3["reference"].values()]

    def pct(lo, hi):
        return (round(100 * lo), round(100 * hi))

    measured = {
        "mean_bootstrap_n3": pct(mean3["bootstrap"]["min"], mean3["bootstrap"]["max"]),
        "mean_bootstrap_n3_skewed": pct(min(skewed), max(skewed)),
        "mean_t_n3": pct(mean3["t"]["min"], mean3["t"]["max"]),
        "mean_t_n3_skewed": pct(min(skewed_t), max(skewed_t)),
        "iqm_bootstrap_n3": pct(got["iqm"]["3"]["bootstrap"]["min"],
                                got["iqm"]["3"]["bootstrap"]["max"]),
        "mean_bootstrap_n10": pct(mean10["bootstrap"]["min"], mean10["bootstrap"]["max"]),
        "iqm_bootstrap_n10": pct(got["iqm"]["10"]["bootstrap"]["min"],
                                 got["iqm"]["10"]["bootstrap"]["max"]),
    }  # fmt: skip
    assert measured == S.COVERAGE
    assert "73-75% per task at n = 3" in S.COVERAGE_NOTE and "76%" not in S.COVERAGE_NOTE
