r"""Generalised advantage estimation over the sub-step sequence of chunked decisions.

Decision t of env e runs up to k sub-steps j = 0..k-1. The critic gives k values per decision,
``V[t, j]`` = value of the state after j sub-steps (all estimated from decision t's
observation). The sub-steps form one sequence per env, (t, 0), (t, 1), ..., (t, k-1), (t+1, 0),
..., and GAE runs over it with per-sub-step gamma and lambda:

    next(t, j)   = V[t, j+1]                    for j < k - 1
                 = V[t+1, 0]                    for j = k - 1 (``last_values`` after the rollout)
    delta[t, j]  = r[t, j] + gamma * c[t, j] * next(t, j) - V[t, j]
    A[t, j]      = delta[t, j] + gamma * lambda * c[t, j] * A(next sub-step)

where ``c[t, j]`` = 0 at the last executed sub-step of a decision that ended its episode
(terminated OR truncated; the next decision belongs to a new episode) and 1 otherwise. Sub-steps
that did not run (``mask`` 0, after an early end) get A = 0 and are excluded from the losses.
Truncation is not termination: the trainer adds ``gamma * V(final observation)`` to the reward of
the last executed sub-step of a truncated episode, so it is bootstrapped while the chain to the
next (reset) decision is cut. Returns are ``A + V``.
"""

from __future__ import annotations

import numpy as np


def gae_substeps(
    rewards: np.ndarray,
    values: np.ndarray,
    masks: np.ndarray,
    ends: np.ndarray,
    last_values: np.ndarray,
    gamma: float,
    lam: float,
) -> tuple[np.ndarray, np.ndarray]:
    """GAE over chunked decisions (pure function; see the module docstring).

    Args:
        rewards: [T, E, k] sub-step rewards (0 where not executed).
        values: [T, E, k] value heads at each decision.
        masks: [T, E, k] 1 for executed sub-steps, 0 after an early end; executed sub-steps are
            a prefix of each decision.
        ends: [T, E] 1 where the episode ended (terminated or truncated) during the decision.
        last_values: [E] value (head 0) of the observation after the last decision.
        gamma: discount per sub-step.
        lam: GAE lambda per sub-step.

    Returns:
        ``(advantages, returns)``, each [T, E, k] float64, 0 where ``masks`` is 0.

    Raises:
        ValueError: inconsistent shapes.
    """
    r = np.asarray(rewards, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    m = np.asarray(masks, dtype=np.float64)
    end = np.asarray(ends, dtype=np.float64)
    last = np.asarray(last_values, dtype=np.float64)
    if r.ndim != 3 or v.shape != r.shape or m.shape != r.shape:
        raise ValueError(
            f"rewards, values, masks: expected equal shapes [T, E, k], got {r.shape}, "
            f"{v.shape}, {m.shape}"
        )
    t_len, n_env, k = r.shape
    if end.shape != (t_len, n_env) or last.shape != (n_env,):
        raise ValueError(
            f"ends: expected [T, E], last_values: expected [E]; got {end.shape}, {last.shape}"
        )
    # Next-sub-step values in sequence order.
    nxt = np.empty_like(v)
    nxt[:, :, :-1] = v[:, :, 1:]
    nxt[:-1, :, -1] = v[1:, :, 0]
    nxt[-1, :, -1] = last
    # Last executed sub-step of each decision: mask 1 and (next masked or j = k - 1).
    m_next = np.concatenate([m[:, :, 1:], np.zeros((t_len, n_env, 1))], axis=2)
    is_last = m * (1.0 - m_next)
    cont = 1.0 - is_last * end[:, :, None]  # c[t, j]
    delta = (r + gamma * cont * nxt - v) * m
    # Flatten to the sub-step sequence [T * k, E] and run the backward recursion.
    d_seq = delta.transpose(0, 2, 1).reshape(t_len * k, n_env)
    c_seq = (cont * m).transpose(0, 2, 1).reshape(t_len * k, n_env)
    adv_seq = np.zeros_like(d_seq)
    acc = np.zeros(n_env)
    gl = gamma * lam
    for i in range(t_len * k - 1, -1, -1):
        acc = d_seq[i] + gl * c_seq[i] * acc
        adv_seq[i] = acc
    adv = adv_seq.reshape(t_len, k, n_env).transpose(0, 2, 1) * m
    return adv, (adv + v) * m


def bootstrap_truncated(
    rewards: np.ndarray,
    masks: np.ndarray,
    boot: np.ndarray,
    final_values: np.ndarray,
    gamma: float,
) -> np.ndarray:
    """Add ``gamma * V(final obs)`` to the last executed sub-step of truncated episodes.

    Args:
        rewards: [E, k] one decision's (normalised) sub-step rewards.
        masks: [E, k] executed sub-steps (a non-empty prefix where ``boot``).
        boot: [E] bool, episodes truncated (time limit, unstable simulator) and NOT terminated.
        final_values: [n_boot] value (head 0) of each such episode's final observation, in the
            order of ``np.flatnonzero(boot)``.
        gamma: discount per sub-step.

    Returns:
        A new [E, k] array.
    """
    out = np.array(rewards, dtype=np.float64, copy=True)
    idx = np.flatnonzero(boot)
    if idx.size:
        last_j = np.asarray(masks)[idx].sum(1).astype(int) - 1
        out[idx, last_j] += gamma * np.asarray(final_values, dtype=np.float64)
    return out
