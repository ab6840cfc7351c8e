"""Policies: action heads (step / multi / ndp), the k-head critic, exploration distributions.

PPO, PPO-multi and NDP share one :class:`ActorCritic`; they differ only in the action head
(:mod:`ndp.policies.heads`).
"""

from ndp.policies.actor_critic import ActorCritic, build_actor_critic
from ndp.policies.config import HEADS, PolicyConfig
from ndp.policies.distributions import (
    ParamGaussian,
    PolicyDistribution,
    SubActionGaussian,
    diag_gaussian_entropy,
    diag_gaussian_log_prob,
)
from ndp.policies.heads import ActionHead, MultiHead, NDPHead, StepHead, build_head

__all__ = [
    "HEADS",
    "ActionHead",
    "ActorCritic",
    "MultiHead",
    "NDPHead",
    "ParamGaussian",
    "PolicyConfig",
    "PolicyDistribution",
    "StepHead",
    "SubActionGaussian",
    "build_actor_critic",
    "build_head",
    "diag_gaussian_entropy",
    "diag_gaussian_log_prob",
]
