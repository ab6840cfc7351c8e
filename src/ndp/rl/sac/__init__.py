"""The SAC family, one package: SAC (k = 1), chunked SAC (k actions per decision, a critic of
the whole chunk trained on the k-step return: the Q-chunking recipe) and NDP-SAC (the actor
emits the DMP's goal and forcing weights; the NDP head turns them into the k-step actions).

- :mod:`ndp.rl.sac.config`: :class:`ndp.rl.sac.config.SACConfig`, every setting typed and
  documented;
- :mod:`ndp.rl.sac.losses`: the pure functions (chunk return, target, the three losses), with
  stated tensor shapes;
- :mod:`ndp.rl.sac.replay`: the decision replay buffer (saved with the checkpoint);
- :mod:`ndp.rl.sac.learner`: :class:`ndp.rl.sac.learner.SACLearner`, an
  :class:`ndp.rl.run.RLLearner` that the run driver opens, seeds, drives and checkpoints.

This module registers the settings section ``sac`` (``TrainConfig.sac``, options ``--sac-*``)
and the methods ``sac``, ``sac-chunk``, ``ndp-sac`` (with the heads of
:mod:`ndp.policies.squashed`) in one :func:`ndp.rl.methods.register_learner` call; importing it
imports no torch (the learner is named by entry point). docs/offpolicy.md has the maths and the
defaults.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ndp.policies.config import PolicyConfig
from ndp.rl.methods import (
    OFF_POLICY_PPO_READS,
    Method,
    PolicyChanges,
    Settings,
    networks,
    no_dmp,
    register_learner,
    resolve_ndp,
)
from ndp.rl.sac.config import SACConfig

SAC_METRICS = (
    "sac/alpha",
    "sac/alpha_loss",
    "sac/q",
    "sac/replay",
    "sac/gradient_steps",
)

if TYPE_CHECKING:
    from ndp.schema import TaskSchema
"""Extra ``metrics.csv`` columns of the SAC family's runs (docs/metrics.md)."""


def _sac_networks(policy: PolicyConfig) -> PolicyChanges:
    """SAC's networks: 256-256 ReLU (actor and each critic) unless ``hidden`` / ``activation``
    are given."""
    return networks(policy, (256, 256), "relu")


def resolve_sac(policy: PolicyConfig, spec: TaskSchema) -> PolicyChanges:
    """SAC: one action per decision (k = 1), no DMP, 256-256 ReLU."""
    return {**no_dmp(policy, spec), **_sac_networks(policy), "k": 1}


def resolve_sac_chunk(policy: PolicyConfig, spec: TaskSchema) -> PolicyChanges:
    """Chunked SAC: k actions per decision (``--k``), no DMP, 256-256 ReLU."""
    return {**no_dmp(policy, spec), **_sac_networks(policy)}


def resolve_ndp_sac(policy: PolicyConfig, spec: TaskSchema) -> PolicyChanges:
    """NDP-SAC: the NDP head's task presets (:func:`ndp.rl.methods.resolve_ndp`), 256-256
    ReLU."""
    return {**resolve_ndp(policy, spec), **_sac_networks(policy)}


_SAC = "ndp.rl.sac.learner:SACLearner"
_SAC_HINT = "Try a smaller --sac-lr or check the task's reward."
_SAC_READS = ("sac", *OFF_POLICY_PPO_READS)
register_learner(
    Settings("sac", SACConfig, "sac", "SAC, chunked SAC and NDP-SAC settings (--algo sac / "
             "sac-chunk / ndp-sac only)."),
    Method("sac", "squashed", "SAC: twin critics, automatic temperature, tanh-squashed "
           "Gaussian, one action per env step", resolve=resolve_sac, metrics=SAC_METRICS,
           learner=_SAC, hint=_SAC_HINT, reads=_SAC_READS),
    Method("sac-chunk", "squashed", "Chunked SAC: k actions per decision executed open-loop, "
           "a critic of the whole chunk on the k-step return (Q-chunking)",
           resolve=resolve_sac_chunk, metrics=SAC_METRICS, learner=_SAC, hint=_SAC_HINT,
           reads=_SAC_READS),
    Method("ndp-sac", "ndp-squashed", "NDP-SAC: SAC over the DMP's goal and forcing weights "
           "(entropy over the parameters), the NDP head turning them into k actions",
           resolve=resolve_ndp_sac, metrics=(*SAC_METRICS, "dmp/goal_norm", "dmp/weight_norm"),
           learner=_SAC, hint=_SAC_HINT, reads=_SAC_READS),
)  # fmt: skip
