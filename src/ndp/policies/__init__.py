"""Policies: action heads (step / multi / ndp), the k-head critic, exploration distributions.

PPO, PPO-multi and NDP share one :class:`ActorCritic`; they differ only in the action head
(:mod:`ndp.policies.heads`).
"""

from typing import Any

_EXPORTS = {
    "ActorCritic": "actor_critic",
    "build_actor_critic": "actor_critic",
    "HEADS": "config",
    "PolicyConfig": "config",
    "NDPHeadConfig": "config",
    "ParamGaussian": "distributions",
    "PolicyDistribution": "distributions",
    "SubActionGaussian": "distributions",
    "diag_gaussian_entropy": "distributions",
    "diag_gaussian_log_prob": "distributions",
    "ActionHead": "heads",
    "MultiHead": "heads",
    "NDPHead": "heads",
    "StepHead": "heads",
    "build_head": "heads",
}


def __getattr__(name: str) -> Any:
    """Import the sub-module of an exported name on first use (the configs import without
    torch, so command-line parsers stay fast)."""
    if name in _EXPORTS:
        import importlib

        return getattr(importlib.import_module(f"ndp.policies.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'ndp.policies' has no attribute {name!r}")


__all__ = [
    "HEADS",
    "ActionHead",
    "ActorCritic",
    "MultiHead",
    "NDPHead",
    "NDPHeadConfig",
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
