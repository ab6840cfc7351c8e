"""GAE over chunked decisions: hand-computed values, k = 1 reduction, truncation bootstrap."""

from __future__ import annotations

import numpy as np
import pytest

from ndp.rl.onpolicy.gae import bootstrap_truncated, gae_substeps

GAMMA, LAM = 0.9, 0.8


def test_gae_hand_computed_no_end():
    # T=2 decisions, E=1 env, k=2 sub-steps: sequence (0,0) (0,1) (1,0) (1,1), then last value.
    r = np.array([[[1.0, 2.0]], [[3.0, 4.0]]])
    v = np.array([[[0.5, 0.6]], [[0.7, 0.8]]])
    m = np.ones_like(r)
    ends = np.zeros((2, 1))
    adv, ret = gae_substeps(r, v, m, ends, np.array([1.0]), GAMMA, LAM)
    # deltas: 1 + .9*.6 - .5 = 1.04; 2 + .9*.7 - .6 = 2.03; 3 + .9*.8 - .7 = 3.02; 4 + .9 - .8 = 4.1
    # A(1,1) = 4.1; A(1,0) = 3.02 + .72*4.1 = 5.972; A(0,1) = 2.03 + .72*5.972 = 6.32984;
    # A(0,0) = 1.04 + .72*6.32984 = 5.5974848
    expected = np.array([[[5.5974848, 6.32984]], [[5.972, 4.1]]])
    np.testing.assert_allclose(adv, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ret, expected + v, atol=1e-12)


def test_gae_hand_computed_early_end_masks_and_cuts_chain():
    # Decision 0 ends its episode after sub-step 0 (sub-step 1 did not run).
    r = np.array([[[1.0, 0.0]], [[3.0, 4.0]]])
    v = np.array([[[0.5, 0.6]], [[0.7, 0.8]]])
    m = np.array([[[1.0, 0.0]], [[1.0, 1.0]]])
    ends = np.array([[1.0], [0.0]])
    adv, ret = gae_substeps(r, v, m, ends, np.array([1.0]), GAMMA, LAM)
    expected = np.array([[[0.5, 0.0]], [[5.972, 4.1]]])  # 1 - 0.5 with no bootstrap
    np.testing.assert_allclose(adv, expected, atol=1e-12)
    assert ret[0, 0, 1] == 0.0


def test_gae_end_at_last_substep_does_not_bootstrap_next_decision():
    r = np.array([[[1.0, 2.0]], [[3.0, 4.0]]])
    v = np.array([[[0.5, 0.6]], [[0.7, 0.8]]])
    ends = np.array([[1.0], [0.0]])
    adv, _ = gae_substeps(r, v, np.ones_like(r), ends, np.array([1.0]), GAMMA, LAM)
    # A(0,1) = 2 - 0.6 = 1.4 (episode over), A(0,0) = 1.04 + .72 * 1.4
    np.testing.assert_allclose(adv[0, 0], [1.04 + 0.72 * 1.4, 1.4], atol=1e-12)


def _naive_gae(r, v, m, ends, last, gamma, lam):
    """Independent reference: walk the flattened list of executed sub-steps per env."""
    t_len, n_env, _ = r.shape
    adv = np.zeros_like(r)
    for e in range(n_env):
        seq = []  # (t, j, is_episode_end)
        for t in range(t_len):
            n = int(m[t, e].sum())
            for j in range(n):
                seq.append((t, j, bool(ends[t, e]) and j == n - 1))
        a = 0.0
        for i in range(len(seq) - 1, -1, -1):
            t, j, end = seq[i]
            if end:
                nv, a_next = 0.0, 0.0
            elif i + 1 < len(seq):
                t2, j2, _ = seq[i + 1]
                nv, a_next = v[t2, e, j2], a
            else:
                nv, a_next = last[e], 0.0
            delta = r[t, e, j] + gamma * nv - v[t, e, j]
            a = delta + gamma * lam * a_next
            adv[t, e, j] = a
    return adv


@pytest.mark.parametrize("k", [1, 3, 5])
def test_gae_matches_naive_reference_random(k):
    rng = np.random.default_rng(k)
    t_len, n_env = 7, 3
    r = rng.normal(size=(t_len, n_env, k))
    v = rng.normal(size=(t_len, n_env, k))
    ends = (rng.random((t_len, n_env)) < 0.3).astype(float)
    m = np.ones((t_len, n_env, k))
    for t in range(t_len):
        for e in range(n_env):
            if ends[t, e]:
                m[t, e, rng.integers(1, k + 1) :] = 0.0
    r *= m
    last = rng.normal(size=n_env)
    adv, _ = gae_substeps(r, v, m, ends, last, 0.97, 0.9)
    np.testing.assert_allclose(adv, _naive_gae(r, v, m, ends, last, 0.97, 0.9), atol=1e-10)


def test_gae_k1_equals_standard_recursion():
    rng = np.random.default_rng(0)
    t_len = 6
    r, v = rng.normal(size=t_len), rng.normal(size=t_len)
    done = np.array([0, 0, 1, 0, 0, 0], dtype=float)
    last = 0.3
    adv = np.zeros(t_len)
    a = 0.0
    for t in reversed(range(t_len)):
        nv = last if t == t_len - 1 else v[t + 1]
        nonterm = 1.0 - done[t]
        delta = r[t] + GAMMA * nv * nonterm - v[t]
        a = delta + GAMMA * LAM * nonterm * a
        adv[t] = a
    got, _ = gae_substeps(
        r[:, None, None],
        v[:, None, None],
        np.ones((t_len, 1, 1)),
        done[:, None],
        np.array([last]),
        GAMMA,
        LAM,
    )
    np.testing.assert_allclose(got[:, 0, 0], adv, atol=1e-12)


def test_bootstrap_truncated_only_on_truncation():
    r = np.zeros((3, 4))
    m = np.array([[1, 1, 0, 0], [1, 1, 1, 1], [1, 1, 1, 1]], dtype=float)
    boot = np.array([True, False, True])  # env 1 terminated (or still running): no bootstrap
    out = bootstrap_truncated(r, m, boot, np.array([2.0, -1.0]), 0.5)
    expected = np.zeros((3, 4))
    expected[0, 1] = 1.0  # last executed sub-step of env 0
    expected[2, 3] = -0.5
    np.testing.assert_allclose(out, expected)
    assert r.sum() == 0.0  # input untouched


def test_gae_rejects_bad_shapes():
    with pytest.raises(ValueError, match="rewards"):
        gae_substeps(
            np.zeros((2, 1, 3)),
            np.zeros((2, 1, 2)),
            np.zeros((2, 1, 3)),
            np.zeros((2, 1)),
            np.zeros(1),
            0.9,
            0.9,
        )
