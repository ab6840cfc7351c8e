"""Dyn-E (Whitney et al., ICLR 2020), one package: TD3 acting in a learned, dynamics-aware
embedding of k-action sequences.

- :mod:`ndp.rl.dyne.config`: :class:`ndp.rl.dyne.config.DyneConfig`, the settings;
- :mod:`ndp.rl.dyne.learner`: :class:`ndp.rl.dyne.learner.DyneLearner` and the embedding's
  training (torch; its names are also reachable here, ``ndp.rl.dyne.DyneLearner``, imported on
  first use).

This module registers the settings section ``dyne`` and the method ``dyne`` in one
:func:`ndp.rl.methods.register_learner` call and imports no torch. docs/dyne.md has the maths,
the defaults and the deviations.
"""

from __future__ import annotations

from typing import Any

from ndp.rl.dyne.config import DyneConfig
from ndp.rl.methods import Method, Settings, register_learner, with_networks

DYNE_METRICS = (
    "dyne/embed_loss",
    "dyne/embed_kl",
    "dyne/decoder_loss",
    "dyne/q",
    "dyne/replay",
    "dyne/gradient_steps",
)
"""Extra ``metrics.csv`` columns of Dyn-E runs (docs/metrics.md)."""

register_learner(
    Settings("dyne", DyneConfig, "", "Dyn-E settings (--algo dyne only)."),
    Method(
        "dyne",
        "dyne",
        "Dyn-E: TD3 in a learned, dynamics-aware embedding of k-action sequences",
        resolve=with_networks((400, 300), "relu"),  # the original's TD3 actor
        metrics=DYNE_METRICS,
        learner="ndp.rl.dyne:DyneLearner",  # torch and the simulators only once it trains
        hint="Try smaller --actor-lr / --critic-lr or check the task's reward.",
        reads=("dyne", "norm_obs"),
    ),
)


def __getattr__(name: str) -> Any:
    """The learner module's names (``DyneLearner``, ``resolve_dyne_config``, ...), imported on
    first use so that registering Dyn-E imports no torch."""
    import importlib

    learner = importlib.import_module("ndp.rl.dyne.learner")
    try:
        return getattr(learner, name)
    except AttributeError:
        raise AttributeError(f"module 'ndp.rl.dyne' has no attribute {name!r}") from None
