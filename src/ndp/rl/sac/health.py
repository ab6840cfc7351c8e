"""Critic health: when a SAC-family critic's value estimate has left the range of the returns.

A decision's soft value is a discounted partial return plus an entropy bonus; while the critics
track it, their mean estimate stays near or below the largest episode return the run has seen.
An estimate many times above it is a critic bootstrapping on its own errors (the runaway that
ends in a temperature far above its start: docs/offpolicy.md, "Critic health"). The learner
says so on stderr once per session (:class:`ndp.rl.sac.learner.SACLearner`), and the
``off-policy`` report flags such runs (:func:`ndp.experiments.report.offpolicy.critic_health`).
"""

from __future__ import annotations

import math

Q_RUNAWAY = 10.0
"""A mean value estimate above this many times the largest mean training-episode return is a
runaway (the return taken as at least 1, so that a run near zero return is not flagged for an
estimate of a few units)."""


def q_runaway(q: float, return_peak: float) -> bool:
    """True where the critics' mean value estimate ``q`` is above :data:`Q_RUNAWAY` times
    ``max(|return_peak|, 1)`` (``return_peak``: the largest mean training-episode return so
    far); False for a NaN estimate (no gradient step yet)."""
    return math.isfinite(q) and q > Q_RUNAWAY * max(abs(return_peak), 1.0)
