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

from ndp.rl.methods import Method, Settings, register_learner, with_networks
from ndp.rl.sac.config import SACConfig

SAC_METRICS = (
    "sac/alpha",
    "sac/alpha_loss",
    "sac/q",
    "sac/replay",
    "sac/gradient_steps",
)
"""Extra ``metrics.csv`` columns of the SAC family's runs (docs/metrics.md)."""

SAC_NETWORKS = ((256, 256), "relu")
"""SAC's networks (actor and each critic) unless ``--hidden`` / ``--activation`` are given."""

_SAC = "ndp.rl.sac.learner:SACLearner"
_SAC_HINT = "Try a smaller --sac-lr or check the task's reward."
_SAC_READS = ("sac",)  # and the run's fields; not its observation normaliser
_SAC_NDP_METRICS = (*SAC_METRICS, "dmp/goal_norm", "dmp/weight_norm")
register_learner(
    Settings("sac", SACConfig, "sac", "SAC, chunked SAC and NDP-SAC settings (--algo sac / "
             "sac-chunk / ndp-sac only)."),
    Method("sac", "squashed", "SAC: twin critics, automatic temperature, tanh-squashed "
           "Gaussian, one action per env step", resolve=with_networks(*SAC_NETWORKS, k=1),
           metrics=SAC_METRICS, learner=_SAC, hint=_SAC_HINT, reads=_SAC_READS),
    Method("sac-chunk", "squashed", "Chunked SAC: k actions per decision executed open-loop, "
           "a critic of the whole chunk on the k-step return (Q-chunking)",
           resolve=with_networks(*SAC_NETWORKS), metrics=SAC_METRICS, learner=_SAC,
           hint=_SAC_HINT, reads=_SAC_READS),
    Method("ndp-sac", "ndp-squashed", "NDP-SAC: SAC over the DMP's goal and forcing weights "
           "(entropy over the parameters), the NDP head turning them into k actions",
           resolve=with_networks(*SAC_NETWORKS, dmp=True), metrics=_SAC_NDP_METRICS,
           learner=_SAC, hint=_SAC_HINT, reads=_SAC_READS),
)  # fmt: skip
