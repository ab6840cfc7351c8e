"""TD3 (Fujimoto, van Hoof, Meger, "Addressing Function Approximation Error in Actor-Critic
Methods", ICML 2018), one package: twin critics with the clipped double-Q target, target
policy smoothing, delayed actor and target updates, Gaussian exploration on a deterministic
tanh-bounded actor; one action per env step (k = 1).

- :mod:`ndp.rl.td3.config`: :class:`ndp.rl.td3.config.TD3Config`, the settings (``--td3-*``);
- :mod:`ndp.rl.td3.losses`: the pure functions, with stated tensor shapes;
- :mod:`ndp.rl.td3.learner`: :class:`ndp.rl.td3.learner.TD3Learner` on the shared off-policy
  loop (:mod:`ndp.rl.offpolicy.loop`).

This module registers the settings section ``td3`` and the method ``td3`` with one
:func:`ndp.rl.methods.register_learner` call and imports no torch. docs/offpolicy.md, "TD3",
has the maths, the defaults with their sources and the deviations.
"""

from __future__ import annotations

from ndp.rl.methods import Method, Settings, register_learner, with_networks
from ndp.rl.td3.config import TD3Config

TD3_METRICS = ("td3/q", "td3/replay", "td3/gradient_steps", "td3/actor_updates")
"""Extra ``metrics.csv`` columns of TD3 runs (docs/metrics.md)."""

register_learner(
    Settings("td3", TD3Config, "td3", "TD3 settings (--algo td3 only)."),
    Method("td3", "squashed", "TD3: twin critics, clipped double-Q, target smoothing, delayed "
           "actor updates, Gaussian exploration; one action per env step",
           resolve=with_networks((400, 300), "relu", k=1),  # SB3's net_arch for TD3, the paper's
           metrics=TD3_METRICS, learner="ndp.rl.td3.learner:TD3Learner",
           hint="Try a smaller --td3-lr or check the task's reward.", reads=("td3",)),
)  # fmt: skip
