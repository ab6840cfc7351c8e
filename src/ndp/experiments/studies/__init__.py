"""The named studies of ``ndp sweep STUDY`` (docs/experiments.md describes each).

Each study is data: one TOML file, ``data/<name>.toml`` in this package, holding its tasks (or
a named task set), arms, seeds, budget, conditions, selection and readings entry point.
:mod:`ndp.experiments.studies.loader` reads the files into the :class:`Study`,
:class:`ArmSpec` and :class:`Condition` objects the sweep and the report read (a malformed
file is refused at import, with one line naming the file and the key), and
:mod:`ndp.experiments.studies.registry` collects them in :data:`STUDIES`.

- :mod:`ndp.experiments.studies.base`: what a study is (the dataclasses, :func:`resolve`);
- :mod:`ndp.experiments.studies.loader`: the file format, the checks, the named task sets;
- :mod:`ndp.experiments.studies.registry`: :data:`STUDIES`, :data:`LIST_ORDER`,
  :func:`get_study`;
- :mod:`ndp.experiments.studies.constants`: names for parts of the files that code and tests
  read (the release's option bundles, the regimes' k values, the task lists, ...), read from
  the data or checked against it by the tests.

Adding a study is one file in ``data/`` (:data:`LIST_ORDER` places it in ``ndp sweep --list``;
a study it does not name comes after those it names, in file name order). A study's readings
are an entry point ``"module:function"`` resolved when the report calls them (:func:`resolve`),
so no study imports the report or the sweep, and importing this package imports neither torch
nor a simulator.
"""

from __future__ import annotations

from ndp.experiments.studies.base import ArmSpec, Condition, Readings, Study, resolve
from ndp.experiments.studies.constants import (
    AR1_CORR,
    BC_DEMOS,
    BC_TASKS,
    CONVERGED_ARGS,
    CONVERGED_LRS,
    CONVERGED_MODELS,
    DIGITS_TASKS,
    EXPLAINED_CONDITIONS,
    EXPLAINED_TASKS,
    FIRST_HELD,
    HEAD_ABLATION_COMMANDED,
    HEAD_LRS,
    HEADS,
    LIVE,
    MECHANISM_BASES,
    MECHANISM_TASKS,
    MT50_ATTRIBUTION_TASKS,
    NDP_SETTINGS_AXES,
    OFF_POLICY_CONDITIONS,
    OFF_POLICY_TASKS,
    OFF_POLICY_UTD1,
    PAPER_FIVE_TASKS,
    PARAM_NOISE_DISPLACEMENT,
    PARAM_NOISE_LOG_STD,
    PPO_VS_SB3_TASKS,
    REGIME_1M_ARMS,
    REGIME_KS,
    REGIME_TASKS,
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
    THROW_DEFAULTS,
    k_args,
)
from ndp.experiments.studies.loader import (
    DATA_DIR,
    TASK_SETS,
    load_studies,
    load_study,
    register_task_set,
)
from ndp.experiments.studies.registry import LIST_ORDER, STUDIES, get_study

__all__ = [
    "AR1_CORR",
    "BC_DEMOS",
    "BC_TASKS",
    "CONVERGED_ARGS",
    "CONVERGED_LRS",
    "CONVERGED_MODELS",
    "DATA_DIR",
    "DIGITS_TASKS",
    "EXPLAINED_CONDITIONS",
    "EXPLAINED_TASKS",
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
    "TASK_SETS",
    "THROW_DEFAULTS",
    "ArmSpec",
    "Condition",
    "Readings",
    "Study",
    "get_study",
    "k_args",
    "load_studies",
    "load_study",
    "register_task_set",
    "resolve",
]
