"""The named studies of ``ndp sweep STUDY`` (docs/experiments.md describes each).

Each study is a declarative :class:`Study` entry (its tasks, arms, seeds, budget, conditions,
selection and readings) in the ``STUDIES`` tuple of one module per study family:

- :mod:`ndp.experiments.studies.paper`: the paper's five tasks, MT50, the ablations;
- :mod:`ndp.experiments.studies.release`: the 2021 release's conditions;
- :mod:`ndp.experiments.studies.sb3`: the checks against Stable-Baselines3;
- :mod:`ndp.experiments.studies.offpolicy`: SAC, chunked SAC, NDP-SAC;
- :mod:`ndp.experiments.studies.regimes` and :mod:`ndp.experiments.studies.mechanism`:
  where NDP can win and why it loses;
- :mod:`ndp.experiments.studies.imitation`: behaviour cloning and digit writing.

Adding a study is one entry in one of those tuples (:data:`LIST_ORDER` places it in
``ndp sweep --list``; a study it does not name comes after those it names, in module order).
A study's readings are an entry point ``"module:function"`` resolved when the report calls
them (:func:`resolve`), so no study module imports the report or the sweep, and importing
this package imports neither torch nor a simulator.
"""

from __future__ import annotations

import difflib

from ndp.experiments.studies import imitation, mechanism, offpolicy, paper, regimes, release, sb3
from ndp.experiments.studies.base import ArmSpec, Condition, Readings, Study, resolve
from ndp.experiments.studies.imitation import (
    BC_DEMOS,
    BC_TASKS,
    CONVERGED_ARGS,
    CONVERGED_LRS,
    CONVERGED_MODELS,
    DIGITS_TASKS,
    HEAD_LRS,
    HEADS,
)
from ndp.experiments.studies.mechanism import LIVE, MECHANISM_BASES, MECHANISM_TASKS
from ndp.experiments.studies.offpolicy import (
    OFF_POLICY_CONDITIONS,
    OFF_POLICY_TASKS,
    OFF_POLICY_UTD1,
)
from ndp.experiments.studies.paper import (
    HEAD_ABLATION_COMMANDED,
    MT50_ATTRIBUTION_TASKS,
    PAPER_FIVE_TASKS,
    THROW_DEFAULTS,
)
from ndp.experiments.studies.regimes import (
    AR1_CORR,
    NDP_SETTINGS_AXES,
    PARAM_NOISE_DISPLACEMENT,
    PARAM_NOISE_LOG_STD,
    REGIME_1M_ARMS,
    REGIME_KS,
    REGIME_TASKS,
)
from ndp.experiments.studies.release import (
    EXPLAINED_CONDITIONS,
    EXPLAINED_TASKS,
    FIRST_HELD,
    RELEASE_1M_CONDITIONS,
    RELEASE_1M_TASKS,
    RELEASE_ALL_MW,
    RELEASE_CONDITIONS,
    RELEASE_FIXED,
    RELEASE_METHODS,
    RELEASE_OPTIMISER,
    RELEASE_RATIO,
    RELEASE_TASKS,
    RELEASE_V1,
)
from ndp.experiments.studies.sb3 import PPO_VS_SB3_TASKS

FAMILIES = (paper, release, sb3, offpolicy, regimes, mechanism, imitation)
"""The study modules, each with a ``STUDIES`` tuple of :class:`Study` entries."""

LIST_ORDER = (
    "paper-five",
    "mt50",
    "ablations",
    "release-conditions",
    "ndp-head-ablation",
    "ppo-vs-sb3",
    "sac-vs-sb3",
    "td3-vs-sb3",
    "off-policy",
    "sac-critic",
    "sb3-ndp",
    "release-goals-1m",
    "release-explained",
    "ndp-regimes",
    "ndp-mechanism",
    "ndp-regimes-1m",
    "ndp-settings",
    "il-robot",
    "digits-data",
    "mt50-attribution",
    "digits-head",
    "digits-converged",
)
"""The order of ``ndp sweep --list`` (and of :data:`STUDIES`)."""


def _registry() -> dict[str, Study]:
    """Every family's studies by name, in :data:`LIST_ORDER` then module order."""
    found: dict[str, Study] = {}
    for family in FAMILIES:
        for s in family.STUDIES:
            if s.name in found:
                raise ValueError(f"name: study {s.name!r} is defined twice ({family.__name__})")
            found[s.name] = s
    ranked = sorted(
        found, key=lambda n: LIST_ORDER.index(n) if n in LIST_ORDER else len(LIST_ORDER)
    )
    return {n: found[n] for n in ranked}


STUDIES: dict[str, Study] = _registry()
"""Name -> :class:`Study`."""


def get_study(name: str) -> Study:
    """The named study (unknown: ValueError naming it and the close names)."""
    if name in STUDIES:
        return STUDIES[name]
    close = difflib.get_close_matches(name, list(STUDIES), n=3, cutoff=0.4)
    hint = f"; close names: {', '.join(close)}" if close else ""
    raise ValueError(f"study: unknown study {name!r}{hint} (known: {', '.join(STUDIES)})")


__all__ = [
    "AR1_CORR",
    "BC_DEMOS",
    "BC_TASKS",
    "CONVERGED_ARGS",
    "CONVERGED_LRS",
    "CONVERGED_MODELS",
    "DIGITS_TASKS",
    "EXPLAINED_CONDITIONS",
    "EXPLAINED_TASKS",
    "FAMILIES",
    "FIRST_HELD",
    "HEADS",
    "HEAD_ABLATION_COMMANDED",
    "HEAD_LRS",
    "LIST_ORDER",
    "LIVE",
    "MECHANISM_BASES",
    "MECHANISM_TASKS",
    "MT50_ATTRIBUTION_TASKS",
    "NDP_SETTINGS_AXES",
    "OFF_POLICY_CONDITIONS",
    "OFF_POLICY_TASKS",
    "OFF_POLICY_UTD1",
    "PAPER_FIVE_TASKS",
    "PARAM_NOISE_DISPLACEMENT",
    "PARAM_NOISE_LOG_STD",
    "PPO_VS_SB3_TASKS",
    "REGIME_1M_ARMS",
    "REGIME_KS",
    "REGIME_TASKS",
    "RELEASE_1M_CONDITIONS",
    "RELEASE_1M_TASKS",
    "RELEASE_ALL_MW",
    "RELEASE_CONDITIONS",
    "RELEASE_FIXED",
    "RELEASE_METHODS",
    "RELEASE_OPTIMISER",
    "RELEASE_RATIO",
    "RELEASE_TASKS",
    "RELEASE_V1",
    "STUDIES",
    "THROW_DEFAULTS",
    "ArmSpec",
    "Condition",
    "Readings",
    "Study",
    "get_study",
    "resolve",
]
