"""The registry of studies: every file of ``data/`` read once, when the package is imported
(:data:`STUDIES`, ordered by :data:`LIST_ORDER`), and :func:`get_study`."""

from __future__ import annotations

import difflib

from ndp.experiments.studies.base import Study
from ndp.experiments.studies.loader import load_studies, study_files

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
"""The order of ``ndp sweep --list`` (and of :data:`STUDIES`); a study it does not name comes
after those it names, in the order of its file's name."""


def _registry() -> dict[str, Study]:
    """Every study file's study by name, in :data:`LIST_ORDER` then file name order."""
    found = load_studies(study_files())
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
