"""The paired sign-flip test (ndp.experiments.report.paired) against a hand count and SciPy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from ndp.experiments.report.paired import paired_pooled, paired_sign_flip


def test_hand_counted_example():
    # d = (1, 2, 3, 4): |mean| >= 2.5 only for all-plus and all-minus: p = 2 / 16
    r = paired_sign_flip([1, 2, 3, 4], [0, 0, 0, 0])
    assert r.diff == 2.5 and r.p == pytest.approx(2 / 16) and r.n_pairs == 4
    assert r.method.startswith("exact sign-flip (all 2^4 = 16 patterns)")


def test_agrees_with_scipy_permutation_test_on_samples():
    rng = np.random.default_rng(3)
    a, b = rng.beta(2, 5, 10), rng.beta(2, 4, 10)
    ours = paired_sign_flip(a, b)
    ref = stats.permutation_test(
        (a, b), lambda x, y: np.mean(x - y), permutation_type="samples",
        alternative="two-sided", n_resamples=np.inf,
    )  # fmt: skip
    assert ours.p == pytest.approx(ref.pvalue, abs=1e-12)


def test_pooled_is_the_one_task_test_for_one_task_and_counts_pairs():
    a, b = [0.3, 0.5, 0.1, 0.7], [0.2, 0.1, 0.0, 0.4]
    one = paired_sign_flip(a, b)
    pooled = paired_pooled({"t": (a, b)})
    assert pooled.p == pytest.approx(one.p) and pooled.diff == pytest.approx(one.diff)
    two = paired_pooled({"t": (a, b), "u": ([1.0, 1.0], [0.0, 0.0])})
    assert two.n_pairs == 6 and two.diff == pytest.approx((one.diff + 1.0) / 2)


def test_many_pairs_are_sampled_and_bad_input_refused():
    r = paired_sign_flip(np.ones(25), np.zeros(25))
    assert r.method.startswith("Monte-Carlo sign-flip (100,000 resamples)") and r.p < 1e-3
    with pytest.raises(ValueError, match="a, b: expected two"):
        paired_sign_flip([1, 2], [1, 2, 3])
    with pytest.raises(ValueError, match="a, b: expected finite scores"):
        paired_sign_flip([1, float("nan")], [0, 0])
