"""The rliable protocol (ndp.experiments.stats) against hand-computed cases and rliable's own
numbers."""

from __future__ import annotations

import numpy as np
import pytest

from ndp.experiments import stats as S

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
